"""Naive sanity baselines: window audio RMS and IMU kurtosis. If these score well, the task is too easy."""

from __future__ import annotations

from typing import Any, Self

import numpy as np

from benchmarks.methods.base import WindowDetector
from msvdd.contract import Windows


def window_rms(audio: np.ndarray) -> np.ndarray:
    """(N,) RMS over both channels of (N, T, C) audio windows."""
    a = np.asarray(audio, dtype=np.float64)
    return np.sqrt(np.mean(a**2, axis=tuple(range(1, a.ndim))))


def window_kurtosis(imu: np.ndarray) -> np.ndarray:
    """(N,) excess (Fisher) kurtosis of each (N, T) IMU window; 0 for a constant window."""
    x = np.asarray(imu, dtype=np.float64)
    dev = x - x.mean(axis=1, keepdims=True)
    var = np.mean(dev**2, axis=1)
    tiny = var <= np.finfo(np.float64).tiny
    return np.where(tiny, 0.0, np.mean(dev**4, axis=1) / np.where(tiny, 1.0, var) ** 2 - 3.0)


class _StatisticDetector(WindowDetector):
    """A detector whose score is a fixed statistic of the window; fitting only sets the threshold."""

    min_train = 2

    def _fit(self, train: Windows, val: Windows | None) -> None:
        return None

    def _state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        return {}, {}

    @classmethod
    def _from_state(cls, header: dict[str, Any], arrays: dict[str, np.ndarray]) -> Self:
        return cls()


class AudioRMS(_StatisticDetector):
    """Score = RMS of the window audio (both channels)."""

    kind = "audio-rms"

    def _score(self, batch: Windows) -> np.ndarray:
        return window_rms(batch.audio)


class IMUKurtosis(_StatisticDetector):
    """Score = excess kurtosis of the IMU z-velocity window (impacts are heavy-tailed)."""

    kind = "imu-kurtosis"

    def _score(self, batch: Windows) -> np.ndarray:
        return window_kurtosis(batch.imu)


def register_methods() -> None:
    """Register `audio-rms` and `imu-kurtosis`."""
    from benchmarks.methods.registry import register

    register(
        "audio-rms",
        lambda seed, scale, device: AudioRMS(),
        cls=AudioRMS,
        family="naive",
        modality="audio",
        description="window audio RMS (sanity baseline)",
        label="audio RMS",
    )
    register(
        "imu-kurtosis",
        lambda seed, scale, device: IMUKurtosis(),
        cls=IMUKurtosis,
        family="naive",
        modality="imu",
        description="excess kurtosis of the IMU window (sanity baseline)",
        label="IMU kurtosis",
    )
