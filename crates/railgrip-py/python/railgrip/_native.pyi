"""Type stubs of railgrip's native module (crates/railgrip-py/src/lib.rs). Use the package
``railgrip``; this module is its implementation."""

import os
from typing import Any, Dict, List, Optional, Tuple, Union

PathLike = Union[str, "os.PathLike[str]"]

import numpy as np
import numpy.typing as npt

__version__: str

class RailgripError(Exception):
    """An error railgrip reported: the message names the file, line or channel and says what
    to do."""

class Pipeline:
    """A checked pipeline file (TOML): channel mapping, conditioning, estimation, training."""

    @staticmethod
    def load(path: PathLike) -> "Pipeline":
        """Reads and checks a pipeline file; RailgripError names the line and key."""
    @staticmethod
    def default() -> "Pipeline":
        """The embedded UIC-Z1 pipeline (the command's default)."""
    @staticmethod
    def from_toml(text: str, source: str) -> "Pipeline":
        """A pipeline from its TOML text; ``source`` names it in errors and provenance."""
    @property
    def source(self) -> str: ...
    @property
    def text(self) -> str: ...
    @property
    def calibration_source(self) -> str:
        """``estimate.calibration``: "auto" (the default), "pipeline", "campaign" or "dry-run"."""
    @property
    def calibration(self) -> Optional[str]:
        """The campaign calibration this pipeline carries (JSON), if any."""

class Model:
    @staticmethod
    def load(path: PathLike) -> "Model": ...
    def mu(
        self,
        dv: npt.NDArray[np.float64],
        ddv: npt.NDArray[np.float64],
        v: npt.NDArray[np.float64],
        t: npt.NDArray[np.float64],
    ) -> npt.NDArray[np.float64]: ...
    @property
    def json(self) -> str: ...
    @property
    def name(self) -> str: ...
    def export_fmu(self, path: str, sources_only: bool = False) -> str: ...

Columns = Dict[str, npt.NDArray[np.generic]]
TrainItem = Union[PathLike, Tuple[str, Dict[str, str], Dict[str, npt.NDArray[np.float64]]]]

def read_log(path: str, pipeline: Optional[Pipeline] = None) -> Tuple[Columns, str]: ...
def estimate(
    path: str, pipeline: Optional[Pipeline] = None, calibration: Optional[str] = None
) -> Tuple[Columns, str]: ...
def train(
    items: List[TrainItem], pipeline: Optional[Pipeline] = None
) -> Tuple[Dict[str, Model], str]: ...
def run(
    archive: str,
    out: str,
    pipeline: Optional[Pipeline] = None,
    jobs: Optional[int] = None,
    force: bool = False,
    mcap: bool = False,
    stage: str = "all",
    shard: Optional[Tuple[int, int]] = None,
) -> str: ...
def calibrate_campaign(
    archive: str, out: str, pipeline: Pipeline, jobs: Optional[int] = None
) -> Pipeline:
    """Fits the campaign's calibration (the pipeline's estimate.calibration), writes
    calibration.json into ``out`` and returns the pipeline carrying it."""

def campaign_runs(
    archive: str, out: Optional[str] = None
) -> List[Tuple[str, str, Optional[str]]]: ...

# A run table's parts: (run, source, log SHA-256, metadata pairs, axle uint8, time_s, v_mps,
# dv_mps, ddv_mps2, mu float64) — the valid samples, axle by axle in time order.
TableParts = Tuple[str, str, str, Dict[str, str], Any, Any, Any, Any, Any, Any]

def estimate_run(
    archive: str,
    run: str,
    log: Optional[str],
    out: str,
    pipeline: Optional[Pipeline] = None,
    force: bool = False,
) -> Tuple[str, Optional[TableParts]]: ...
def failed_record(run: str, source: str, error: str) -> str: ...
class RunSet:
    def __init__(self) -> None: ...
    def add(
        self,
        record: str,
        table: Optional[TableParts] = None,
        reused: bool = False,
        seconds: float = 0.0,
    ) -> None: ...
    def __len__(self) -> int: ...

def run_models(
    archive: str,
    out: str,
    runs: RunSet,
    pipeline: Optional[Pipeline] = None,
    jobs: Optional[int] = None,
    mcap: bool = False,
) -> str: ...
