#!/usr/bin/env python3
"""scipy peer of railgrip's Levenberg-Marquardt training (benches/train.rs runs this).

Reads the exact problem the Rust benchmark trains on: normalised inputs and targets of the
training and validation sets, the network shape, the Nguyen-Widrow initial weights and the scale
from normalised MSE to mu^2. Fits the same 10-neuron tanh MLP with
scipy.optimize.least_squares(method='lm') (MINPACK lmder) and an analytic Jacobian, from the same
initial weights, and prints one JSON line: seconds, function and Jacobian evaluations, training
and validation MSE (mu^2).

Usage: python3 benches/peers/lm_scipy.py <problem.json>    (needs numpy and scipy)
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
    k, h = p["inputs"], p["hidden"]
    x = np.asarray(p["train_x"], dtype=float).reshape(-1, k)
    y = np.asarray(p["train_y"], dtype=float)
    vx = np.asarray(p["val_x"], dtype=float).reshape(-1, k)
    vy = np.asarray(p["val_y"], dtype=float)
    theta0 = np.asarray(p["theta0"], dtype=float)
    scale = p["scale"]

    def unpack(t):
        w1 = t[: h * k].reshape(h, k)
        b1 = t[h * k : h * k + h]
        w2 = t[h * k + h : h * k + 2 * h]
        b2 = t[-1]
        return w1, b1, w2, b2

    def forward(t, xx):
        w1, b1, w2, b2 = unpack(t)
        tt = np.tanh(xx @ w1.T + b1)
        return tt @ w2 + b2, tt

    def resid(t):
        return forward(t, x)[0] - y

    def jac(t):
        w1, b1, w2, b2 = unpack(t)
        _, tt = forward(t, x)
        d = (1.0 - tt * tt) * w2
        dw1 = (d[:, :, None] * x[:, None, :]).reshape(len(x), h * k)
        return np.hstack([dw1, d, tt, np.ones((len(x), 1))])

    t0 = time.perf_counter()
    res = least_squares(resid, theta0, jac=jac, method="lm")
    secs = time.perf_counter() - t0
    train_mse = float(np.mean(resid(res.x) ** 2) * scale)
    val_mse = float(np.mean((forward(res.x, vx)[0] - vy) ** 2) * scale)
    print(json.dumps({
        "seconds": secs,
        "nfev": int(res.nfev),
        "njev": int(res.njev) if res.njev is not None else None,
        "train_mse": train_mse,
        "val_mse": val_mse,
        "status": int(res.status),
        "message": res.message,
        "versions": versions(),
    }))


def versions():
    """scipy's and numpy's versions and the BLAS each was built with (MINPACK's own loops are
    plain C; the residuals and Jacobian here are numpy)."""
    def blas(module):
        try:
            b = module.show_config(mode="dicts")["Build Dependencies"]["blas"]
            return f"{b.get('name', '?')} {b.get('version', '')}".strip()
        except Exception:  # a release without show_config(mode="dicts"), or no BLAS entry
            return "BLAS unknown"
    return (f"scipy {scipy.__version__} ({blas(scipy)}), "
            f"numpy {np.__version__} ({blas(np)})")


if __name__ == "__main__":
    main(sys.argv[1])
