"""visuotact: camera-based soft tactile sensors from numpy (type stubs)."""

from os import PathLike
from typing import Any, Callable, Iterator, Sequence

import numpy as np
import numpy.typing as npt

__version__: str

Frame = npt.NDArray[np.uint8] | str | PathLike[str]

class VisuotactError(Exception):
    """An error from visuotact; the message names the file, frame or column."""

class Features:
    """One frame's features: the feature row and per-marker arrays."""
    @property
    def values(self) -> npt.NDArray[np.float64]: ...
    @property
    def columns(self) -> list[str]: ...
    @property
    def dx(self) -> npt.NDArray[np.float64]: ...
    @property
    def dy(self) -> npt.NDArray[np.float64]: ...
    @property
    def darea(self) -> npt.NDArray[np.float64]: ...
    @property
    def status(self) -> list[str]: ...
    @property
    def found(self) -> int: ...

class Sensor:
    """A sensor calibration: markers at rest, how to find them, their layout."""
    @staticmethod
    def calibrate(
        frames: Sequence[Frame],
        preset: str = "auto",
        layout: str = "auto",
        *,
        channel: str = ...,
        invert: bool = ...,
        threshold: str | float = ...,
        window: int = ...,
        offset: float = ...,
        open: bool = ...,
        close: bool = ...,
        morph_size: int = ...,
        min_area: int = ...,
        max_area: int = ...,
        keep_border: bool = ...,
        connectivity: int = ...,
        centroid: str = ...,
        roi: tuple[int, int, int, int] = ...,
        circle: tuple[float, float, float] = ...,
    ) -> Sensor:
        """Calibrates from contact-free frames; keyword options change the preset's detector."""
    @staticmethod
    def load(path: str | PathLike[str]) -> Sensor: ...
    def save(self, path: str | PathLike[str]) -> None: ...
    def to_json(self) -> str: ...
    @property
    def n_markers(self) -> int: ...
    @property
    def feature_columns(self) -> list[str]: ...
    def extract(self, frame: Frame) -> Features: ...

class Model:
    """A trained model: one network or an ensemble."""
    @staticmethod
    def train(
        features: npt.NDArray[np.float64],
        labels: npt.NDArray[np.float64],
        columns: Sequence[str],
        targets: Sequence[str],
        hidden: Sequence[int] | None = None,
        algorithm: str = "trainbr",
        components: str = "auto",
        field: str = "auto",
        ensemble: int | None = None,
        seed: int = 1,
        max_epochs: int = 1000,
        sensor: Sensor | None = None,
    ) -> Model: ...
    @staticmethod
    def load(path: str | PathLike[str]) -> Model: ...
    def save(self, path: str | PathLike[str]) -> None: ...
    def to_json(self) -> str: ...
    @property
    def columns(self) -> list[str]: ...
    @property
    def targets(self) -> list[str]: ...
    @property
    def selection(self) -> list[dict[str, object]]: ...
    def predict(
        self,
        features: Features | npt.NDArray[np.float64],
        columns: Sequence[str] | None = None,
    ) -> dict[str, npt.NDArray[np.float64] | npt.NDArray[np.int64]]: ...

class Live(Iterator[dict[str, object]]):
    def __next__(self) -> dict[str, object]: ...

def live(
    source: str | PathLike[str] | Sequence[str | PathLike[str]],
    model: Model | None = None,
    sensor: Sensor | None = None,
    fps: float = 25.0,
    temporal: bool = False,
    slip: str | None = None,
) -> Live: ...
def slip_detect(
    videos: str | PathLike[str] | Sequence[str | PathLike[str]],
    detector: str = "builtin",
    sensor: Sensor | None = None,
    calibration_frames: int = 5,
) -> list[dict[str, object]]: ...
def filtfilt(
    b: npt.NDArray[np.float64], a: npt.NDArray[np.float64], x: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]: ...
def simulate(x_mm: float = 0.0, y_mm: float = 0.0, depth_mm: float = 0.0, seed: int = 1) -> npt.NDArray[np.uint8]: ...
def export_mcap(
    session: str | PathLike[str],
    output: str | PathLike[str],
    namespace: str = "/visuotact",
    frame_id: str = "visuotact",
    sensor: str | PathLike[str] | None = None,
    start_unix_s: float | None = None,
    images: bool = True,
    progress: Callable[[int, int], None] | None = None,
) -> dict[str, Any]: ...
def export_lerobot(
    sessions: Sequence[str | PathLike[str]],
    output: str | PathLike[str],
    fps: int | None = None,
    task: str = "touch the tactile sensor",
    robot_type: str | None = None,
    video: bool = True,
    encoder: str = "libsvtav1",
    progress: Callable[[int, int], None] | None = None,
) -> dict[str, Any]: ...
