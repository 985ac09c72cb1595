"""Type stubs of railgrip's native module (crates/railgrip-py/src/lib.rs). Use the package
``railgrip``; this module is its implementation."""

import os
from typing import Dict, List, Optional, Tuple, Union

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

Columns = Dict[str, npt.NDArray[np.generic]]
TrainItem = Union[PathLike, Tuple[str, Dict[str, str], Dict[str, npt.NDArray[np.float64]]]]

def read_log(path: str, pipeline: Optional[Pipeline] = None) -> Tuple[Columns, str]: ...
def estimate(path: str, pipeline: Optional[Pipeline] = None) -> Tuple[Columns, str]: ...
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
def campaign_runs(archive: str, out: Optional[str] = None) -> List[Tuple[str, str]]: ...
