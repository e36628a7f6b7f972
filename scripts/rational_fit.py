"""A rational P/Q of relative minimax error on [0, x_max], shared by the fit scripts
(scripts/fit_erfc.py, scripts/fit_ewald_force.py).

Loeb's iteration (linearised least squares, each row divided by the previous Q) on Chebyshev
nodes, with Lawson's reweighting by the error from the sixth round on, towards equal ripples.
Q's constant term is fixed at 1. Coefficients lowest power first, in mpmath at the caller's
precision.
"""

import mpmath as mp


def fit_rational(func, m, n, x_max, nodes=400, rounds=30):
    """P of degree m, Q of degree n with Q(0) = 1, fitting func on [0, x_max]."""
    xs = [x_max * (1 - mp.cos(mp.pi * (k + 0.5) / nodes)) / 2 for k in range(nodes)]
    fs = [func(x) for x in xs]
    q_prev = [mp.mpf(1)] * nodes
    lawson = [mp.mpf(1)] * nodes
    for it in range(rounds):
        rows, rhs = [], []
        for x, f, qp, w in zip(xs, fs, q_prev, lawson):
            s = mp.sqrt(w) / (f * qp)
            # P(x) - f (Q(x) - 1) = f  with Q's constant term fixed at 1.
            rows.append([s * x**k for k in range(m + 1)] + [-s * f * x**k for k in range(1, n + 1)])
            rhs.append(s * f)
        sol = mp.qr_solve(mp.matrix(rows), mp.matrix(rhs))[0]
        p = [sol[k] for k in range(m + 1)]
        q = [mp.mpf(1)] + [sol[m + 1 + k] for k in range(n)]
        q_prev = [mp.polyval(q[::-1], x) for x in xs]
        err = [abs(mp.polyval(p[::-1], x) / qv / f - 1) for x, qv, f in zip(xs, q_prev, fs)]
        if it >= 5:  # Lawson: weight by the error, towards equal ripples
            total = sum(w * e for w, e in zip(lawson, err))
            lawson = [w * e / total * nodes for w, e in zip(lawson, err)]
    return p, q


def print_rust_array(name, coefficients):
    """The coefficients as a Rust `const NAME: [f64; N]`, each as Python's repr of the f64."""
    print(f"const {name}: [f64; {len(coefficients)}] = [")
    for c in coefficients:
        print(f"    {float(c)!r},")
    print("];")
