#!/usr/bin/env python3
"""scipy peer of railgrip's Polach fit (benches/polach.rs runs this).

Reads the exact samples the Rust benchmark fits: per sample the speed v (m/s), the slip
w = dv (m/s) and the estimated mu; the wheel load Q (N) and c = pi G a b c11 / 4 of the fixed
contact patch; the start (mu0, A, B, k_A, rho = k_S/k_A). Fits Polach's law (seed 004 eq. 1-2)

    mu_w = mu0 ((1 - A) exp(-B w) + A),  eps = c (w/v) / (Q mu_w),
    mu   = (2 mu_w / pi) (k_A eps / (1 + (k_A eps)^2) + atan(k_A rho eps))

with scipy.optimize.least_squares(method='trf') inside the same bounds (0 < mu0 < 1.5,
0 < A < 1, 1e-3 < B < 100 s/m, 0 < k_A < 1, 0 < rho < 1), the analytic Jacobian and tolerances
ftol = xtol = 1e-10 (as railgrip's MINPACK tests), gtol 1e-12. This is what a scipy user would
write for a bounded fit ('lm' takes no bounds). Prints one JSON line: seconds (best of 3),
evaluations, parameters (mu0, A, B, k_A, k_S), RMS residual.

Usage: python3 benches/peers/polach_scipy.py <problem.json>    (needs numpy and scipy)
"""
import json
import sys
import time

import numpy as np
import scipy
from scipy.optimize import least_squares


def main(path):
    with open(path) as f:
        p = json.load(f)
    v = np.asarray(p["v"], dtype=float)
    w = np.asarray(p["dv"], dtype=float)
    mu = np.asarray(p["mu"], dtype=float)
    q, c = p["q_n"], p["c_per_s"]
    x0 = np.asarray(p["start"], dtype=float)
    lo = np.array([1e-9, 1e-9, 1e-3 * (1 + 1e-9), 1e-9, 1e-9])
    hi = np.array([1.5 - 1e-9, 1 - 1e-9, 100.0 * (1 - 1e-9), 1 - 1e-9, 1 - 1e-9])
    cs = c * (w / v) / q

    def parts(x):
        mu0, a, b, ka, rho = x
        e = np.exp(-b * w)
        g = (1 - a) * e + a
        muw = mu0 * g
        eps = cs / muw
        xa, ys = ka * eps, ka * rho * eps
        dxa, dys = 1 + xa * xa, 1 + ys * ys
        bracket = xa / dxa + np.arctan(ys)
        return e, g, muw, eps, xa, ys, dxa, dys, bracket

    def residuals(x):
        *_, muw, _eps, _xa, _ys, _dxa, _dys, bracket = parts(x)
        return 2 / np.pi * muw * bracket - mu

    def jacobian(x):
        mu0, a, b, ka, rho = x
        e, g, muw, eps, xa, ys, dxa, dys, bracket = parts(x)
        h1 = (1 - xa * xa) / (dxa * dxa)
        dmuw = 2 / np.pi * (bracket - xa * h1 - ys / dys)
        scale = 2 / np.pi * muw * eps
        return np.column_stack(
            [
                dmuw * g,
                dmuw * mu0 * (1 - e),
                -dmuw * mu0 * (1 - a) * w * e,
                scale * (h1 + rho / dys),
                scale * ka / dys,
            ]
        )

    best, res = float("inf"), None
    for _ in range(3):
        t0 = time.perf_counter()
        r = least_squares(
            residuals,
            np.clip(x0, lo, hi),
            jac=jacobian,
            bounds=(lo, hi),
            method="trf",
            ftol=1e-10,
            xtol=1e-10,
            gtol=1e-12,
        )
        best = min(best, time.perf_counter() - t0)
        res = r
    mu0, a, b, ka, rho = res.x
    print(
        json.dumps(
            {
                "seconds": best,
                "nfev": int(res.nfev),
                "njev": int(res.njev),
                "params": [mu0, a, b, ka, ka * rho],
                "rmse": float(np.sqrt(np.mean(res.fun**2))),
                "message": res.message,
                "versions": f"scipy {scipy.__version__}, numpy {np.__version__}",
            }
        )
    )


if __name__ == "__main__":
    main(sys.argv[1])
