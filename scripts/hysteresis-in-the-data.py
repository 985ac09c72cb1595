#!/usr/bin/env python3
"""Does a simulated campaign's data keep the true loss - recovery difference?

For every run and axle, bins the estimates (`railgrip run`'s runs/<run>/estimates.parquet,
valid samples) by their own slip and slip rate, and the truth (<archive>/<run>.truth.parquet)
by the true ones, and takes each cell's mean mu. The cells are laid out as the curve view of
`railgrip score` lays them out (score::Grid's defaults, speed ignored): slip every 0.1 m/s
(+-0.1) from 0.5 to 3 m/s, slip rate +-{0.25, 0.5, 1, 2, 4, 8} m/s^2 (0.5-1.5 times the
centre). Unlike the curve view, which scores a model at one point per cell on the
best-supported axle, this compares the two tables' cell means axle by axle. A pair of cells
(+q, -q) counts where both hold at least 20 samples in both tables. Prints per run and axle
the pairs, the estimates' mean loss - recovery difference over the truth's, and the
estimates' mean offset on each branch (loss: +q, recovery: -q).

    python3 scripts/hysteresis-in-the-data.py ARCHIVE_DIR RUN_OUT_DIR

ARCHIVE_DIR holds the scenes' truth tables (`railgrip simulate`), RUN_OUT_DIR is the output
folder of `railgrip run` on that archive. Needs numpy, pandas and pyarrow. The 0.94-1.05 of
docs/training.md ("Where the network loses it") comes from it.
"""
import os
import sys

import numpy as np
import pyarrow.parquet as pq

from campaign_tables import run_estimates

SLIPS = np.arange(0.5, 3.0 + 1e-9, 0.1)
RATES = [0.25, 0.5, 1.0, 2.0, 4.0, 8.0]
MIN_SAMPLES = 20
TRUTH_COLUMNS = ("axle", "dv_mps", "ddv_mps2", "mu")
ESTIMATE_COLUMNS = TRUTH_COLUMNS + ("valid",)
# True loss - recovery difference below which no ratio is given (railgrip score's threshold).
MIN_DIFFERENCE = 0.002


def cell_means(dv, q, mu):
    """{(slip, rate): (mean mu at +rate, mean mu at -rate)} where both hold enough samples."""
    out = {}
    for s in SLIPS:
        near = np.abs(dv - s) <= 0.1
        for r in RATES:
            sides = []
            for sign in (1.0, -1.0):
                m = near & (q * sign >= 0.5 * r) & (q * sign <= 1.5 * r)
                sides.append((int(m.sum()), mu[m].mean() if m.any() else np.nan))
            if all(n >= MIN_SAMPLES for n, _ in sides):
                out[(round(float(s), 2), r)] = (sides[0][1], sides[1][1])
    return out


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    archive, run_out = sys.argv[1], sys.argv[2]
    compared = 0
    for run, path in run_estimates(run_out):
        truth_path = os.path.join(archive, f"{run}.truth.parquet")
        if not os.path.exists(truth_path):
            print(f"{truth_path}: missing, run {run} skipped (give the archive it was simulated into)",
                  file=sys.stderr)
            continue
        truth = pq.read_table(truth_path).to_pandas()
        est = pq.read_table(path).to_pandas()
        for table, name, cols in ((truth, truth_path, TRUTH_COLUMNS), (est, path, ESTIMATE_COLUMNS)):
            missing = [c for c in cols if c not in table.columns]
            if missing:
                sys.exit(f"{name}: no column {missing[0]}; give a table written by railgrip")
        compared += 1
        cols = []
        for axle in sorted(truth.axle.unique()):
            t = truth[truth.axle == axle]
            e = est[(est.axle == axle) & est.valid]
            ct = cell_means(t.dv_mps.values, t.ddv_mps2.values, t.mu.values)
            ce = cell_means(e.dv_mps.values, e.ddv_mps2.values, e.mu.values)
            both = sorted(set(ct) & set(ce))
            if not both:
                cols.append(f"axle {axle}: no pairs")
                continue
            diff_t = np.mean([ct[k][0] - ct[k][1] for k in both])
            diff_e = np.mean([ce[k][0] - ce[k][1] for k in both])
            loss = np.mean([ce[k][0] - ct[k][0] for k in both])
            rec = np.mean([ce[k][1] - ct[k][1] for k in both])
            # A ratio of two near-zero differences means nothing (the score's threshold).
            ratio = f"{diff_e / diff_t:.2f}" if abs(diff_t) >= MIN_DIFFERENCE else "n/a"
            cols.append(
                f"axle {axle}: {len(both):2d} pairs, ratio {ratio}"
                f" (loss {loss:+.4f}, recovery {rec:+.4f})"
            )
        print(f"{run:18s} " + " | ".join(cols))
    if compared == 0:
        sys.exit(f"no run of {run_out} has its truth table in {archive}: nothing compared")


if __name__ == "__main__":
    main()
