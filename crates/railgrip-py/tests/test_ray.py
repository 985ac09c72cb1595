"""railgrip.ray on a local Ray (2 CPUs, a small object store: containers have little
/dev/shm): the same bytes as `railgrip run`, from a local folder with a broken log and a
worker killed mid-task, and from and to an S3 API server (moto's server mode)."""

from __future__ import annotations

import filecmp
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
    # Run again: every run is reused, the bytes stay.
    lines = []
    again = railgrip.ray.run(camp, tmp_path / "ray", progress=lines.append)
    assert again.reused == 3, lines  # the broken log is estimated (and fails) again
    assert sum(": unchanged, reused" in line for line in lines) == 3, lines
    assert_same_tree(tmp_path / "ray", tmp_path / "cli")


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
