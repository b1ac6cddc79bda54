"""The window batch every detector consumes and the detector contract every method implements.

Windows follow the paper (Experimental Setting): 2 s of binaural audio decimated to 4410 Hz
(8820 x 2) and IMU z-axis velocity at 200 Hz (400). Detectors score windows, higher = more anomalous,
with `threshold_` fixed at fit time from training data only.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Protocol, Self, runtime_checkable

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


@dataclass(frozen=True)
class Windows:
    """A batch of aligned audio/IMU windows."""

    audio: np.ndarray
    """(N, 8820, 2) float32 binaural audio at 4410 Hz."""
    imu: np.ndarray
    """(N, 400) float32 IMU z-axis velocity at 200 Hz."""
    imu6: np.ndarray | None = None
    """Optional (N, 400, 6) float32 accelerometer xyz and gyro xyz at 200 Hz."""
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
        for name, arr in (("audio", a), ("imu", i), ("imu6", self.imu6)):
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
        )


@runtime_checkable
class Detector(Protocol):
    """What every method (M-SVDD, its ablations, every baseline) implements."""

    threshold_: float
    """Decision threshold, fixed by `fit` from training scores only (95th percentile by default)."""

    def fit(self, train: Windows, val: Windows | None = None) -> Self:
        """Fit on nominal windows; `val` (nominal too) may be used for model selection."""
        ...

    def score(self, batch: Windows) -> np.ndarray:
        """(N,) float64 anomaly scores, higher = more anomalous."""
        ...

    def predict(self, batch: Windows) -> np.ndarray:
        """(N,) bool: score > threshold_."""
        ...

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write everything needed to score again into one file."""
        ...

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Self:
        """Read a file written by `save`."""
        ...
