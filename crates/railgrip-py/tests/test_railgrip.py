"""The Python package against the `railgrip` command on the same inputs: the same values, the
same files, the same errors. The command is the binary `cargo build` made (RAILGRIP_BIN, else
target/debug or target/release of the repository)."""

from __future__ import annotations

import filecmp
import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import railgrip

ROOT = Path(__file__).resolve().parents[3]
ARCHIVE = ROOT / "fixtures" / "archive"
CSV_RUN = ARCHIVE / "soap_120kmh_0c.csv"
MCAP_RUN = ARCHIVE / "soap_160kmh_0c.mcap"
# Three runs at two temperatures and two speeds: every fit and the model choice run, quickly.
SMALL = ["soap_120kmh_0c", "soap_120kmh_p20", "soap_160kmh_m20"]


def _binary() -> Path:
    env = os.environ.get("RAILGRIP_BIN")
    candidates = [Path(env)] if env else []
    candidates += [ROOT / "target" / p / "railgrip" for p in ("debug", "release")]
    for c in candidates:
        if c.is_file():
            return c
    raise RuntimeError(
        "no railgrip binary: run `cargo build` in the repository or set RAILGRIP_BIN"
    )


def cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(_binary()), *args], check=True, capture_output=True, text=True
    )


def read_exact(path: Path) -> pd.DataFrame:
    """A CSV of railgrip's with every number parsed by Python's float (correctly rounded, so
    a shortest round-trip text gives back its bits, whatever pandas' parser does)."""
    raw = pd.read_csv(path, dtype=str, keep_default_na=False)
    out = {}
    for c in raw.columns:
        values = raw[c].tolist()
        if c == "valid":
            out[c] = np.array([v == "true" for v in values])
        elif c == "axle":
            out[c] = np.array([int(v) for v in values])
        else:
            out[c] = np.array([float(v) if v != "" else np.nan for v in values])
    return pd.DataFrame(out)


@pytest.fixture(scope="module")
def small_archive(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("archive")
    for name in SMALL:
        for f in ARCHIVE.glob(name + ".*"):
            if not f.name.endswith(".truth.parquet"):
                shutil.copy(f, d / f.name)
    return d


def test_read_log_is_the_uniform_log_of_the_command(tmp_path):
    log = railgrip.read_log(CSV_RUN)
    assert list(log.columns) == [
        "time_s",
        "v_radar_mps",
        *[f"omega{a}_radps" for a in range(1, 5)],
        *[f"p{a}_bar" for a in range(1, 5)],
        "valid",
    ]
    assert log.attrs["sample_rate_hz"] == 417.0
    assert log.attrs["metadata"]["condition"] == "soap"
    # The time base is uniform at the log's rate.
    dt = np.diff(log["time_s"].to_numpy())
    assert np.allclose(dt, 1 / 417.0, rtol=0, atol=1e-9)
    assert log["valid"].dtype == bool
    mcap = railgrip.read_log(MCAP_RUN)
    assert mcap.attrs["format"] == "MCAP" and len(mcap) > 1000
    assert mcap.attrs["start_log_time_ns"] is not None


def assert_same_table(ours: pd.DataFrame, theirs: pd.DataFrame) -> None:
    """The same columns and values: floats to the bit (the CSV holds every float in shortest
    round-trip form), NaN for NaN."""
    assert list(ours.columns) == list(theirs.columns)
    assert len(ours) == len(theirs)
    for c in ours.columns:
        a, b = ours[c].to_numpy(), theirs[c].to_numpy()
        if a.dtype.kind == "f":
            assert np.array_equal(a, b.astype(np.float64), equal_nan=True), c
        else:
            assert np.array_equal(a, b), c


def test_estimate_has_the_values_of_railgrip_estimate(tmp_path):
    ours = railgrip.estimate(CSV_RUN)
    cli("estimate", str(CSV_RUN), "--out", str(tmp_path), "--csv")
    theirs = read_exact(tmp_path / "soap_120kmh_0c.estimates.csv")
    assert_same_table(ours, theirs)
    assert ours.attrs["name"] == "soap_120kmh_0c"
    assert ours.attrs["filter_mode"] in ("zero-phase", "causal")


def test_estimate_with_a_campaigns_calibration_is_railgrip_estimate_with_it(tmp_path, small_archive):
    # The default pipeline ("auto") calibrates the campaign of three runs.
    railgrip.run(small_archive, tmp_path / "o", jobs=2)
    cal = tmp_path / "o" / "calibration.json"
    run = small_archive / "soap_120kmh_0c.csv"
    ours = railgrip.estimate(run, calibration=cal)
    cli("estimate", str(run), "--out", str(tmp_path / "e"), "--csv", "--calibration", str(cal))
    assert_same_table(ours, read_exact(tmp_path / "e" / "soap_120kmh_0c.estimates.csv"))
    # The calibration moved the estimates (the tachometers' counting delay at least).
    plain = railgrip.estimate(run)
    assert not np.array_equal(plain["mu"].to_numpy(), ours["mu"].to_numpy())
    # Fitted with another pipeline file: refused, saying so.
    other = tmp_path / "other.toml"
    other.write_text(railgrip.Pipeline.default().text + "\n# another pipeline\n")
    with pytest.raises(railgrip.RailgripError, match="fitted with another pipeline file"):
        railgrip.estimate(run, railgrip.Pipeline.load(other), calibration=cal)
    # A calibration file that is not there: refused, naming it.
    with pytest.raises(railgrip.RailgripError, match="no_such_calibration.json"):
        railgrip.estimate(run, calibration=tmp_path / "no_such_calibration.json")
    # A pipeline that asks for the campaign's calibration is refused without one.
    asks = tmp_path / "asks.toml"
    asks.write_text(
        railgrip.Pipeline.default().text.replace(
            "[estimate]\n", '[estimate]\ncalibration = "campaign"\n', 1
        )
    )
    with pytest.raises(railgrip.RailgripError, match="needs the campaign's calibration"):
        railgrip.estimate(run, railgrip.Pipeline.load(asks))


def test_model_mu_is_railgrip_eval_bit_for_bit(tmp_path, small_archive):
    out = tmp_path / "models"
    cli("train", str(small_archive), "--out", str(out), "--quiet")
    rng = np.random.default_rng(7)
    n = 500
    grid = pd.DataFrame(
        {
            "dv_mps": rng.uniform(-0.5, 4.0, n),
            "ddv_mps2": rng.uniform(-3.0, 3.0, n),
            "v_mps": rng.uniform(5.0, 50.0, n),
            "ambient_temperature_c": rng.uniform(-25.0, 25.0, n),
        }
    )
    names = ["mlp.json", "mlp.3in.json", "mlp.4in.json", "mlp.residual.json", "mlp.polach.json"]
    files = [out / n for n in names]
    for f in files:
        model = railgrip.Model.load(f)
        cols = ["dv_mps", "ddv_mps2", "v_mps", "ambient_temperature_c"]
        grid[cols].to_csv(tmp_path / "in.csv", index=False)
        cli("eval", str(f), "--input", str(tmp_path / "in.csv"), "--output", str(tmp_path / "o.csv"))
        expected = read_exact(tmp_path / "o.csv")["mu"].to_numpy()
        got = model.mu(grid.dv_mps, grid.ddv_mps2, v=grid.v_mps, t=grid.ambient_temperature_c)
        assert np.array_equal(got, expected), f.name


def test_model_mu_broadcasts_and_returns_scalars_for_scalars(tmp_path, small_archive):
    models = railgrip.train(small_archive)
    m = models["mlp"]
    grid = m.mu(np.linspace(0, 2, 5)[:, None], np.linspace(-1, 1, 3)[None, :])
    assert grid.shape == (5, 3)
    assert isinstance(m.mu(1.0, 0.1), float)
    assert m.mu(1.0, 0.0) == grid[2, 1]
    # Non-finite slip gives NaN, not an exception or a crash.
    assert np.isnan(m.mu(np.nan, 0.0))
    p = models["polach"]
    assert p.kind == "polach" and p.inputs[0] == "dv_mps"
    assert all(lo <= hi for lo, hi in p.domain.values())
    s = m.support
    assert s is not None and s["counts"].shape == s["cells"]
    assert s["supported"].any()
    assert p.support is None
    with pytest.raises(ValueError, match="unequal length"):
        m._native.mu(np.zeros(3), np.zeros(2), np.zeros(0), np.zeros(0))


def test_train_on_paths_writes_what_railgrip_train_writes(tmp_path, small_archive):
    models = railgrip.train([small_archive])
    assert models.runs == 3 and models.condition == "soap"
    assert models.chosen_name in models
    cli("train", str(small_archive), "--out", str(tmp_path), "--quiet")
    files = {
        "mlp": "mlp.json",
        "polach": "mlp.polach.json",
        "mlp_3in": "mlp.3in.json",
        "mlp_4in": "mlp.4in.json",
        "residual": "mlp.residual.json",
    }
    assert sorted(models) == sorted(files)
    for name, file in files.items():
        assert models[name].json == (tmp_path / file).read_text(), name


def test_train_on_estimate_tables_gives_the_same_models(small_archive):
    runs = sorted(small_archive.glob("*.csv")) + sorted(small_archive.glob("*.mcap"))
    frames = [railgrip.estimate(r) for r in runs]
    from_frames = railgrip.train(frames)
    from_paths = railgrip.train(runs)
    assert list(from_frames) == list(from_paths)
    dv, ddv = np.linspace(0, 3, 40), np.linspace(-2, 2, 40)
    for name in from_paths:
        a = from_frames[name].mu(dv, ddv, v=30.0, t=5.0)
        b = from_paths[name].mu(dv, ddv, v=30.0, t=5.0)
        assert np.array_equal(a, b), name
    # The tables' provenance names them as tables in memory.
    src = [i["path"] for i in from_frames["mlp"].provenance["inputs"]]
    assert all("in memory" in s for s in src)


def test_run_writes_the_same_bytes_as_railgrip_run(tmp_path, small_archive):
    ours, theirs = tmp_path / "py", tmp_path / "cli"
    result = railgrip.run(small_archive, ours, jobs=2)
    cli("run", str(small_archive), "--out", str(theirs), "--jobs", "2")
    assert result.failed == 0 and len(result.records) == 3
    assert result.report is not None and Path(result.report).is_file()
    assert len(result.runs) == 3
    # The candidates' table, as the file holds it.
    with open(ours / "models" / "mlp.choice.json") as f:
        assert result.choice == json.load(f)

    def files(d: Path):
        return sorted(p.relative_to(d) for p in d.rglob("*") if p.is_file())

    assert files(ours) == files(theirs)
    differ = [
        str(p)
        for p in files(ours)
        if p.name != "timings.json" and not filecmp.cmp(ours / p, theirs / p, shallow=False)
    ]
    assert differ == []
    # A second run reuses every run, as the command does.
    again = railgrip.run(small_archive, ours)
    assert again.reused == 3


def test_errors_name_the_file_and_say_what_to_do(tmp_path):
    missing = tmp_path / "nope.csv"
    with pytest.raises(railgrip.RailgripError, match="nope.csv"):
        railgrip.read_log(missing)
    bad = tmp_path / "bad.toml"
    bad.write_text("[ingest\n")
    with pytest.raises(railgrip.RailgripError, match="bad.toml"):
        railgrip.Pipeline.load(bad)
    model = tmp_path / "m.json"
    model.write_text('{"format": "railgrip-model"}')
    with pytest.raises(railgrip.RailgripError, match="m.json"):
        railgrip.Model.load(model)
    with pytest.raises(TypeError, match="item 1"):
        railgrip.train([42])
    bare = railgrip.estimate(CSV_RUN)
    bare.attrs.pop("metadata")
    with pytest.raises(railgrip.RailgripError, match="metadata"):
        railgrip.train([bare])
    frame = railgrip.estimate(CSV_RUN).drop(columns=["mu"])
    with pytest.raises(railgrip.RailgripError, match="mu"):
        railgrip.train([frame])
    frame = railgrip.estimate(CSV_RUN)
    frame.loc[frame.index[frame["valid"]][0], "axle"] = 7
    with pytest.raises(railgrip.RailgripError, match="axle = 7"):
        railgrip.train([frame])
    with pytest.raises(ValueError, match="jobs"):
        railgrip.run(ARCHIVE, tmp_path / "o", jobs=0)
    # A campaign folder without logs is an error naming it.
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(railgrip.RailgripError, match="empty"):
        railgrip.run(empty, tmp_path / "o2")


def test_a_pipeline_file_is_used(tmp_path):
    text = (ROOT / "pipelines" / "uic_z1.toml").read_text()
    p = tmp_path / "mine.toml"
    p.write_text(text)
    pipeline = railgrip.Pipeline.load(p)
    assert pipeline.source.endswith("mine.toml")
    a = railgrip.estimate(CSV_RUN, pipeline)
    b = railgrip.estimate(CSV_RUN)
    assert np.array_equal(a["mu"].to_numpy(), b["mu"].to_numpy(), equal_nan=True)
