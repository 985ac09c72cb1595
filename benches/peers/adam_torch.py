#!/usr/bin/env python3
"""PyTorch peer of railgrip's mini-batch Adam/AdamW training (benches/adam.rs runs both on
identical inputs in the same run).

What a PyTorch user would write: nn.Sequential of Linear + Tanh layers and a linear output, in
float64 (railgrip trains in f64), torch.optim.Adam or AdamW with the same learning rate and
weight decay and burn's betas and epsilon, MSE loss on the normalised data, mini-batches of the same size drawn from a
torch.randperm shuffle every epoch, the validation MSE after every epoch. The weights start
from railgrip's Nguyen-Widrow theta (per layer W row-major [out][in], then b; the output layer
last), so both start from the same point; the shuffles differ (each uses its own generator), so
the trajectories agree in distribution, not bit for bit.

Reads the problem benches/adam.rs writes (JSON: inputs, hidden, train_x row-major n x inputs,
train_y, val_x, val_y, theta0, scale, optimizer, learning_rate, weight_decay, batch, epochs)
and prints one JSON line: threads, seconds per epoch (median over the epochs), and the
training and validation MSE (scale applied: mu^2) after every epoch.

Usage: python3 benches/peers/adam_torch.py <problem.json> [threads]   (needs torch)
"""
import json
import sys
import time

import torch


def main():
    p = json.load(open(sys.argv[1]))
    if len(sys.argv) > 2:
        torch.set_num_threads(int(sys.argv[2]))
    torch.manual_seed(1)
    dt = torch.float64
    k = p["inputs"]
    x = torch.tensor(p["train_x"], dtype=dt).reshape(-1, k)
    y = torch.tensor(p["train_y"], dtype=dt).reshape(-1, 1)
    vx = torch.tensor(p["val_x"], dtype=dt).reshape(-1, k)
    vy = torch.tensor(p["val_y"], dtype=dt).reshape(-1, 1)

    layers = []
    theta = p["theta0"]
    at = 0
    n_in = k
    for n in p["hidden"] + [1]:
        lin = torch.nn.Linear(n_in, n, dtype=dt)
        with torch.no_grad():
            lin.weight.copy_(torch.tensor(theta[at:at + n * n_in], dtype=dt).reshape(n, n_in))
            lin.bias.copy_(torch.tensor(theta[at + n * n_in:at + n * n_in + n], dtype=dt))
        at += n * (n_in + 1)
        layers.append(lin)
        if n != 1 or len(layers) <= len(p["hidden"]):
            layers.append(torch.nn.Tanh())
        n_in = n
    # The output layer is linear: drop a Tanh appended after it.
    if isinstance(layers[-1], torch.nn.Tanh):
        layers.pop()
    assert at == len(theta), (at, len(theta))
    net = torch.nn.Sequential(*layers)

    opt_cls = torch.optim.AdamW if p["optimizer"] == "adamw" else torch.optim.Adam
    # burn's defaults: betas (0.9, 0.999), epsilon 1e-5 (torch's default is 1e-8).
    opt = opt_cls(net.parameters(), lr=p["learning_rate"], betas=(0.9, 0.999), eps=1e-5,
                  weight_decay=p["weight_decay"])
    loss_fn = torch.nn.MSELoss()
    n = x.shape[0]
    b = p["batch"]
    times, train_mse, val_mse = [], [], []
    for _ in range(p["epochs"]):
        t0 = time.perf_counter()
        order = torch.randperm(n)
        for s in range(0, n, b):
            idx = order[s:s + b]
            opt.zero_grad()
            loss = loss_fn(net(x[idx]), y[idx])
            loss.backward()
            opt.step()
        with torch.no_grad():
            tr = loss_fn(net(x), y).item() * p["scale"]
            va = loss_fn(net(vx), vy).item() * p["scale"]
        times.append(time.perf_counter() - t0)
        train_mse.append(tr)
        val_mse.append(va)
    times.sort()
    print(json.dumps({
        "threads": torch.get_num_threads(),
        "s_per_epoch": times[len(times) // 2],
        "train_mse": train_mse,
        "val_mse": val_mse,
        "torch": torch.__version__,
        # The vector extension torch's own CPU kernels dispatch to, and its math libraries.
        "cpu_capability": getattr(getattr(torch.backends, "cpu", None), "get_cpu_capability",
                                  lambda: "unknown")(),
        "mkl": available("mkl"),
        "mkldnn": available("mkldnn"),
    }))


def available(backend):
    """Whether torch has the math library `backend` ("mkl", "mkldnn"); None where this torch
    cannot say."""
    try:
        return bool(getattr(torch.backends, backend).is_available())
    except Exception:
        return None


if __name__ == "__main__":
    main()
