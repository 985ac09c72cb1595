#!/usr/bin/env python3
"""A simulated campaign's estimates with one column replaced by the truth's, for `railgrip train`.

Copies every runs/<run>/estimates.parquet of a `railgrip run` output folder to
OUT_DIR/<run>.estimates.parquet (the name `railgrip train` takes) with the named columns
(default ddv_mps2, the slip rate) taken from <archive>/<run>.truth.parquet, matched per axle
to the nearest truth sample in time (within 1 ms; where none is that close the estimate is
kept). Every other column, and the file's run metadata, stay as they were. Training on the
result asks how much of a model's error comes from that column's estimation error:

    python3 scripts/true-slip-rate.py ARCHIVE_DIR RUN_OUT_DIR OUT_DIR [COLUMNS]
    railgrip train OUT_DIR/*.estimates.parquet --out OUT_DIR/models
    railgrip score OUT_DIR/models/mlp.residual.json pipelines/scenes/top_speed/*.toml --seeds N

COLUMNS is a comma-separated list of estimate columns the truth table also has (ddv_mps2,
dv_mps, mu, v_mps, omega_radps, p_bar, normal_N, tangential_N). Needs numpy, pandas and
pyarrow. docs/training.md ("The estimated slip rate is the cause") used it with the default.
"""
import glob
import os
import sys

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq


def replaced(estimates, truth, columns):
    """The estimates table with `columns` from the truth, matched per axle by time."""
    keys = pd.DataFrame(
        {
            "time_s": estimates["time_s"].to_numpy(),
            "axle": estimates["axle"].to_numpy(),
            "row": np.arange(estimates.num_rows),
        }
    )
    parts = []
    for axle in np.unique(keys.axle):
        e = keys[keys.axle == axle].sort_values("time_s")
        t = truth[truth.axle == axle].sort_values("time_s")[["time_s"] + columns]
        t = t.rename(columns={c: c + "_true" for c in columns})
        parts.append(pd.merge_asof(e, t, on="time_s", direction="nearest", tolerance=1e-3))
    matched = pd.concat(parts).sort_values("row")
    for c in columns:
        field = estimates.schema.field(c)
        old = estimates[c].to_numpy(zero_copy_only=False).astype(float)
        new = matched[c + "_true"].to_numpy(dtype=float)
        values = np.where(np.isnan(new), old, new)
        idx = estimates.schema.get_field_index(c)
        estimates = estimates.set_column(idx, field, pa.array(values, type=field.type))
    return estimates


def main():
    if len(sys.argv) not in (4, 5):
        sys.exit(__doc__)
    archive, run_out, out = sys.argv[1:4]
    columns = (sys.argv[4] if len(sys.argv) == 5 else "ddv_mps2").split(",")
    paths = sorted(glob.glob(os.path.join(run_out, "runs", "*", "estimates.parquet")))
    if not paths:
        sys.exit(f"no runs/*/estimates.parquet under {run_out}: give the output folder of `railgrip run`")
    os.makedirs(out, exist_ok=True)
    for path in paths:
        run = os.path.basename(os.path.dirname(path))
        truth_path = os.path.join(archive, f"{run}.truth.parquet")
        if not os.path.exists(truth_path):
            sys.exit(f"{truth_path}: missing; give the archive the run was simulated into")
        truth = pq.read_table(truth_path).to_pandas()
        missing = [c for c in columns if c not in truth.columns]
        if missing:
            sys.exit(f"{truth_path}: no column {missing[0]}; the truth has {', '.join(truth.columns)}")
        table = pq.read_table(path)
        # The run metadata railgrip reads is in the file's key-value metadata.
        meta = {k: v for k, v in (pq.read_metadata(path).metadata or {}).items() if k != b"ARROW:schema"}
        table = replaced(table, truth, columns).replace_schema_metadata(meta)
        pq.write_table(table, os.path.join(out, f"{run}.estimates.parquet"))
        print(f"{run}: {', '.join(columns)} from the truth")


if __name__ == "__main__":
    main()
