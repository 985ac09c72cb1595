"""railgrip: wheel–rail adhesion curves from railway braking-test logs, in Python.

The same pipeline as the ``railgrip`` command (the Rust library underneath, no subprocess):

>>> import railgrip
>>> log = railgrip.read_log("run.mcap")              # the log on its uniform time base
>>> est = railgrip.estimate("run.mcap")              # μ per axle and sample, as `railgrip estimate`
>>> models = railgrip.train(["campaign/"])           # the campaign's models, as `railgrip train`
>>> models.chosen.mu([0.5, 1.0], [0.2, -0.1], v=30.0)
>>> result = railgrip.run("campaign.zip", "out")     # the whole job, as `railgrip run`

Tables are pandas DataFrames whose ``attrs`` hold the run's metadata, warnings and gaps.
Errors railgrip reports are :class:`RailgripError` with the library's message (the file, line or
channel, and what to do). Documentation: docs/python.md in the repository.
"""

from __future__ import annotations

import json
import os
import warnings
from dataclasses import dataclass, field
from typing import Any, Dict, Iterable, List, Optional, Tuple, Union

import numpy as np
import pandas as pd

from . import _native
from ._native import Pipeline, RailgripError

__version__ = _native.__version__

__all__ = [
    "Campaign",
    "Model",
    "Models",
    "Pipeline",
    "RailgripError",
    "estimate",
    "read_log",
    "run",
    "train",
]

PathLike = Union[str, "os.PathLike[str]"]


def _frame(columns: Dict[str, np.ndarray], info: str) -> pd.DataFrame:
    frame = pd.DataFrame(columns, copy=False)
    frame.attrs.update(json.loads(info))
    return frame


def read_log(path: PathLike, pipeline: Optional[Pipeline] = None) -> pd.DataFrame:
    """Reads a braking-run log (.csv with its .meta.toml sidecar, or .mcap; a path,
    ``file://PATH`` or ``s3://BUCKET/KEY``) onto its uniform time base, in canonical units: ``time_s``, ``v_radar_mps``, ``omega1_radps`` …
    ``omega4_radps``, ``p1_bar`` … ``p4_bar`` (NaN in gaps) and ``valid`` — the columns of
    ``railgrip ingest --out``. ``attrs``: source, format, sample_rate_hz, metadata (the run's
    key/value pairs as text), start_log_time_ns, warnings, gaps.

    ``pipeline`` maps the file's channel names and units (default: the embedded UIC-Z1
    pipeline). Raises :class:`RailgripError` naming the file, line or channel.
    """
    return _frame(*_native.read_log(os.fspath(path), pipeline))


def estimate(
    path: PathLike,
    pipeline: Optional[Pipeline] = None,
    calibration: Optional[PathLike] = None,
) -> pd.DataFrame:
    """Estimates a run: the long table ``railgrip estimate`` writes (one row per sample and
    axle, time-major): ``time_s``, ``axle`` (1–4), ``v_mps``, ``omega_radps``, ``p_bar``,
    ``dv_mps``, ``ddv_mps2``, ``slip_ratio``, ``decel_mps2``, ``normal_N``, ``tangential_N``,
    ``mu`` and ``valid``; the same values as the command. ``attrs`` as :func:`read_log`, plus
    filter_mode, group_delay_s and despiked. The table (with its ``attrs``) can be given to
    :func:`train`. A run alone cannot calibrate itself: with ``estimate.calibration = "auto"``
    (the default) it is estimated with the pipeline's α and the radar as logged, as the command
    does without ``--calibration``. ``calibration``: a campaign's ``calibration.json`` (what
    :func:`run`, :func:`railgrip.ray.run` or ``railgrip calibrate --campaign`` wrote) to estimate
    the run with, as ``railgrip estimate --calibration`` does: refused, saying why, when it was
    fitted with another pipeline file or is another kind of calibration; a record that the
    campaign fitted none leaves the pipeline's values, with a warning. A pipeline with
    ``estimate.calibration = "campaign"`` or ``"dry-run"`` needs it (or carries one).
    """
    cal = None if calibration is None else os.fspath(calibration)
    if cal is not None:
        try:
            with open(cal, encoding="utf-8") as f:
                source = json.load(f).get("calibrated", {}).get("source")
        except (OSError, ValueError, AttributeError):
            source = None  # the native reader names what is wrong with the file
        if source == "none":
            warnings.warn(
                f"estimated with [vehicle]'s α and the radar as logged: {cal} records that the "
                'campaign fitted no calibration (estimate.calibration = "auto")',
                stacklevel=2,
            )
    frame = _frame(*_native.estimate(os.fspath(path), pipeline, cal))
    frame.attrs["name"] = _stem(frame.attrs.get("source", "run"))
    return frame


def _stem(source: str) -> str:
    base = os.path.basename(source)
    for suffix in (".estimates.parquet", ".parquet", ".csv", ".mcap"):
        if base.endswith(suffix):
            return base[: -len(suffix)]
    return os.path.splitext(base)[0] or "run"


class Model:
    """A model file, checked and ready to evaluate: networks (of any depth, 2–4 inputs,
    residual grey-box models) and Polach models with their temperature and speed laws.

    Evaluation goes through railgrip's lean model crate: networks give the same bits as the
    Rust evaluator and the exported C header, Polach models the Rust evaluator's values (the C
    header agrees within 1e-12).
    """

    __slots__ = ("_native", "_file")

    def __init__(self, native: Any) -> None:
        self._native = native
        self._file = json.loads(native.json)

    @classmethod
    def load(cls, path: PathLike) -> "Model":
        """Reads and checks a model file (``mlp.json``, ``*.polach.json``, …)."""
        return cls(_native.Model.load(os.fspath(path)))

    def mu(
        self,
        dv: Any,
        ddv: Any,
        v: Any = None,
        t: Any = None,
    ) -> Union[float, np.ndarray]:
        """μ at slip ``dv`` (m/s), slip rate ``ddv`` (m/s²), speed ``v`` (m/s) and ambient
        temperature ``t`` (°C). The inputs broadcast against each other like numpy's; a scalar
        result for scalar inputs. ``v`` or ``t`` None (or NaN) means the file's reference value;
        inputs outside the domain follow the file's rule (``outside_domain``: networks clamp,
        Polach models follow the law). Non-finite ``dv`` or ``ddv`` give NaN.
        """
        given = [dv, ddv] + [x for x in (v, t) if x is not None]
        arrays = np.broadcast_arrays(*[np.asarray(x, dtype=np.float64) for x in given])
        shape = arrays[0].shape
        flat = [np.ascontiguousarray(a).reshape(-1) for a in arrays]
        empty = np.empty(0, dtype=np.float64)
        it = iter(flat[2:])
        v_flat = next(it) if v is not None else empty
        t_flat = next(it) if t is not None else empty
        out = self._native.mu(flat[0], flat[1], v_flat, t_flat).reshape(shape)
        return float(out) if shape == () else out

    @property
    def kind(self) -> str:
        """``mlp`` (a network, residual models included) or ``polach``."""
        return self._file["kind"]

    @property
    def inputs(self) -> List[str]:
        """The inputs by their estimates-table names, in order: ``dv_mps``, ``ddv_mps2``
        [, ``v_mps``][, ``ambient_temperature_c``]."""
        return [i["name"] for i in self._file["inputs"]]

    @property
    def units(self) -> Dict[str, str]:
        """Each input's unit."""
        return {i["name"]: i["unit"] for i in self._file["inputs"]}

    @property
    def domain(self) -> Dict[str, Tuple[float, float]]:
        """Each input's validity domain (min, max): the range seen in training."""
        return {i["name"]: (i["domain_min"], i["domain_max"]) for i in self._file["inputs"]}

    @property
    def support(self) -> Optional[Dict[str, Any]]:
        """Where the training data lie (networks with a support grid; else None): ``cells``
        per input, ``edges`` per input (cell boundaries in the input's unit), ``counts`` (the
        samples per cell, shaped ``cells``), ``supported`` (counts ≥ ``min_samples``),
        ``min_samples`` and ``fallback``."""
        spec = self._file.get("support")
        if spec is None:
            return None
        cells = tuple(spec["cells"])
        counts = np.asarray(spec["counts"], dtype=np.int64).reshape(cells)
        edges = {
            i["name"]: np.linspace(i["norm_min"], i["norm_max"], n + 1)
            for i, n in zip(self._file["inputs"], cells)
        }
        return {
            "cells": cells,
            "edges": edges,
            "counts": counts,
            "supported": counts >= spec["min_samples"],
            "min_samples": spec["min_samples"],
            "fallback": spec["fallback"],
        }

    @property
    def provenance(self) -> Dict[str, Any]:
        """The file's provenance: input files with their SHA-256, pipeline, seed, version,
        generation."""
        return self._file["provenance"]

    @property
    def metrics(self) -> Dict[str, Any]:
        """The file's metrics (training and validation errors)."""
        return self._file["metrics"]

    @property
    def json(self) -> str:
        """The model file as JSON text."""
        return self._native.json

    @property
    def name(self) -> str:
        """The path it was loaded from, or its name among trained models."""
        return self._native.name

    def save(self, path: PathLike) -> None:
        """Writes the model file (JSON) to ``path``."""
        with open(os.fspath(path), "w", encoding="utf-8") as f:
            f.write(self._native.json)

    def export_fmu(self, path: PathLike, sources_only: bool = False) -> Dict[str, Any]:
        """Writes the model as an FMI 2.0 FMU (Model Exchange and Co-Simulation) at ``path``,
        as ``railgrip export --fmu`` does: the binary for this host compiled with the system C
        compiler (``$CC``, else ``cc``) and the sources, or the sources only. Returns what was
        written: ``path``, ``model_identifier`` (the file's stem), ``guid``, ``platform`` and
        ``variables`` (name, value reference, unit, start, description). docs/fmu.md."""
        return json.loads(self._native.export_fmu(os.fspath(path), sources_only))

    def __repr__(self) -> str:
        return repr(self._native)


class Models(Dict[str, Model]):
    """The models :func:`train` trained, by name (``mlp``, ``polach`` and the model choice's
    other candidates), with the campaign's facts as attributes."""

    chosen_name: str
    condition: str
    runs: int
    samples: int
    notes: List[str]
    skipped: List[Any]
    choice: Dict[str, Any]

    @property
    def chosen(self) -> Model:
        """The model the choice by held-out runs picked (``choice["reason"]`` says why)."""
        return self[self.chosen_name]


TableOrPath = Union[PathLike, pd.DataFrame]


def _train_item(item: TableOrPath, k: int) -> Any:
    if isinstance(item, pd.DataFrame):
        name = str(item.attrs.get("name", f"table{k + 1}"))
        missing = [
            c
            for c in ("time_s", "axle", "v_mps", "dv_mps", "ddv_mps2", "mu", "valid")
            if c not in item.columns
        ]
        if missing:
            raise RailgripError(
                f"{name}: no column(s) {', '.join(missing)}. "
                "Hint: give the table railgrip.estimate returns"
            )
        columns = {
            c: np.ascontiguousarray(item[c].to_numpy(dtype=np.float64))
            for c in ("time_s", "axle", "v_mps", "dv_mps", "ddv_mps2", "mu", "valid")
        }
        if "metadata" not in item.attrs:
            raise RailgripError(
                f"{name}: the table has no attrs['metadata'] (the run's rail condition and "
                "ambient temperature the fits use; operations such as pd.concat may drop attrs). "
                "Hint: give tables from railgrip.estimate, or set table.attrs['metadata'] = "
                "{'condition': 'soap', 'ambient_temperature_c': '20'}"
            )
        metadata = {str(k): str(v) for k, v in dict(item.attrs["metadata"]).items()}
        return (name, metadata, columns)
    if isinstance(item, (str, os.PathLike)):
        return os.fspath(item)
    raise TypeError(
        f"train: item {k + 1} is a {type(item).__name__}; give paths (logs, estimates tables, "
        "campaign folders, archives) or DataFrames from railgrip.estimate"
    )


def train(
    inputs: Union[TableOrPath, Iterable[TableOrPath]],
    pipeline: Optional[Pipeline] = None,
) -> Models:
    """Trains the campaign's models as ``railgrip train`` does, on any mix of run logs,
    estimates tables (``*.estimates.parquet``), campaign folders, archives and DataFrames from
    :func:`estimate` (their ``attrs["metadata"]`` carries the rail condition and ambient
    temperature the fits use). Returns the models by name; ``.chosen`` is the campaign's model.
    """
    if isinstance(inputs, (str, os.PathLike, pd.DataFrame)):
        inputs = [inputs]
    items = [_train_item(x, k) for k, x in enumerate(inputs)]
    if not items:
        raise ValueError("train: give at least one input")
    native, info = _native.train(items, pipeline)
    models = Models((name, Model(m)) for name, m in native.items())
    facts = json.loads(info)
    models.chosen_name = facts["chosen"]
    models.condition = facts["condition"]
    models.runs = facts["runs"]
    models.samples = facts["samples"]
    models.notes = facts["notes"]
    models.skipped = facts["skipped"]
    models.choice = facts["choice"]
    return models


@dataclass
class Campaign:
    """What :func:`run` did (the files are in the output folder, as ``railgrip run`` writes
    them)."""

    archive: str
    records: List[Dict[str, Any]]
    failed: int
    reused: int
    condition: Optional[str]
    models: List[str]
    model_error: Optional[str]
    chosen: Optional[Dict[str, str]]
    notes: List[str]
    report: Optional[str]
    stages: List[Tuple[str, float]]
    skipped: List[Dict[str, str]] = field(default_factory=list)
    #: The model choice: every candidate's held-out scores and the chosen one (as
    #: ``models/mlp.choice.json``); None when no models were trained.
    choice: Optional[Dict[str, Any]] = None

    @property
    def runs(self) -> pd.DataFrame:
        """One row per run: name, status, error, speed, temperature, condition, peak μ …"""
        return pd.DataFrame(self.records)


def run(
    archive: Union[PathLike, str],
    out: Union[PathLike, str],
    pipeline: Optional[Pipeline] = None,
    jobs: Optional[int] = None,
    force: bool = False,
    mcap: bool = False,
) -> Campaign:
    """Runs a campaign (a folder of logs or an archive of one) as ``railgrip run`` does, into
    ``out`` — the same files, the same bytes. Both may be local paths, ``file://PATH`` or
    ``s3://BUCKET/PREFIX`` (credentials and endpoint from the ``AWS_*`` environment variables): estimates per run (reused when unchanged, unless
    ``force``), the models, ``campaign.json`` and the report. ``jobs``: runs estimated in
    parallel (None: one per core). A run that fails is a record, not an exception.
    """
    facts = json.loads(
        _native.run(os.fspath(archive), os.fspath(out), pipeline, jobs, force, mcap)
    )
    facts["stages"] = [tuple(s) for s in facts["stages"]]
    return Campaign(**facts)
