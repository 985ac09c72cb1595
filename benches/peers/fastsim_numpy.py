#!/usr/bin/env python3
"""FASTSIM peers for `cargo bench --bench contact`: the same algorithm as
railgrip::contact::fastsim (Kalker's simplified theory; cell-centre bound, midpoint rule,
pressure scaled per grid so the cells carry exactly N, spin term integrated over the travel),
written the two ways a Python user would:

- numpy: the strips vectorised (one array op per cell row across all ny strips), the cells
  along x in a Python loop (each cell needs the previous one);
- numba: the plain double loop compiled with @njit (skipped with a message when numba is
  missing: pip install numba).

    python3 benches/peers/fastsim_numpy.py PROBLEM.json

PROBLEM: {"a", "b", "l1", "l2", "l3", "normal_n", "mu", "sx", "sy", "spin", "elliptic",
"grids": [n, ...]} (flexibilities in m/Pa, already as railgrip computes them). Prints JSON:
per grid n (n × n) the forces (fx, fy, mz, slip_fraction) and the best-of-5 time per call in
µs of each peer.
"""

import json
import math
import sys
import time

import numpy as np


def pressure_scale(nx, ny, elliptic):
    """Exact integral of the normalised pressure over the unit ellipse / its midpoint sum."""
    dy = 2.0 / ny
    y = -1.0 + (np.arange(ny) + 0.5) * dy
    ey = 1.0 - y * y
    dx = 2.0 * np.sqrt(ey) / nx
    total = 0.0
    for i in range(nx):
        xc = np.sqrt(ey) - (i + 0.5) * dx
        e = np.maximum(ey - xc * xc, 0.0)
        total += np.sum((np.sqrt(e) if elliptic else e) * dx * dy)
    exact = 2.0 * math.pi / 3.0 if elliptic else math.pi / 2.0
    return exact / total


def fastsim_numpy(p, nx, ny, scale):
    a, b, mu = p["a"], p["b"], p["mu"]
    pn0 = (1.5 if p["elliptic"] else 2.0) * p["normal_n"] / (math.pi * a * b) * scale
    gx0, gy, gs = p["sx"] / p["l1"], p["sy"] / p["l2"], p["spin"] / p["l3"]
    dy = 2.0 * b / ny
    y = -b + (np.arange(ny) + 0.5) * dy
    ey = 1.0 - (y / b) ** 2
    ay = a * np.sqrt(ey)
    dx = 2.0 * ay / nx
    gx = gx0 - gs * y
    px = np.zeros(ny)
    py = np.zeros(ny)
    sfx = np.zeros(ny)
    sfy = np.zeros(ny)
    smz = np.zeros(ny)
    slide = np.zeros(ny)
    x_prev = ay.copy()
    for i in range(nx):
        xc = ay - (i + 0.5) * dx
        step = 0.5 * dx if i == 0 else dx
        spin_step = gs * 0.5 * (x_prev * x_prev - xc * xc)
        e = np.maximum(ey - (xc / a) ** 2, 0.0)
        g = mu * pn0 * (np.sqrt(e) if p["elliptic"] else e)
        tx = px + gx * step
        ty = py + gy * step + spin_step
        t = np.hypot(tx, ty)
        sliding = t > g
        scale = np.where(sliding, g / np.where(t > 0.0, t, 1.0), 1.0)
        px = tx * scale
        py = ty * scale
        sfx += px
        sfy += py
        smz += xc * py - y * px
        slide += sliding
        x_prev = xc
    area = dx * dy
    return (
        float(np.sum(sfx * area)),
        float(np.sum(sfy * area)),
        float(np.sum(smz * area)),
        float(min(np.sum(slide * area) / (math.pi * a * b), 1.0)),
    )


def make_numba():
    try:
        from numba import njit
    except ImportError:
        return None

    @njit(cache=False, fastmath=False)
    def fastsim_numba(a, b, l1, l2, l3, n, mu, sx, sy, spin, elliptic, nx, ny, scale):
        pn0 = (1.5 if elliptic else 2.0) * n / (math.pi * a * b) * scale
        gx0, gy, gs = sx / l1, sy / l2, spin / l3
        dy = 2.0 * b / ny
        fx = fy = mz = slide_area = 0.0
        for j in range(ny):
            y = -b + (j + 0.5) * dy
            ey = 1.0 - (y / b) * (y / b)
            ay = a * math.sqrt(ey)
            dx = 2.0 * ay / nx
            gx = gx0 - gs * y
            px = py = 0.0
            sfx = sfy = smz = 0.0
            n_slide = 0
            x_prev = ay
            for i in range(nx):
                xc = ay - (i + 0.5) * dx
                step = 0.5 * dx if i == 0 else dx
                spin_step = gs * 0.5 * (x_prev * x_prev - xc * xc)
                xu = xc / a
                e = max(ey - xu * xu, 0.0)
                g = mu * pn0 * (math.sqrt(e) if elliptic else e)
                tx = px + gx * step
                ty = py + gy * step + spin_step
                t2 = tx * tx + ty * ty
                if t2 > g * g:
                    s = g / math.sqrt(t2)
                    tx *= s
                    ty *= s
                    n_slide += 1
                px, py = tx, ty
                sfx += px
                sfy += py
                smz += xc * py - y * px
                x_prev = xc
            area = dx * dy
            fx += sfx * area
            fy += sfy * area
            mz += smz * area
            slide_area += n_slide * area
        return fx, fy, mz, min(slide_area / (math.pi * a * b), 1.0)

    return fastsim_numba


def best_us(f, calls):
    best = float("inf")
    for _ in range(5):
        t0 = time.perf_counter()
        for _ in range(calls):
            f()
        best = min(best, (time.perf_counter() - t0) / calls)
    return best * 1e6


def versions():
    """numpy's version, and numba's when it is installed with the CPU its LLVM compiles for
    and the widest vector extension that CPU gives it."""
    v = f"numpy {np.__version__}"
    try:
        import numba
        v += f", numba {numba.__version__}"
        try:
            import llvmlite.binding as llvm
            feats = llvm.get_host_cpu_features()
            width = ("AVX-512" if feats.get("avx512f") else
                     "AVX2" if feats.get("avx2") else "no AVX2")
            # NUMBA_CPU_NAME, when set, is what numba compiles for instead of this CPU.
            target = numba.core.config.CPU_NAME or llvm.get_host_cpu_name()
            v += f" (LLVM target {target}, the host CPU has {width})"
        except Exception:
            pass
    except ImportError:
        pass
    return v


def main(path):
    p = json.load(open(path))
    numba_f = make_numba()
    out = {"numba": numba_f is not None, "grids": {}, "versions": versions()}
    for n in p["grids"]:
        scale = pressure_scale(n, n, p["elliptic"])
        row = {}
        forces = fastsim_numpy(p, n, n, scale)
        row["numpy"] = {"forces": forces, "us": best_us(lambda: fastsim_numpy(p, n, n, scale), max(5, 4000 // n))}
        if numba_f is not None:
            args = (p["a"], p["b"], p["l1"], p["l2"], p["l3"], p["normal_n"], p["mu"], p["sx"],
                    p["sy"], p["spin"], p["elliptic"], n, n, scale)
            forces = numba_f(*args)  # compiles on the first call (not timed)
            row["numba"] = {"forces": list(forces),
                            "us": best_us(lambda: numba_f(*args), max(20, 400000 // (n * n)))}
        out["grids"][str(n)] = row
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main(sys.argv[1])
