"""railgrip campaigns on a Ray cluster: one Ray task per run, then the models as one task.

>>> import ray, railgrip.ray
>>> ray.init(address="auto")                  # or ray.init(num_cpus=2) on one machine
>>> result = railgrip.ray.run("s3://tests/2026/campaign", "s3://tests/2026/out")

The driver lists the campaign once and hands each task its run's name and log (a file's path
or an object's URI; a member of an archive has none, and its task reads the archive to find
it). Each task estimates its run into the output folder (local paths must be on a file system
every node sees; ``s3://`` works anywhere), exactly as ``railgrip run --stage estimate`` does
for a shard of one run: an unchanged run is reused, a run whose log is broken becomes a failed
record. It returns the run's record and its estimates as an Arrow table (``pyarrow``; the valid
samples the models train on: ``axle``, ``time_s``, ``v_mps``, ``dv_mps``, ``ddv_mps2``, ``mu``,
with the run's name, source, log SHA-256 and metadata in the schema's metadata), which stays in
Ray's object store. When every run task is done, one task takes those tables, trains the models
and writes the summary, ``campaign.json`` and the report (the models part of ``railgrip run``).
The files are the same bytes as ``railgrip run`` on the same inputs, but ``timings.json``.

A task whose worker dies is retried (``max_retries``); a run whose task still does not finish,
or fails (an error railgrip raised in it), is a failed run (its record says why) and the
campaign goes on without it; so is a run whose table Ray lost. Files such a task wrote before
it died may remain in the run's folder (the next campaign reuses or rewrites them).
``campaign.json`` and the report are written last, so nothing half-written is left as a
finished campaign. A task that hangs is waited for.
"""

from __future__ import annotations

import json
import os
import sys
import time
from typing import Any, Callable, Dict, List, Optional, Tuple, Union

from . import Campaign, Pipeline, _native

__all__ = ["run", "to_arrow", "from_arrow"]

#: The columns of a run's Arrow table, in order.
COLUMNS = ("axle", "time_s", "v_mps", "dv_mps", "ddv_mps2", "mu")


def to_arrow(parts: Tuple[Any, ...]) -> Any:
    """A run table (the parts ``_native.estimate_run`` returns) as a ``pyarrow.Table``: the
    columns of :data:`COLUMNS` (``axle`` uint8, the others float64, SI units as their names
    say) and the run's name, source, log SHA-256 and metadata (JSON) in the schema metadata."""
    import pyarrow as pa

    name, source, sha256, metadata, *columns = parts
    return pa.table(
        dict(zip(COLUMNS, columns)),
        metadata={
            "railgrip.run": name,
            "railgrip.source": source,
            "railgrip.sha256": sha256,
            "railgrip.metadata": json.dumps(metadata, sort_keys=True),
        },
    )


def from_arrow(table: Any) -> Tuple[Any, ...]:
    """The parts of a run table from :func:`to_arrow`'s ``pyarrow.Table``."""
    meta = {k.decode(): v.decode() for k, v in (table.schema.metadata or {}).items()}
    missing = [k for k in ("railgrip.run", "railgrip.source", "railgrip.sha256", "railgrip.metadata") if k not in meta]
    if missing:
        raise _native.RailgripError(
            f"a run table without {', '.join(missing)} in its schema metadata. "
            "Hint: hand over the table the run's estimate task returned, unchanged"
        )
    import numpy as np

    def column(name: str, dtype: Any) -> Any:
        if name not in table.column_names:
            raise _native.RailgripError(
                f"{meta['railgrip.run']}: the run table has no column {name!r}. "
                "Hint: hand over the table the run's estimate task returned, unchanged"
            )
        return np.ascontiguousarray(table.column(name).to_numpy(), dtype=dtype)

    return (
        meta["railgrip.run"],
        meta["railgrip.source"],
        meta["railgrip.sha256"],
        json.loads(meta["railgrip.metadata"]),
        column("axle", np.uint8),
        *(column(c, np.float64) for c in COLUMNS[1:]),
    )


def _estimate(
    archive: str, run: str, log: Optional[str], out: str, pipeline: Optional[Pipeline], first: bool
) -> Tuple[Dict[str, Any], Any]:
    # The tests' ways to kill a worker: once, at the start of the first run's task (a marker
    # file records it), or at every attempt of one run.
    marker = os.environ.get("RAILGRIP_TEST_KILL_WORKER_ONCE")
    if marker and first and not os.path.exists(marker):
        open(marker, "w").close()
        os._exit(1)
    if os.environ.get("RAILGRIP_TEST_KILL_WORKER") == run:
        os._exit(1)
    facts, parts = _native.estimate_run(archive, run, log, out, pipeline, False)
    return json.loads(facts), (None if parts is None else to_arrow(parts))


def _models(
    archive: str,
    out: str,
    pipeline: Optional[Pipeline],
    jobs: Optional[int],
    runs: List[Tuple[str, str, str, bool, float]],
    tables: List[Any],
) -> str:
    import ray

    # The tables stay in the object store until here (references nested in a list are not
    # resolved by Ray on the way in); None for a run that has no table. `runs`: (name, source,
    # record JSON, reused, seconds) per run.
    given = _native.RunSet()
    for (name, source, rec, reused, seconds), ref in zip(runs, tables):
        table = None
        if ref is not None:
            # One table at a time: it is copied in, and the object store's copy let go. A
            # table Ray lost (its node died and it could not be made again) fails its run.
            try:
                table = ray.get(ref)
            except Exception as e:
                why = f"{source}: its estimates were lost in Ray's object store: {type(e).__name__}: {e}"
                given.add(_native.failed_record(name, source, why), None)
                continue
        given.add(rec, None if table is None else from_arrow(table), reused, seconds)
        del table
    return _native.run_models(archive, out, given, pipeline, jobs)


def _why(source: str, e: Exception) -> str:
    """Why a run's task gave no result: an error railgrip raised in it (a bucket it could not
    reach), or a task Ray could not finish (its worker died at every attempt)."""
    import ray.exceptions as rex

    if isinstance(e, rex.RayTaskError):
        cause = e.cause if getattr(e, "cause", None) is not None else e
        return f"{source}: the run's task failed: {type(cause).__name__}: {cause}"
    return f"{source}: the Ray task did not finish: {type(e).__name__}: {e}"


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
    # A campaign that calibrates itself (the default pipeline's "auto" from 3 runs on) is
    # calibrated here, once, over every run; each task is then given the pipeline that carries
    # the calibration (the two passes of `railgrip run`).
    if pipeline is None:
        pipeline = _native.Pipeline.default()
    if pipeline.calibration_source != "pipeline":
        say(f"calibrate  {n} run(s) from {archive} ({pipeline.calibration_source})")
        pipeline = _native.calibrate_campaign(archive, out, pipeline)
    say(f"estimate   {n} run(s) from {archive} as {n} Ray task(s)")
    # Tasks reach a bucket with the driver's AWS_* settings unless told otherwise.
    if env is None and any(x.startswith("s3://") for x in (archive, out)):
        env = {k: v for k, v in os.environ.items() if k.startswith("AWS_")}
    options: Dict[str, Any] = {"runtime_env": {"env_vars": env}} if env else {}
    estimate = ray.remote(num_cpus=1, max_retries=max_retries, num_returns=2)(_estimate).options(**options)
    start = time.monotonic()
    # Per run: (name, source, record JSON, reused, seconds) once its task is done.
    done_runs: List[Any] = [None] * n
    tables: List[Any] = [None] * n
    pending = {}
    for k, (name, _, log) in enumerate(runs):
        info, table = estimate.remote(archive, name, log, out, pipeline, k == 0)
        pending[info] = k
        tables[k] = table
    reused = 0
    while pending:
        ready, _ = ray.wait(list(pending), num_returns=min(len(pending), 64), timeout=1.0)
        for ref in ready:
            k = pending.pop(ref)
            name, source, _ = runs[k]
            try:
                result = ray.get(ref)
            except Exception as e:  # that run only
                why = _why(source, e)
                done_runs[k] = (name, source, _native.failed_record(name, source, why), False, 0.0)
                tables[k] = None
                say(f"run        {name}: FAILED: {why}")
                continue
            record = result["record"]
            done_runs[k] = (name, source, json.dumps(record), result["reused"], result["seconds"])
            if record.get("status") != "ok":
                tables[k] = None
            reused += result["reused"]
            say(_line(result))
    say("train      network and Polach fits on the pooled estimates (one Ray task)")
    models = ray.remote(num_cpus=models_cpus, max_retries=max_retries)(_models).options(**options)
    facts = json.loads(ray.get(models.remote(archive, out, pipeline, models_cpus, done_runs, tables)))
    facts["stages"] = [tuple(s) for s in facts["stages"]]
    facts["reused"] = reused
    say(f"time       estimate and train {time.monotonic() - start:.2f} s")
    return Campaign(**facts)
