"""What the analysis scripts share: a `railgrip run` output folder's per-run estimates tables,
their run metadata, and the simulated counting tachometers' default delay.

Imported by the scripts beside it (`python3 scripts/<script>.py` puts this folder on the path).
"""
import glob
import os
import sys

import pyarrow.parquet as pq

# Half of the simulator's default counting window: 8 samples at the default 417 Hz (20 ms
# rounded to whole samples), ms.
COUNTER_DELAY_MS = 8 / 417 / 2 * 1e3


def run_estimates(run_out):
    """(run, path) of every runs/<run>/estimates.parquet under `run_out`, sorted; an exit naming
    the folder when there is none."""
    paths = sorted(glob.glob(os.path.join(run_out, "runs", "*", "estimates.parquet")))
    if not paths:
        sys.exit(f"no runs/*/estimates.parquet under {run_out}: give the output folder of `railgrip run`")
    return [(os.path.basename(os.path.dirname(p)), p) for p in paths]


def run_metadata(path):
    """The file's key-value metadata, where railgrip keeps the run's metadata (Arrow's own
    schema entry left out, so that an edited table's schema is written instead)."""
    return {k: v for k, v in (pq.read_metadata(path).metadata or {}).items() if k != b"ARROW:schema"}


def write_estimates(out, run, table, meta):
    """`table` with `meta` as OUT/<run>.estimates.parquet, the name `railgrip train` takes."""
    pq.write_table(table.replace_schema_metadata(meta), os.path.join(out, f"{run}.estimates.parquet"))
