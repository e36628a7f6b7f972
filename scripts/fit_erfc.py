#!/usr/bin/env python3
"""Fit the rational approximation of the scaled complementary error function used by the
cluster-pair kernel's Ewald real space (src/forces/nonbonded/kernel.rs):

    erfc(x) = exp(-x^2) * erfcx(x),   erfcx(x) ~ P(x) / Q(x)  on 0 <= x <= X_MAX,

P of degree m, Q of degree m + 1 with Q(0) = 1 (erfcx ~ 1/(sqrt(pi) x) at large x). The fit
minimises the relative error P/Q/erfcx - 1 by iterated, re-weighted linear least squares
(Loeb's linearisation, then Lawson's weights towards the minimax solution) in 60-digit
arithmetic (mpmath), at Chebyshev nodes. It prints the coefficients (Rust arrays) and the
maximum relative error of the exact rational on a dense grid (20 001 points), and of the
rational evaluated in the target precision with Horner's rule (numpy, f64 or f32
arithmetic; the kernel uses fused multiply-adds, which are more accurate, not less).

Usage: python3 scripts/fit_erfc.py [m] [x_max] [f32|f64]
"""
import sys

import mpmath as mp
import numpy as np

from rational_fit import fit_rational, print_rust_array

mp.mp.dps = 60


def erfcx(x):
    return mp.exp(x * x) * mp.erfc(x)


def fit(m, x_max):
    return fit_rational(erfcx, m, m + 1, x_max, rounds=30)


def horner(c, x, dtype):
    y = np.full_like(x, dtype(c[-1]))
    for a in c[-2::-1]:
        y = y * x + dtype(a)
    return y


def main():
    m = int(sys.argv[1]) if len(sys.argv) > 1 else 9
    x_max = mp.mpf(sys.argv[2]) if len(sys.argv) > 2 else mp.mpf(6.5)
    dtype = np.float32 if (len(sys.argv) > 3 and sys.argv[3] == "f32") else np.float64
    p, q = fit(m, x_max)
    grid = [x_max * k / 20000 for k in range(20001)]
    exact = [erfcx(x) for x in grid]
    err_exact = max(abs(mp.polyval(p[::-1], x) / mp.polyval(q[::-1], x) / f - 1) for x, f in zip(grid, exact))
    xd = np.array([float(x) for x in grid], dtype=dtype)
    pd, qd = [float(c) for c in p], [float(c) for c in q]
    approx = horner(pd, xd, dtype) / horner(qd, xd, dtype)
    # The error of the lanes' value, against the exact erfcx of the rounded argument.
    ref = [erfcx(mp.mpf(float(x))) for x in xd]
    err_round = max(abs(mp.mpf(float(a)) / f - 1) for a, f in zip(approx, ref))
    print(f"// m = {m}, x_max = {x_max}: max |P/Q / erfcx - 1| = {mp.nstr(err_exact, 3)} exact,"
          f" {mp.nstr(err_round, 3)} in {dtype.__name__} Horner")
    name = "32" if dtype is np.float32 else "64"
    print_rust_array(f"ERFCX_P{name}", p)
    print_rust_array(f"ERFCX_Q{name}", q)


if __name__ == "__main__":
    main()
