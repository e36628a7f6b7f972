#!/usr/bin/env python3
"""Fit the rational approximation of the Ewald real-space force correction used by the
cluster-pair kernel in mixed precision (src/forces/nonbonded/kernel.rs, EwaldReal):

    -V'(r)/r = Q (1/r^3 - beta^3 F(z)),   z = beta^2 r^2,   V = Q erfc(beta r)/r,
    F(z) = (erf(sqrt z) - 2 sqrt(z/pi) exp(-z)) / z^(3/2)  ~  P(z)/Q(z)  on 0 <= z <= Z_MAX,

F is the force of erf(beta r)/r (the smooth part that the reciprocal sum carries), analytic
in z, F(0) = 4/(3 sqrt(pi)), F ~ z^(-3/2) for large z. P of degree m, Q of degree n with
Q(0) = 1. The fit minimises the relative error P/Q/F - 1 (which bounds the force's absolute
error by the same factor times Q/r^3, since beta^3 F <= 1/r^3) by iterated, re-weighted
linear least squares (Loeb's linearisation, then Lawson's weights towards the minimax
solution) in 60-digit arithmetic (mpmath) at Chebyshev nodes in z.

It prints the coefficients (Rust arrays), the maximum relative error of the exact rational
on a dense grid, and of the rational evaluated as the kernel does in f32 (coefficients
rounded to f32, Horner's rule in fused multiply-adds, one division; each fused step is
emulated exactly in f64 and rounded once to f32), with the condition of each Horner sum
(sum |c_k| z^k / |P(z)|) that the error bound in tests/nonbonded_engine.rs uses.

Usage: python3 scripts/fit_ewald_force.py [m] [n] [z_max]
"""
import sys

import mpmath as mp
import numpy as np

from rational_fit import fit_rational, print_rust_array

mp.mp.dps = 60


def force(z):
    x = mp.sqrt(z)
    return (mp.erf(x) - 2 * x * mp.exp(-z) / mp.sqrt(mp.pi)) / (z * x)


def fit(m, n, z_max):
    return fit_rational(force, m, n, z_max, rounds=40)


def fma32(a, b, c):
    """a * b + c rounded once to f32 (a * b of two f32 is exact in f64)."""
    return (a.astype(np.float64) * b.astype(np.float64) + c.astype(np.float64)).astype(np.float32)


def horner32(c, z):
    c32 = [np.float32(a) for a in c]
    y = np.full_like(z, c32[-1])
    for a in c32[-2::-1]:
        y = fma32(y, z, np.full_like(z, a))
    return y


def main():
    m = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 5
    z_max = mp.mpf(sys.argv[3]) if len(sys.argv) > 3 else mp.mpf(16)
    p, q = fit(m, n, z_max)
    grid = [z_max * k / 20000 for k in range(1, 20001)]
    exact = [force(z) for z in grid]
    err_exact = max(abs(mp.polyval(p[::-1], z) / mp.polyval(q[::-1], z) / f - 1) for z, f in zip(grid, exact))
    z32 = np.array([float(z) for z in grid], dtype=np.float32)
    num, den = horner32([float(c) for c in p], z32), horner32([float(c) for c in q], z32)
    approx = num / den  # IEEE f32 division, rounded once
    ref = [force(mp.mpf(float(z))) for z in z32]
    err_f32 = max(abs(mp.mpf(float(a)) / f - 1) for a, f in zip(approx, ref))
    cond = lambda c: max(
        sum(abs(a) * mp.mpf(float(z)) ** k for k, a in enumerate(c)) / abs(mp.polyval(c[::-1], mp.mpf(float(z))))
        for z in z32[::50]
    )
    print(f"// m = {m}, n = {n}, z_max = {z_max}: max |P/Q / F - 1| = {mp.nstr(err_exact, 3)} exact,"
          f" {mp.nstr(err_f32, 3)} in f32 (fused Horner, f32 coefficients, one division)")
    print(f"// Horner condition max sum |c_k| z^k / |P(z)|: P {mp.nstr(cond(p), 3)}, Q {mp.nstr(cond(q), 3)}")
    print_rust_array("EWALD_FORCE_P", p)
    print_rust_array("EWALD_FORCE_Q", q)


if __name__ == "__main__":
    main()
