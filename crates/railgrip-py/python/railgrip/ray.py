"""railgrip campaigns on a Ray cluster: one Ray task per run, then the models as one task.

>>> import ray, railgrip.ray
>>> ray.init(address="auto")                  # or ray.init(num_cpus=2) on one machine
>>> result = railgrip.ray.run("s3://tests/2026/campaign", "s3://tests/2026/out")

Each run is estimated by its own task into the output folder (local paths must be on a file
system every node sees; ``s3://`` works anywhere), exactly as ``railgrip run --stage estimate``
does for a shard of one run: unchanged runs are reused, a run whose log is broken becomes a
failed record. When every run task is done, one task trains the models and writes the summary,
``campaign.json`` and the report (``railgrip run --stage models``). The files are the same
bytes as ``railgrip run`` on the same inputs, but ``timings.json``.

A task whose worker dies is retried (``max_retries``); a run that still has no result is named
by the models task's error (it refuses missing runs), and nothing half-written is left as a
finished campaign (``campaign.json`` and the report are written last).
"""

from __future__ import annotations

import json
import os
import sys
import time
from typing import Any, Callable, Dict, List, Optional, Union

from . import Campaign, Pipeline, _native

__all__ = ["run"]


def _estimate(archive: str, out: str, pipeline: Optional[Pipeline], k: int, n: int) -> Dict[str, Any]:
    # The tests' way to kill a worker once, at the start of a task (a marker file records it).
    marker = os.environ.get("RAILGRIP_TEST_KILL_WORKER_ONCE")
    if marker and k == 1 and not os.path.exists(marker):
        open(marker, "w").close()
        os._exit(1)
    facts = json.loads(
        _native.run(archive, out, pipeline, 1, False, False, "estimate", (k, n))
    )
    seconds = dict(facts["stages"]).get("estimate", 0.0)
    record = facts["records"][0] if facts["records"] else {}
    return {"record": record, "reused": facts["reused"] > 0, "seconds": seconds}


def _models(archive: str, out: str, pipeline: Optional[Pipeline], jobs: Optional[int]) -> str:
    return _native.run(archive, out, pipeline, jobs, False, False, "models", None)


def _line(done: Dict[str, Any]) -> str:
    """A finished run as `railgrip run` prints it."""
    record = done["record"]
    if done["reused"] and record.get("status") == "ok":
        return f"run        {record['run']}: unchanged, reused"
    if record.get("status") == "ok":
        return f"run        {record['run']}: ok ({done['seconds']:.2f} s)"
    return f"run        {record.get('run', '?')}: FAILED: {record.get('error', '')}"


def _absolute(location: str) -> str:
    """A local location as an absolute path (tasks may run elsewhere); URIs as they are."""
    if "://" in location and not location.startswith("file://"):
        return location
    path = location[len("file://"):] if location.startswith("file://") else location
    return os.path.abspath(path)


def run(
    archive: Union[str, "os.PathLike[str]"],
    out: Union[str, "os.PathLike[str]"],
    pipeline: Optional[Pipeline] = None,
    progress: Optional[Callable[[str], None]] = None,
    max_retries: int = 2,
    models_cpus: int = 1,
    env: Optional[Dict[str, str]] = None,
) -> Campaign:
    """Runs the campaign at ``archive`` into ``out`` on the Ray cluster this process is
    connected to (``ray.init()`` first; without it a local Ray is started). ``progress``
    receives one line per finished run and stage (default: printed to stderr, as the command
    prints them); ``models_cpus`` are the CPUs the training task asks Ray for (its threads).
    ``env``: environment variables for the tasks; by default, when a location is ``s3://``,
    the driver's ``AWS_*`` variables (credentials, region, endpoint), so that workers reach the
    bucket as the driver does. They travel in the tasks' runtime environment, which Ray's
    dashboard and state API show, and a session token may expire during a long campaign: pass
    ``{}`` where the workers have credentials of their own (an instance role)."""
    import ray

    archive, out = _absolute(os.fspath(archive)), _absolute(os.fspath(out))
    say = progress or (lambda line: print(line, file=sys.stderr, flush=True))
    if not ray.is_initialized():
        ray.init()
    runs = _native.campaign_runs(archive, out)
    n = len(runs)
    say(f"estimate   {n} run(s) from {archive} as {n} Ray task(s)")
    # Tasks reach a bucket with the driver's AWS_* settings unless told otherwise.
    if env is None and any(x.startswith("s3://") for x in (archive, out)):
        env = {k: v for k, v in os.environ.items() if k.startswith("AWS_")}
    options: Dict[str, Any] = {"runtime_env": {"env_vars": env}} if env else {}
    estimate = ray.remote(num_cpus=1, max_retries=max_retries)(_estimate).options(**options)
    start = time.monotonic()
    pending = {estimate.remote(archive, out, pipeline, k + 1, n): k for k in range(n)}
    reused = 0
    while pending:
        done, _ = ray.wait(list(pending), num_returns=1)
        for ref in done:
            k = pending.pop(ref)
            try:
                result = ray.get(ref)
            except Exception as e:  # a task that failed after its retries: that run only
                say(f"run        {runs[k][0]}: FAILED: {runs[k][1]}: the Ray task did not finish: {e}")
                continue
            reused += result["reused"]
            say(_line(result))
    say("train      network and Polach fits on the pooled estimates (one Ray task)")
    models = ray.remote(num_cpus=models_cpus, max_retries=max_retries)(_models).options(**options)
    facts = json.loads(ray.get(models.remote(archive, out, pipeline, models_cpus)))
    facts["stages"] = [tuple(s) for s in facts["stages"]]
    # The models task finds every run done by the tasks; reused are the runs the tasks kept.
    facts["reused"] = reused
    say(f"time       estimate and train {time.monotonic() - start:.2f} s")
    return Campaign(**facts)
