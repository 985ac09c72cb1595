"""The notebooks in docs/ run: every code cell in order, in one namespace, in a scratch folder
that sees the repository's fixtures (as a kernel started at the root would)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

if os.environ.get("CI") == "true":
    import fmpy  # noqa: F401  CI installs them: a missing one fails there
    import matplotlib
else:
    matplotlib = pytest.importorskip("matplotlib")

ROOT = Path(__file__).resolve().parents[3]


def run_notebook(name: str, folder: Path) -> dict:
    matplotlib.use("Agg")
    (folder / "fixtures").symlink_to(ROOT / "fixtures")
    os.chdir(folder)
    notebook = ROOT / "docs" / name
    cells = [c for c in json.loads(notebook.read_text())["cells"] if c["cell_type"] == "code"]
    assert len(cells) >= 4
    ns: dict = {"__name__": "__notebook__"}
    for i, cell in enumerate(cells):
        exec(compile("".join(cell["source"]), f"{name} cell {i}", "exec"), ns)
    return ns


def test_the_python_notebook_runs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    ns = run_notebook("python-notebook.ipynb", tmp_path)
    # What the cells made: a bias table with the top speed band of the 160 km/h runs, the
    # figure and the model file.
    bias = ns["bias"]
    top = bias[(bias.run == "soap_160kmh_0c") & (bias.band_kmh.astype(str) == "[145, 170)")]
    assert len(top) == 3 and top.bias.abs().max() < 0.05 and top.rmse.notna().all()
    assert (tmp_path / "curve.png").stat().st_size > 10_000
    assert (tmp_path / "chosen.json").exists()


def test_the_fmu_notebook_runs(tmp_path, monkeypatch):
    if os.environ.get("CI") != "true":
        pytest.importorskip("fmpy")
    monkeypatch.chdir(tmp_path)
    ns = run_notebook("fmu-notebook.ipynb", tmp_path)
    assert ns["n"] > 500 and (tmp_path / "adhesion.fmu").exists()
    assert (tmp_path / "fmu.png").stat().st_size > 10_000
