"""The package's calls on logs and campaigns in a bucket (moto's S3 server): the values of the
same files read locally, and errors that name the URI."""

from __future__ import annotations

import numpy as np
import pytest

import railgrip

from test_railgrip import ARCHIVE


def test_logs_and_campaigns_in_a_bucket(moto_server, tmp_path):
    s3 = moto_server
    s3.create_bucket(Bucket="logs")
    for f in ["soap_120kmh_p20.csv", "soap_120kmh_p20.meta.toml", "soap_160kmh_0c.mcap",
              "soap_120kmh_m20.csv", "soap_120kmh_m20.meta.toml"]:
        s3.upload_file(str(ARCHIVE / f), "logs", f"r/{f}")
    remote = railgrip.estimate("s3://logs/r/soap_120kmh_p20.csv")
    local = railgrip.estimate(ARCHIVE / "soap_120kmh_p20.csv")
    assert remote.attrs["metadata"] == local.attrs["metadata"]  # the sidecar came along
    for c in local.columns:
        assert np.array_equal(remote[c].to_numpy(), local[c].to_numpy(), equal_nan=True), c
    assert remote.attrs["source"] == "s3://logs/r/soap_120kmh_p20.csv"
    log = railgrip.read_log("s3://logs/r/soap_160kmh_0c.mcap")
    assert log.attrs["format"] == "MCAP" and len(log) > 1000
    models = railgrip.train(["s3://logs/r"])
    assert models.runs == 3
    paths = [i["path"] for i in models["mlp"].provenance["inputs"]]
    assert paths == sorted(paths) and all(p.startswith("s3://logs/r/") for p in paths)
    result = railgrip.run("s3://logs/r", tmp_path / "out")
    assert result.failed == 0 and (tmp_path / "out" / "campaign.json").exists()
    with pytest.raises(railgrip.RailgripError, match="s3://logs/r/nope.csv: no such object"):
        railgrip.read_log("s3://logs/r/nope.csv")
    with pytest.raises(railgrip.RailgripError, match="s3://nobucket"):
        railgrip.run("s3://nobucket/x", tmp_path / "o2")
    with pytest.raises(railgrip.RailgripError, match="an estimates table in a bucket"):
        railgrip.train(["s3://logs/r/x.estimates.parquet"])
