#!/usr/bin/env python3
"""How far the wheels' acceleration read from a simulated campaign's tachometers is from the
truth, per run, at several low-pass cut-offs, and how much of that is bandwidth and how much
noise.

For each run of ARCHIVE_DIR (the CSV logs of `railgrip simulate --format csv`, with their
truth tables) and one axle: the tachometer channel omega<axle> (rad/s) moved back by the
counter's delay (half its counting window), low-passed with a 4th-order Butterworth
forward-backward (as railgrip's zero-phase filters, scipy's sosfiltfilt) at each cut-off and
differentiated (central differences): omega_dot. Against the truth's omega_dot (the truth's
omega differentiated the same way, unfiltered), over the samples 3 s after the start with the
wheel turning faster than 10 rad/s, it prints r times the rms error (m/s^2, r the wheel
radius), split into
- bandwidth: the truth low-passed at the same cut-off against the truth (what the filter
  removes of the true signal), and
- noise: the estimate against the truth low-passed at the same cut-off (what the counter
  adds).

    python3 scripts/wheel-acceleration-error.py ARCHIVE_DIR [--axle 2] [--cutoffs 4,6,8,12]
                                                [--delay-ms 9.592] [--radius 0.445]

--delay-ms: the counter's delay (default: half of 8 samples at 417 Hz, the simulator's
default 20 ms window at the default rate); --radius: the pipeline's wheel radius (m).
Needs numpy, pandas, pyarrow and scipy. docs/training.md ("A higher cut-off for the slip rate")
quotes it on seed 1 of the top-speed scenes.
"""
import argparse
import glob
import os

import numpy as np
import pandas as pd
from scipy.signal import butter, sosfiltfilt

from campaign_tables import COUNTER_DELAY_MS


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("archive")
    ap.add_argument("--axle", type=int, default=2)
    ap.add_argument("--cutoffs", default="4,6,8,12")
    ap.add_argument("--delay-ms", type=float, default=COUNTER_DELAY_MS)
    ap.add_argument("--radius", type=float, default=0.445)
    a = ap.parse_args()
    try:
        cutoffs = [float(c) for c in a.cutoffs.split(",")]
    except ValueError:
        raise SystemExit(f"--cutoffs {a.cutoffs!r}: give frequencies in Hz separated by commas, e.g. 4,6,8")
    if not all(c > 0.0 for c in cutoffs):
        raise SystemExit(f"--cutoffs {a.cutoffs!r}: every cut-off must be above 0 Hz")
    if a.delay_ms < 0.0:
        raise SystemExit(f"--delay-ms {a.delay_ms}: a delay is not negative")
    logs = sorted(glob.glob(os.path.join(a.archive, "*.csv")))
    if not logs:
        raise SystemExit(f"{a.archive}: no .csv logs (simulate with --format csv)")
    print(f"axle {a.axle}, r × rms error of the wheel's acceleration, m/s²: total = bandwidth (+) noise")
    print("run".ljust(18) + "".join(f"{c:>24.0f} Hz" for c in cutoffs))
    for path in logs:
        run = os.path.basename(path)[:-4]
        truth_path = os.path.join(a.archive, f"{run}.truth.parquet")
        if not os.path.exists(truth_path):
            print(f"{run}: no {run}.truth.parquet, skipped")
            continue
        log = pd.read_csv(path)
        col = f"omega{a.axle}"
        for c in ("t", col):
            if c not in log.columns:
                raise SystemExit(f"{path}: no column {c!r} (a log of `railgrip simulate --format csv`; --axle 1–4)")
        t = log["t"].to_numpy()
        fs = 1.0 / np.median(np.diff(t))
        if not max(cutoffs) < fs / 2:
            raise SystemExit(f"{path}: cut-off {max(cutoffs)} Hz is not below half the sample rate of {fs:.0f} Hz; give lower --cutoffs")
        h = 1.0 / fs
        shift = int(round(a.delay_ms * 1e-3 * fs))
        omega = log[col].to_numpy()[shift:]
        t = t[: len(omega)]
        tr = pd.read_parquet(truth_path)
        for c in ("axle", "time_s", "omega_radps"):
            if c not in tr.columns:
                raise SystemExit(f"{truth_path}: no column {c!r} (the truth table `railgrip simulate` writes)")
        tr = tr[tr.axle == a.axle].sort_values("time_s")
        if tr.empty:
            raise SystemExit(f"{truth_path}: no samples of axle {a.axle}")
        w_true = np.interp(t, tr.time_s.to_numpy(), tr.omega_radps.to_numpy())
        wdot_true = np.gradient(w_true, h)
        keep = (t > 3.0) & (w_true > 10.0)
        cells = []
        for c in cutoffs:
            sos = butter(4, c, fs=fs, output="sos")
            wdot = np.gradient(sosfiltfilt(sos, omega), h)
            wdot_band = sosfiltfilt(sos, wdot_true)

            def rms(x):
                return a.radius * np.sqrt(np.mean(x[keep] ** 2))

            total = rms(wdot - wdot_true)
            band = rms(wdot_band - wdot_true)
            noise = rms(wdot - wdot_band)
            cells.append(f"{total:.2f} = {band:.2f} (+) {noise:.2f}")
        print(run.ljust(18) + "".join(f"{x:>27}" for x in cells))


if __name__ == "__main__":
    main()
