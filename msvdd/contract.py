"""The window batch every detector consumes and the detector contract every method implements.

Windows follow the paper (Experimental Setting): 2 s of binaural audio decimated to 4410 Hz
(8820 x 2) and IMU z-axis velocity at 200 Hz (400). Detectors score windows, higher = more anomalous,
with `threshold_` fixed at fit time from nominal data only (`Detector`: the one threshold rule).
"""

from __future__ import annotations

import abc
import contextlib
import os
from collections.abc import Iterator
from dataclasses import dataclass
from typing import ClassVar, Self

import numpy as np

AUDIO_RATE = 4410.0
"""Sample rate of window audio, Hz (44.1 kHz decimated by 10)."""
IMU_RATE = 200.0
"""Sample rate of window IMU, Hz."""
WINDOW_S = 2.0
"""Window length, s."""
AUDIO_LEN = int(AUDIO_RATE * WINDOW_S)
IMU_LEN = int(IMU_RATE * WINDOW_S)


class WindowError(ValueError):
    """A window batch has the wrong shape, rate or values; the message says which."""


class ModelFormatError(ValueError):
    """A model file or folder is not of the expected model, is of another format version, or has a field
    missing or malformed: an M-SVDD model file (`msvdd.model.MSVDD.load`) or a benchmark method's model
    folder or file (`benchmarks.methods`). The message names the file and, where one is at fault, the
    field."""


@contextlib.contextmanager
def model_fields(source: object) -> Iterator[None]:
    """Around rebuilding a model from a read file's fields: what that raises for a missing or malformed field
    becomes a ModelFormatError naming `source` (the file) and the field."""
    try:
        yield
    except ModelFormatError as err:  # the model's own finding, which does not know the file
        raise ModelFormatError(f"{source}: {err}") from err
    except KeyError as err:
        raise ModelFormatError(f"{source}: field {err} is missing") from err
    except (AttributeError, TypeError, ValueError) as err:
        raise ModelFormatError(f"{source}: a field is malformed ({err})") from err


@dataclass(frozen=True)
class Windows:
    """A batch of aligned audio/IMU windows."""

    audio: np.ndarray
    """(N, 8820, 2) float32 binaural audio at 4410 Hz."""
    imu: np.ndarray
    """(N, 400) float32 IMU z-axis velocity at 200 Hz."""
    imu6: np.ndarray | None = None
    """Optional (N, 400, 6) float32 accelerometer xyz and gyro xyz at 200 Hz."""
    odometry: np.ndarray | None = None
    """Optional (N, 400, W) float32 wheel encoder positions at 200 Hz, rad, each relative to the window's
    first sample (the wheel odometry modality; W wheels)."""
    audio_rate: float = AUDIO_RATE
    """Audio sample rate, Hz; must be 4410."""
    imu_rate: float = IMU_RATE
    """IMU sample rate, Hz; must be 200."""

    def __post_init__(self) -> None:
        if self.audio_rate != AUDIO_RATE:
            raise WindowError(f"audio_rate {self.audio_rate} Hz; windows need {AUDIO_RATE} Hz")
        if self.imu_rate != IMU_RATE:
            raise WindowError(f"imu_rate {self.imu_rate} Hz; windows need {IMU_RATE} Hz")
        a, i = np.asarray(self.audio), np.asarray(self.imu)
        if a.ndim != 3 or a.shape[1:] != (AUDIO_LEN, 2):
            raise WindowError(f"audio shape {a.shape}; expected (N, {AUDIO_LEN}, 2)")
        if i.ndim != 2 or i.shape[1] != IMU_LEN:
            raise WindowError(f"imu shape {i.shape}; expected (N, {IMU_LEN})")
        if a.shape[0] != i.shape[0]:
            raise WindowError(f"audio has {a.shape[0]} windows but imu has {i.shape[0]}")
        if self.imu6 is not None and np.asarray(self.imu6).shape != (i.shape[0], IMU_LEN, 6):
            raise WindowError(
                f"imu6 shape {np.asarray(self.imu6).shape}; expected ({i.shape[0]}, {IMU_LEN}, 6)"
            )
        if self.odometry is not None:
            shape = np.asarray(self.odometry).shape
            if len(shape) != 3 or shape[:2] != (i.shape[0], IMU_LEN):
                raise WindowError(f"odometry shape {shape}; expected ({i.shape[0]}, {IMU_LEN}, W)")
        for name, arr in (("audio", a), ("imu", i), ("imu6", self.imu6), ("odometry", self.odometry)):
            if arr is not None and not np.all(np.isfinite(arr)):
                raise WindowError(f"{name} holds NaN or inf")

    def __len__(self) -> int:
        return int(self.audio.shape[0])

    def subset(self, index: np.ndarray | slice) -> Windows:
        """The windows at `index` (a slice, integer or boolean array)."""
        return Windows(
            audio=self.audio[index],
            imu=self.imu[index],
            imu6=None if self.imu6 is None else self.imu6[index],
            odometry=None if self.odometry is None else self.odometry[index],
        )


THRESHOLD_QUANTILE = 0.95
"""The decision threshold is this quantile of a fitted detector's scores on nominal windows."""
MIN_HELD_OUT = 20
"""Fewest held-out nominal windows (`val`) from which the threshold is taken; with fewer, the training
windows' scores are used."""
THRESHOLD_SOURCES: tuple[str, ...] = ("val", "train")
"""Where a threshold came from: held-out nominal windows, or the windows the detector was fit on."""


class NotFittedError(RuntimeError):
    """A detector is used before `fit` (or `load`)."""


def check_windows(batch: object, what: str, minimum: int = 1) -> Windows:
    """Return `batch` if it is a `Windows` with at least `minimum` windows; else a `WindowError`."""
    if not isinstance(batch, Windows):
        raise WindowError(f"{what} must be a msvdd.contract.Windows batch, got {type(batch).__name__}")
    if len(batch) < minimum:
        raise WindowError(f"{what} has {len(batch)} windows; at least {minimum} needed")
    return batch


class Detector(abc.ABC):
    """What every method (M-SVDD, its ablations, every baseline) implements.

    Subclasses implement `_fit`, `_score`, `save` and `load`. `fit` fits, then fixes `threshold_` by the one
    threshold rule: the `quantile` (0.95) of the scores of the held-out nominal windows `val` when there
    are at least `MIN_HELD_OUT` of them, else of the training windows (`threshold_source_` says which).
    Scores of held-out windows are what test nominal windows look like to a detector; the scores of the
    windows it was fit on are lower for a detector that fits them closely, and a threshold from them
    fires on nominal test windows far more often than 5 % of the time. No test window is ever used.
    Bad input raises `WindowError` (a `ValueError`); use before fitting raises `NotFittedError`.
    """

    min_train: ClassVar[int] = 2
    """Fewest training windows `fit` accepts."""
    quantile: float = THRESHOLD_QUANTILE
    """Threshold quantile of nominal scores (M-SVDD reads it from its config)."""

    threshold_: float = float("nan")
    """Decision threshold, fixed by `fit` (or read by `load`); nan before."""
    threshold_source_: str = "train"
    """`val` or `train`: the windows whose scores gave `threshold_` (`THRESHOLD_SOURCES`)."""
    _fitted: bool = False

    @abc.abstractmethod
    def _fit(self, train: Windows, val: Windows | None) -> None:
        """Fit the model on nominal training windows (`val`, nominal too, may select a model)."""

    @abc.abstractmethod
    def _score(self, batch: Windows) -> np.ndarray:
        """(N,) scores of a fitted model, higher = more anomalous."""

    @abc.abstractmethod
    def save(self, path: str | os.PathLike[str]) -> None:
        """Write everything needed to score again, threshold included, into one file."""

    @classmethod
    @abc.abstractmethod
    def load(cls, path: str | os.PathLike[str]) -> Self:
        """Read a file written by `save`."""

    def fit(self, train: Windows, val: Windows | None = None) -> Self:
        """Fit on nominal `train` windows (`val`: nominal, for model selection), then set the threshold."""
        check_windows(train, "train", self.min_train)
        if val is not None:
            check_windows(val, "val")
        self._fit(train, val)
        self._fitted = True
        held_out = val is not None and len(val) >= MIN_HELD_OUT
        reference = val if held_out and val is not None else train
        self.threshold_ = float(np.quantile(self.score(reference), self.quantile))
        self.threshold_source_ = "val" if held_out else "train"
        return self

    def score(self, batch: Windows) -> np.ndarray:
        """(N,) float64 anomaly scores, higher = more anomalous."""
        if not self._fitted:
            raise NotFittedError(f"{type(self).__name__} is not fitted; call fit(train) or load(path) first")
        check_windows(batch, "batch")
        scores = np.asarray(self._score(batch), dtype=np.float64)
        if scores.shape != (len(batch),):
            raise RuntimeError(f"{type(self).__name__} produced scores of shape {scores.shape}")
        return scores

    def predict(self, batch: Windows) -> np.ndarray:
        """(N,) bool: score > threshold_."""
        return self.score(batch) > self.threshold_

    def _set_threshold(self, threshold: float, source: str) -> None:
        """Restore a saved threshold (for `load`) and mark the detector fitted."""
        if source not in THRESHOLD_SOURCES:
            raise WindowError(f"threshold source {source!r}; allowed: {', '.join(THRESHOLD_SOURCES)}")
        self.threshold_ = float(threshold)
        self.threshold_source_ = source
        self._fitted = True
