#!/usr/bin/env python3
"""A simulated campaign's estimates with the slip rate replaced by a variant, for `railgrip train`.

Copies every runs/<run>/estimates.parquet of a `railgrip run` output folder to
OUT_DIR/<run>.estimates.parquet (the name `railgrip train` takes) with the slip-rate column
ddv_mps2 (m/s^2) replaced, axle by axle, by one of:

- truth-lowpass:F   the truth's slip rate low-passed at F Hz (4th-order Butterworth,
                    forward-backward): the estimate's bandwidth without its noise;
- error-below:F     the truth plus only the part of the estimate's error below F Hz;
- error-above:F     the truth plus only the part of the estimate's error above F Hz;
- brake-torque:F    (F > 4) the estimate's wheel acceleration with the brake torque's fast
                    part added, omega'_new = omega'_4 + kappa (alpha/J)(p_4 - p_F), so that
                    ddv_new = ddv - r kappa (alpha/J)(p_4 - p_F) (braking runs: ddv = v' - r
                    omega'). The wheel's acceleration is omega' = c - (alpha/J) p (c the
                    contact's torque over the inertia J), the estimate's omega'_4 is low-passed
                    at 4 Hz, and p_4, p_F are the logged pressure (bar) low-passed at 4 and F
                    Hz. kappa is the regression, over a centred sliding 1 s window, of the
                    4-15 Hz band of the logged omega' on that of -(alpha/J) p, clipped to
                    [0, 1.2]: where the wheel creeps the contact force follows the brake and
                    cancels part of it. The tachometers are moved back by --delay-ms first.

Every other column and each file's run metadata stay as they were. The truth comes from
<ARCHIVE_DIR>/<run>.truth.parquet, the logs (brake-torque only) from <ARCHIVE_DIR>/<run>.csv,
matched to the estimates by time. Training on the result asks what the slip rate's error costs
the models, and of what kind:

    python3 scripts/slip-rate-variants.py ARCHIVE_DIR RUN_OUT_DIR OUT_DIR VARIANT
                                          [--alpha 1600] [--inertia 120] [--radius 0.445]
                                          [--delay-ms 9.592]
    railgrip train OUT_DIR/*.estimates.parquet --out OUT_DIR/models
    railgrip score OUT_DIR/models/mlp.residual.json pipelines/scenes/top_speed/*.toml --seeds N

--alpha (N m/bar), --inertia (kg m^2), --radius (m): the pipeline's (defaults: UIC-Z1's).
--delay-ms: the counting tachometers' delay, half their counting window (default: half of 8
samples at 417 Hz, the simulator's default 20 ms window at the default rate). Nothing is
written unless every run could be edited.
Needs numpy, pandas, pyarrow and scipy. docs/training.md ("The loss is the 4 Hz bandwidth" and
"The brake torque's fast part added back") used it on the top-speed scenes.
"""
import argparse
import os
import sys

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
from scipy.signal import butter, sosfiltfilt

from campaign_tables import COUNTER_DELAY_MS, run_estimates, run_metadata, write_estimates

VARIANTS = ("truth-lowpass", "error-below", "error-above", "brake-torque")


def lowpass(x, hz, fs):
    return sosfiltfilt(butter(4, hz, fs=fs, output="sos"), x)


def column(frame, name, path):
    """The column `name` of `frame` as floats, or an exit naming the file."""
    if name not in frame:
        sys.exit(f"{path}: no column {name}; it has {', '.join(map(str, frame.columns))}")
    return frame[name].to_numpy(dtype=float)


def brake_torque_part(log, log_path, axle, fs, a):
    """r kappa (alpha/J)(p_4 - p_F) on the log's time base, kappa over a sliding 1 s window."""
    b = a.alpha / a.inertia
    shift = int(round(a.delay_ms * 1e-3 * fs))
    omega = column(log, f"omega{axle}", log_path)
    omega = np.concatenate([omega[shift:], np.full(shift, omega[-1])])
    p = column(log, f"p{axle}", log_path)
    h = 1.0 / fs
    w4 = lowpass(omega, 4.0, fs)
    band_w = np.gradient(lowpass(omega, 15.0, fs) - w4, h)
    p4 = lowpass(p, 4.0, fs)
    band_p = -b * (lowpass(p, 15.0, fs) - p4)
    win = np.ones(int(fs)) / int(fs)
    num = np.convolve(band_w * band_p, win, mode="same")
    den = np.convolve(band_p * band_p, win, mode="same")
    kappa = np.clip(num / np.maximum(den, 1e-9), 0.0, 1.2)
    return a.radius * kappa * b * (p4 - lowpass(p, a.cutoff, fs))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("archive", help="folder with the scenes' logs (.csv) and truth tables")
    ap.add_argument("run_out", help="output folder of `railgrip run` on that archive")
    ap.add_argument("out", help="folder to write <run>.estimates.parquet into")
    ap.add_argument("variant", help="truth-lowpass:F | error-below:F | error-above:F | brake-torque:F")
    ap.add_argument("--alpha", type=float, default=1600.0)
    ap.add_argument("--inertia", type=float, default=120.0)
    ap.add_argument("--radius", type=float, default=0.445)
    ap.add_argument("--delay-ms", type=float, default=COUNTER_DELAY_MS)
    a = ap.parse_args()
    kind, _, hz = a.variant.partition(":")
    if kind not in VARIANTS or not hz:
        sys.exit(f"variant {a.variant!r}: give one of {', '.join(v + ':F' for v in VARIANTS)} (F in Hz)")
    try:
        a.cutoff = float(hz)
    except ValueError:
        sys.exit(f"variant {a.variant!r}: {hz!r} is not a frequency in Hz")
    if not a.cutoff > 0.0 or (kind == "brake-torque" and not a.cutoff > 4.0):
        sys.exit(f"variant {a.variant!r}: give F above {'4 Hz (the estimate is at 4 Hz)' if kind == 'brake-torque' else '0'}")
    if a.delay_ms < 0.0:
        sys.exit(f"--delay-ms {a.delay_ms}: a delay is not negative")
    edited = []
    for run, path in run_estimates(a.run_out):
        table = pq.read_table(path)
        meta = run_metadata(path)
        est = table.to_pandas()
        t = est["time_s"].to_numpy()
        fs = 1.0 / np.median(np.diff(np.unique(t)))
        if not a.cutoff < fs / 2:
            sys.exit(f"{path}: {a.cutoff} Hz is not below half the sample rate ({fs:.0f} Hz); give a lower F")
        new = est["ddv_mps2"].to_numpy().copy()
        if kind == "brake-torque":
            log_path = os.path.join(a.archive, f"{run}.csv")
            if not os.path.exists(log_path):
                sys.exit(f"{log_path}: missing; brake-torque reads the CSV log (simulate with --format csv)")
            log = pd.read_csv(log_path)
        else:
            truth_path = os.path.join(a.archive, f"{run}.truth.parquet")
            if not os.path.exists(truth_path):
                sys.exit(f"{truth_path}: missing; give the archive the run was simulated into")
            truth = pd.read_parquet(truth_path)
        for axle in np.unique(est["axle"]):
            sel = (est["axle"] == axle).to_numpy()
            old = new[sel]
            if kind == "brake-torque":
                part = brake_torque_part(log, log_path, axle, fs, a)
                x = old - np.interp(t[sel], column(log, "t", log_path), part)
            else:
                tr = truth[truth.axle == axle].sort_values("time_s")
                if tr.empty:
                    sys.exit(f"{truth_path}: no samples of axle {axle}; give the truth the run was simulated with")
                q = np.interp(t[sel], tr.time_s.to_numpy(), tr.ddv_mps2.to_numpy())
                err = np.nan_to_num(old - q)
                if kind == "truth-lowpass":
                    x = lowpass(q, a.cutoff, fs)
                elif kind == "error-below":
                    x = q + lowpass(err, a.cutoff, fs)
                else:
                    x = q + err - lowpass(err, a.cutoff, fs)
            new[sel] = np.where(np.isfinite(old), x, old)
        i = table.schema.get_field_index("ddv_mps2")
        table = table.set_column(i, table.schema.field("ddv_mps2"), pa.array(new))
        edited.append((run, table, meta))
    os.makedirs(a.out, exist_ok=True)
    for run, table, meta in edited:
        write_estimates(a.out, run, table, meta)
        print(f"{run}: ddv_mps2 as {a.variant}")


if __name__ == "__main__":
    main()
