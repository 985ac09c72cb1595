"""docs/python-notebook.ipynb runs: every code cell in order, in one namespace, in a scratch
folder that sees the repository's fixtures (as a kernel started at the root would)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

if os.environ.get("CI") == "true":
    import matplotlib  # CI installs it: a missing matplotlib fails there
else:
    matplotlib = pytest.importorskip("matplotlib")

ROOT = Path(__file__).resolve().parents[3]
NOTEBOOK = ROOT / "docs" / "python-notebook.ipynb"


def test_the_notebook_runs(tmp_path, monkeypatch):
    matplotlib.use("Agg")
    (tmp_path / "fixtures").symlink_to(ROOT / "fixtures")
    monkeypatch.chdir(tmp_path)
    cells = [c for c in json.loads(NOTEBOOK.read_text())["cells"] if c["cell_type"] == "code"]
    assert len(cells) >= 5
    ns: dict = {"__name__": "__notebook__"}
    for i, cell in enumerate(cells):
        source = "".join(cell["source"])
        exec(compile(source, f"{NOTEBOOK.name} cell {i}", "exec"), ns)
    # What the cells made: a bias table with the top speed band of the 160 km/h runs, the
    # figure and the model file.
    bias = ns["bias"]
    top = bias[(bias.run == "soap_160kmh_0c") & (bias.band_kmh.astype(str) == "[145, 170)")]
    assert len(top) == 3 and top.bias.abs().max() < 0.05 and top.rmse.notna().all()
    assert (tmp_path / "curve.png").stat().st_size > 10_000
    assert (tmp_path / "chosen.json").exists()
