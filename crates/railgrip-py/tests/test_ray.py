"""railgrip.ray on a local Ray (2 CPUs, a small object store: containers have little
/dev/shm): the same bytes as `railgrip run`, from a local folder with a broken log and a
worker killed mid-task, and from and to an S3 API server (moto's server mode)."""

from __future__ import annotations

import filecmp
import json
import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

if os.environ.get("CI") == "true":
    import ray  # CI installs it: a missing Ray fails there
else:
    ray = pytest.importorskip("ray")

import railgrip
import railgrip.ray

from test_railgrip import ARCHIVE, SMALL, _binary

KILL_MARKER_ENV = "RAILGRIP_TEST_KILL_WORKER_ONCE"


@pytest.fixture(scope="module")
def local_ray(tmp_path_factory):
    marker = tmp_path_factory.mktemp("kill") / "killed"
    ray.init(
        num_cpus=2,
        object_store_memory=80 * 1024 * 1024,
        include_dashboard=False,
        runtime_env={"env_vars": {KILL_MARKER_ENV: str(marker)}},
    )
    yield marker
    ray.shutdown()


def campaign(d: Path, broken: bool) -> Path:
    d.mkdir()
    for name in SMALL:
        for f in ARCHIVE.glob(name + ".*"):
            if not f.name.endswith(".truth.parquet"):
                shutil.copy(f, d / f.name)
    if broken:
        (d / "broken.csv").write_text("t,v_radar\n0,abc\n")
    return d


def railgrip_cli(*args: str, env=None) -> int:
    return subprocess.run([str(_binary()), *args], capture_output=True, env=env).returncode


def tree(d: Path):
    return sorted(p.relative_to(d) for p in d.rglob("*") if p.is_file() and p.name != "timings.json")


def assert_same_tree(a: Path, b: Path):
    assert tree(a) == tree(b) and len(tree(a)) >= 12
    differ = [str(p) for p in tree(a) if not filecmp.cmp(a / p, b / p, shallow=False)]
    assert differ == []


def test_ray_run_writes_the_bytes_of_railgrip_run(local_ray, tmp_path):
    camp = campaign(tmp_path / "camp", broken=True)
    lines = []
    result = railgrip.ray.run(camp, tmp_path / "ray", progress=lines.append)
    # The first run's worker was killed once at the start of its task; Ray ran it again.
    assert local_ray.exists()
    assert result.failed == 1 and len(result.records) == 4 and result.reused == 0, lines
    assert any("broken: FAILED" in line for line in lines), lines
    assert sum(": ok (" in line for line in lines) == 3, lines
    assert railgrip_cli("run", str(camp), "--out", str(tmp_path / "cli")) == 3
    assert_same_tree(tmp_path / "ray", tmp_path / "cli")
    # timings.json says what the tasks did: every ok run computed, in some time.
    timings = json.loads((tmp_path / "ray" / "timings.json").read_text())
    ok_runs = [r for r in timings["runs"] if r["run"] != "broken"]
    assert len(ok_runs) == 3 and all(not r["reused"] and r["duration_s"] > 0 for r in ok_runs), timings
    # Run again: every run is reused, the bytes stay.
    lines = []
    again = railgrip.ray.run(camp, tmp_path / "ray", progress=lines.append)
    assert again.reused == 3, lines  # the broken log is estimated (and fails) again
    assert sum(": unchanged, reused" in line for line in lines) == 3, lines
    assert_same_tree(tmp_path / "ray", tmp_path / "cli")
    timings = json.loads((tmp_path / "ray" / "timings.json").read_text())
    assert sum(r["reused"] for r in timings["runs"]) == 3, timings


def download(s3, bucket: str, prefix: str, dest: Path):
    for page in s3.get_paginator("list_objects_v2").paginate(Bucket=bucket, Prefix=prefix + "/"):
        for o in page.get("Contents", []):
            target = dest / o["Key"][len(prefix) + 1 :]
            target.parent.mkdir(parents=True, exist_ok=True)
            s3.download_file(bucket, o["Key"], str(target))


def test_ray_run_from_and_to_object_storage(local_ray, moto_server, tmp_path):
    s3 = moto_server
    s3.create_bucket(Bucket="campaigns")
    camp = campaign(tmp_path / "camp", broken=False)
    for f in sorted(camp.iterdir()):
        s3.upload_file(str(f), "campaigns", f"2026/a/{f.name}")
    result = railgrip.ray.run("s3://campaigns/2026/a", "s3://campaigns/2026/ray", progress=lambda _: None)
    assert result.failed == 0 and result.report == "s3://campaigns/2026/ray/report/index.html"
    # Ray workers were started with the driver's environment at ray.init; the endpoint
    # reaches them through it (AWS_* in the environment of the cluster's processes).
    assert railgrip_cli("run", "s3://campaigns/2026/a", "--out", "s3://campaigns/2026/cli", env=dict(os.environ)) == 0
    download(s3, "campaigns", "2026/ray", tmp_path / "ray")
    download(s3, "campaigns", "2026/cli", tmp_path / "cli")
    assert_same_tree(tmp_path / "ray", tmp_path / "cli")


def test_a_run_whose_task_never_finishes_fails_alone(local_ray, tmp_path):
    camp = campaign(tmp_path / "camp", broken=False)
    victim = railgrip._native.campaign_runs(str(camp))[1][0]
    lines = []
    result = railgrip.ray.run(
        camp,
        tmp_path / "ray",
        progress=lines.append,
        max_retries=1,
        env={"RAILGRIP_TEST_KILL_WORKER": victim},
    )
    # Killed at both attempts: that run is failed, the others are trained on and reported.
    failed = [r for r in result.records if r["status"] != "ok"]
    assert [r["run"] for r in failed] == [victim], lines
    assert "the Ray task did not finish" in failed[0]["error"]
    assert any(f"{victim}: FAILED" in line for line in lines), lines
    assert result.report is not None and len(result.models) >= 2
    record = json.loads((tmp_path / "ray" / "campaign.json").read_text())
    assert [r["status"] for r in record["runs"] if r["run"] == victim] == ["failed"]
    # Nothing of that run is in the output folder.
    assert not (tmp_path / "ray" / "runs" / victim).exists()


def test_a_task_reads_its_own_log_without_listing_the_campaign(tmp_path):
    # The campaign folder is not there at all: the task is handed its log and never lists it.
    log = ARCHIVE / (SMALL[0] + ".mcap")
    if not log.exists():
        log = next(ARCHIVE.glob(SMALL[0] + ".*"))
    facts, parts = railgrip._native.estimate_run(
        str(tmp_path / "nowhere"), "one", str(log), str(tmp_path / "out")
    )
    facts = json.loads(facts)
    assert facts["record"]["status"] == "ok" and facts["record"]["source"] == str(log)
    table = railgrip.ray.to_arrow(parts)
    assert table.column_names == list(railgrip.ray.COLUMNS) and table.num_rows > 1000
    assert table.schema.field("axle").type == "uint8"
    back = railgrip.ray.from_arrow(table)
    assert back[:4] == parts[:4] and all((a == b).all() for a, b in zip(back[4:], parts[4:]))
    # The same valid samples as railgrip.estimate gives for the log.
    df = railgrip.estimate(log)
    valid = df[df["valid"]]
    assert len(valid) == table.num_rows
    assert sorted(valid["mu"].to_numpy()) == sorted(table.column("mu").to_numpy())


def test_the_models_task_refuses_missing_runs_and_foreign_tables(tmp_path):
    camp = campaign(tmp_path / "camp", broken=False)
    runs = railgrip._native.campaign_runs(str(camp))
    out = str(tmp_path / "out")
    # The default pipeline calibrates the campaign's 3 runs: the parts are given it.
    pipeline = railgrip._native.calibrate_campaign(str(camp), out, railgrip.Pipeline.default())
    assert pipeline.calibration is not None
    name, _, log = runs[0]
    facts, parts = railgrip._native.estimate_run(str(camp), name, log, out, pipeline)
    record = json.dumps(json.loads(facts)["record"])
    one = railgrip._native.RunSet()
    one.add(record, parts)
    assert len(one) == 1
    with pytest.raises(railgrip.RailgripError, match=r"2 of the campaign's 3 runs were not given: .*" + runs[1][0]):
        railgrip._native.run_models(str(camp), out, one, pipeline)
    import pyarrow as pa

    with pytest.raises(railgrip.RailgripError, match="schema metadata"):
        railgrip.ray.from_arrow(pa.table({"mu": [0.1]}))
    bad = list(parts)
    bad[4] = bad[4].copy()
    bad[4][0] = 7
    with pytest.raises(railgrip.RailgripError, match="axle 7"):
        railgrip._native.RunSet().add(record, tuple(bad))
    with pytest.raises(railgrip.RailgripError, match="record does not parse"):
        railgrip._native.RunSet().add("{}", None)
    # Every run, but one twice, one the campaign does not have, and a table under another
    # run's record: each named.
    results = [railgrip._native.estimate_run(str(camp), n, l, out, pipeline) for n, _, l in runs]
    recs = [json.dumps(json.loads(f)["record"]) for f, _ in results]
    bad = railgrip._native.RunSet()
    bad.add(recs[0], results[0][1])
    bad.add(recs[1], results[2][1])  # run 2's record, run 3's table
    bad.add(recs[2], results[2][1])
    bad.add(recs[2], results[2][1])
    foreign = json.loads(recs[0])
    foreign["run"] = "elsewhere"
    bad.add(json.dumps(foreign), None)
    with pytest.raises(railgrip.RailgripError) as e:
        railgrip._native.run_models(str(camp), out, bad, pipeline)
    text = str(e.value)
    assert f"{runs[1][0]}: the table of run {runs[2][0]!r}" in text.replace('"', "'"), text
    assert f"{runs[2][0]}: given twice" in text, text
    assert "elsewhere: not a run of this campaign" in text, text


def test_a_self_calibrating_campaign_on_ray_writes_the_bytes_of_railgrip_run(local_ray, tmp_path):
    """estimate.calibration = "campaign": the driver fits the calibration once over every run
    (calibration.json in the output), each task estimates its run with it, and the files are
    those of `railgrip run` with the same pipeline."""
    camp = campaign(tmp_path / "camp", broken=False)
    text = (ARCHIVE.parent.parent / "pipelines" / "uic_z1.toml").read_text()
    pipe = tmp_path / "campaign.toml"
    pipe.write_text(text.replace("[estimate]\n", '[estimate]\ncalibration = "campaign"\n', 1))
    pipeline = railgrip.Pipeline.load(pipe)
    assert pipeline.calibration_source == "campaign" and pipeline.calibration is None
    lines = []
    result = railgrip.ray.run(camp, tmp_path / "ray", pipeline=pipeline, progress=lines.append)
    assert result.failed == 0, lines
    assert any(line.startswith("calibrate ") for line in lines), lines
    assert railgrip_cli("run", str(camp), "--pipeline", str(pipe), "--out", str(tmp_path / "cli")) == 0
    assert (tmp_path / "ray" / "calibration.json").exists()
    assert_same_tree(tmp_path / "ray", tmp_path / "cli")
    record = json.loads((tmp_path / "ray" / "campaign.json").read_text())
    assert record["calibration"]["source"] == "campaign"


def test_a_campaign_auto_cannot_calibrate_runs_on_ray_as_railgrip_run(local_ray, tmp_path):
    """The default pipeline ("auto") on two good runs and a broken log: no calibration can be
    fitted; the driver writes the record that says so, the tasks and the models task follow it,
    and the files are those of `railgrip run`."""
    camp = tmp_path / "camp"
    camp.mkdir()
    for name in SMALL[:2]:
        for f in ARCHIVE.glob(name + ".*"):
            if not f.name.endswith(".truth.parquet"):
                shutil.copy(f, camp / f.name)
    (camp / "broken.csv").write_text("t,v_radar\n0,abc\n")
    lines = []
    result = railgrip.ray.run(camp, tmp_path / "ray", progress=lines.append)
    assert result.failed == 1, lines
    assert railgrip_cli("run", str(camp), "--out", str(tmp_path / "cli")) == 3
    assert_same_tree(tmp_path / "ray", tmp_path / "cli")
    record = json.loads((tmp_path / "ray" / "calibration.json").read_text())
    assert record["calibrated"]["source"] == "none", record
    assert "only 2 runs" in record["notes"][0], record
