#!/usr/bin/env python3
"""A simulated campaign's estimates with columns replaced by the truth's, for `railgrip train`.

Copies every runs/<run>/estimates.parquet of a `railgrip run` output folder to
OUT_DIR/<run>.estimates.parquet (the name `railgrip train` takes). In the runs that --only
selects (default: all), the --columns (default ddv_mps2, the slip rate) are taken from
<archive>/<run>.truth.parquet, matched per axle to the nearest truth sample in time (within
1 ms; where none is that close the estimate is kept); the other runs are copied unedited.
Every other column, and each file's run metadata, stay as they were. Training on the result
asks how much of a model's error comes from that column's estimation error:

    python3 scripts/true-slip-rate.py ARCHIVE_DIR RUN_OUT_DIR OUT_DIR [--columns C1,C2]
                                      [--only PATTERN ...]
    railgrip train OUT_DIR/*.estimates.parquet --out OUT_DIR/models
    railgrip score OUT_DIR/models/mlp.residual.json pipelines/scenes/top_speed/*.toml --seeds N

--columns: estimate columns the truth table also has, numeric (ddv_mps2, dv_mps, mu, v_mps,
omega_radps, p_bar, normal_N, tangential_N). --only: shell patterns of run names
(e.g. 'lrq_160*' 'lrq_200*'). Needs numpy, pandas and pyarrow. docs/training.md ("On seed 1
the estimated slip rate is the cause") used it.
"""
import argparse
import fnmatch
import os
import sys

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from campaign_tables import run_estimates, run_metadata, write_estimates


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


def check_columns(path, schema, columns, what):
    """Exits naming the file when a column is missing or not a floating-point column."""
    for c in columns:
        if c not in schema.names:
            sys.exit(f"{path}: no column {c} in the {what}; it has {', '.join(schema.names)}")
        if not pa.types.is_floating(schema.field(c).type):
            sys.exit(f"{path}: column {c} is {schema.field(c).type}, not a number; give numeric columns")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("archive", help="folder with the scenes' <run>.truth.parquet")
    ap.add_argument("run_out", help="output folder of `railgrip run` on that archive")
    ap.add_argument("out", help="folder to write <run>.estimates.parquet into")
    ap.add_argument("--columns", default="ddv_mps2", help="comma-separated (default ddv_mps2)")
    ap.add_argument("--only", nargs="*", default=["*"], help="run-name patterns to edit (default all)")
    a = ap.parse_args()
    columns = [c for c in a.columns.split(",") if c]
    runs = run_estimates(a.run_out)
    os.makedirs(a.out, exist_ok=True)
    for run, path in runs:
        table = pq.read_table(path)
        meta = run_metadata(path)
        edit = any(fnmatch.fnmatchcase(run, p) for p in a.only)
        if edit:
            truth_path = os.path.join(a.archive, f"{run}.truth.parquet")
            if not os.path.exists(truth_path):
                sys.exit(f"{truth_path}: missing; give the archive the run was simulated into")
            check_columns(path, table.schema, columns, "estimates")
            truth = pq.read_table(truth_path)
            check_columns(truth_path, truth.schema, columns, "truth")
            table = replaced(table, truth.to_pandas(), columns)
        write_estimates(a.out, run, table, meta)
        print(f"{run}: {', '.join(columns) + ' from the truth' if edit else 'unedited'}")


if __name__ == "__main__":
    main()
