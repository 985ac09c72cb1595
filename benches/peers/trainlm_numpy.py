#!/usr/bin/env python3
"""numpy peer of railgrip's Levenberg-Marquardt training: MATLAB trainlm as a user would write
it with numpy (benches/lm.rs runs this side by side with railgrip on identical inputs;
tests/lm_peer.rs checks that both follow the same trajectory).

The way trainlm works: one Jacobian per epoch (J, N x P, built with numpy broadcasting),
J'J and J'r by BLAS (numpy dispatches J.T @ J to a symmetric rank-k update), then damped
steps (J'J + mu I) d = J'r (numpy.linalg.solve, one LAPACK call) until the error falls,
mu *= mu_dec on success and mu *= mu_inc on failure, stop at mu > mu_max, at the goal, at a
gradient below min_grad, after `epochs`, or when the validation error has not improved for
max_fail epochs in a row. The network: inputs -> tanh hidden layer -> linear output, theta in
MATLAB's order (IW row-major, b1, LW, b2), exactly railgrip's problem.

Reads the problem railgrip writes (normalised training and validation data, initial weights,
shape, settings), trains `repeats` times and prints one JSON line: the seconds per epoch of
the fastest repeat, the epochs run, the training MSE (mu^2 units) after every epoch, and the
weights trainlm returns ("theta": those of the best validation error), and what sets numpy's
speed here ("environment": numpy's version, its BLAS and the kernel it picked, numpy's SIMD
extensions, np.tanh's ns per element).

With "bayesian": true in the settings it trains as MATLAB trainbr: F = beta*E_D + alpha*E_W,
steps -(beta J'J + (mu + alpha) I) \\ (beta J'r + alpha theta) accepted when F falls, then
gamma = P - alpha tr((beta J'J + alpha I)^-1) (J'J of the epoch's start), alpha = gamma / (2 E_W),
beta = (N - gamma) / (2 E_D); validation never stops. The output then also holds "gamma" per
epoch.

Usage: python3 benches/peers/trainlm_numpy.py <problem.json> [repeats]   (needs numpy)
repeats = 0 prints only "environment", without training.
Thread count: set OPENBLAS_NUM_THREADS (and OMP_NUM_THREADS) before numpy starts.
Rounding probes, to measure how much the trajectory amplifies rounding (tests/lm_peer.rs):
TRAINLM_PROBE=gemm computes J'J by a general product (J.T @ J.copy()) instead of syrk, the same
sums in another order; TRAINLM_PROBE=tanh evaluates tanh as 1 - 2 / (exp(2z) + 1), a few ulp
from np.tanh.
"""
import json
import os
import sys
import time

import numpy as np

PROBE = os.environ.get("TRAINLM_PROBE", "")


def tanh(z):
    if PROBE == "tanh":
        return 1.0 - 2.0 / (np.exp(2.0 * z) + 1.0)
    return np.tanh(z)


def environment(n_elements):
    """What decides numpy's speed on this machine: its version, the BLAS it was built with and
    the kernel that BLAS picked at run time (OpenBLAS's core name, when it can be read), the
    SIMD extensions numpy's own loops dispatch to, and np.tanh's cost in ns per element on an
    array of `n_elements` (best of 20)."""
    import ctypes
    import glob
    info = {"numpy": np.__version__}
    try:
        blas = np.show_config(mode="dicts")["Build Dependencies"]["blas"]
        info["blas"] = f"{blas.get('name', '?')} {blas.get('version', '')}".strip()
    except Exception:  # an older numpy without mode="dicts"
        info["blas"] = "unknown"
    libs = os.path.join(os.path.dirname(np.__file__), "..", "numpy.libs", "*openblas*")
    for f in glob.glob(libs):
        for name in ("scipy_openblas_get_corename64_", "scipy_openblas_get_corename",
                     "openblas_get_corename64_", "openblas_get_corename"):
            try:
                fn = getattr(ctypes.CDLL(f), name)
            except (AttributeError, OSError):
                continue
            fn.restype = ctypes.c_char_p
            info["blas_core"] = fn().decode()
            break
    try:
        from numpy._core._multiarray_umath import __cpu_features__ as feats
    except ImportError:  # numpy 1.x
        try:
            from numpy.core._multiarray_umath import __cpu_features__ as feats
        except ImportError:
            feats = None
    info["simd"] = ([k for k in ("AVX2", "AVX512F", "AVX512_SKX") if feats.get(k)]
                    if feats is not None else ["unknown"])
    z = np.linspace(-3.0, 3.0, n_elements)
    out = np.empty_like(z)
    best = float("inf")
    for _ in range(20):
        t0 = time.perf_counter()
        np.tanh(z, out=out)
        best = min(best, time.perf_counter() - t0)
    info["tanh_ns_per_element"] = best / n_elements * 1e9
    return info


def main(path, repeats):
    with open(path) as f:
        p = json.load(f)
    k, h = p["inputs"], p["hidden"]
    x = np.asarray(p["train_x"], dtype=float).reshape(-1, k)
    y = np.asarray(p["train_y"], dtype=float)
    vx = np.asarray(p["val_x"], dtype=float).reshape(-1, k)
    vy = np.asarray(p["val_y"], dtype=float)
    theta0 = np.asarray(p["theta0"], dtype=float)
    scale = p["scale"]
    s = p["settings"]
    n_params = h * (k + 2) + 1
    if repeats == 0:
        # Only what sets numpy's speed here, without training.
        print(json.dumps({"environment": environment(len(y) * h)}))
        return

    def unpack(t):
        return t[: h * k].reshape(h, k), t[h * k : h * k + h], t[h * k + h : h * k + 2 * h], t[-1]

    def forward(t, xx):
        w1, b1, w2, b2 = unpack(t)
        return tanh(xx @ w1.T + b1) @ w2 + b2

    def sse(t, xx, yy):
        r = forward(t, xx) - yy
        return float(r @ r)

    def jacobian(t):
        w1, b1, w2, b2 = unpack(t)
        a = tanh(x @ w1.T + b1)
        d = w2 * (1.0 - a * a)
        j = np.empty((x.shape[0], n_params))
        j[:, : h * k] = (d[:, :, None] * x[:, None, :]).reshape(x.shape[0], h * k)
        j[:, h * k : h * k + h] = d
        j[:, h * k + h : h * k + 2 * h] = a
        j[:, -1] = 1.0
        return j, a @ w2 + b2 - y

    def train():
        theta = theta0.copy()
        mu = s["mu"]
        n = len(y)
        bayes = bool(s.get("bayesian", False))
        best_val = sse(theta, vx, vy) / len(vy) * scale if len(vy) else np.inf
        best_theta = theta.copy()
        fails = 0
        history = []
        gammas = []
        eye = np.eye(n_params)
        if bayes:
            e_d, e_w = sse(theta, x, y), float(theta @ theta)
            gamma = float(n_params)
            alpha = gamma / (2.0 * e_w) if e_w > 0 else 1.0
            beta = (n - gamma) / (2.0 * e_d) if e_d > 0 else 1.0
        for _ in range(s["epochs"]):
            j, r = jacobian(theta)
            e0 = float(r @ r)
            jtj = j.T @ (j.copy() if PROBE == "gemm" else j)
            jtr = j.T @ r
            if bayes:
                rhs = beta * jtr + alpha * theta
                a0 = beta * jtj
                ridge = alpha
                f0 = beta * e0 + alpha * float(theta @ theta)
            else:
                rhs, a0, ridge, f0 = jtr, jtj, 0.0, e0
            grad = 2.0 * float(np.sqrt(rhs @ rhs))
            if e0 / n * scale <= s["goal"] or grad < s["min_grad"]:
                history.append(e0 / n * scale)
                break
            stop = False
            nxt, e_next = theta, e0
            while True:
                try:
                    # MATLAB's (JJ + mu I) \ Jr: one LAPACK solve (gesv).
                    step = np.linalg.solve(a0 + (mu + ridge) * eye, rhs)
                    trial = theta - step
                    ok = np.all(np.isfinite(trial))
                except np.linalg.LinAlgError:
                    ok = False
                if ok:
                    e = sse(trial, x, y)
                    f = beta * e + alpha * float(trial @ trial) if bayes else e
                    if np.isfinite(e) and f < f0:
                        nxt, e_next = trial, e
                        mu *= s["mu_dec"]
                        if bayes:
                            mu = max(mu, 1e-20)
                        break
                mu *= s["mu_inc"]
                if mu > s["mu_max"]:
                    stop = True
                    break
            theta = nxt
            history.append(e_next / n * scale)
            if bayes and not stop:
                inv = np.linalg.inv(beta * jtj + alpha * eye)
                gamma = min(max(n_params - alpha * float(np.trace(inv)), 0.0), float(n_params))
                e_w = float(theta @ theta)
                alpha = gamma / (2.0 * e_w) if e_w > 0 else 1.0
                beta = (n - gamma) / (2.0 * e_next) if e_next > 0 else beta
            if bayes:
                gammas.append(gamma)
            elif len(vy):
                v = sse(theta, vx, vy) / len(vy) * scale
                if v < best_val:
                    best_val, fails, best_theta = v, 0, theta.copy()
                else:
                    fails += 1
                    if fails >= s["max_fail"]:
                        break
            if stop:
                break
        # trainlm returns the weights of the best validation error (without validation: the
        # last ones).
        kept = best_theta if len(vy) and not bayes else theta
        return history, gammas, kept

    best = float("inf")
    history, gammas, kept = None, None, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        history, gammas, kept = train()
        best = min(best, (time.perf_counter() - t0) / max(len(history), 1))
    print(json.dumps({"seconds_per_epoch": best, "epochs": len(history), "train_mse": history,
                      "gamma": gammas, "theta": kept.tolist(),
                      "environment": environment(len(y) * h)}))


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 3)
