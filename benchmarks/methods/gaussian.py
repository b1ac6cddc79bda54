"""The reference detector: a Gaussian model of fixed window statistics, scored by Mahalanobis distance.

Features per window: the mean and standard deviation over frames of each log-mel band of the 4410 Hz
audio (`benchmarks.features.log_mel`), the z-velocity statistics (`imu_features`) and the six-axis IMU
statistics (`imu6_features`). They are standardised with training statistics; the covariance is the
Ledoit-Wolf shrinkage estimate (scikit-learn), well conditioned with few windows; the score is the
squared Mahalanobis distance to the training mean. No hyper-parameter is tuned.

It is deliberately simple: the audit (`benchmarks.audit`) uses it to find what a competent detector
learns from the data, and the benchmark reports it next to M-SVDD (`gaussian-early`), with audio-only and
IMU-only variants.
"""

from __future__ import annotations

from typing import Any, Self

import numpy as np
from sklearn.covariance import LedoitWolf

from benchmarks.features import FeatureConfig, imu6_features, imu_features, log_mel
from benchmarks.methods.base import WindowDetector
from msvdd.contract import WindowError, Windows

MODALITIES: tuple[str, ...] = ("early", "audio", "imu")
"""Which features the model reads: both modalities concatenated, audio only, or IMU only."""
_STD_FLOOR = 1e-8


_FEATURES = FeatureConfig()


def log_mel_statistics(audio: np.ndarray, config: FeatureConfig = _FEATURES) -> np.ndarray:
    """(N, 2 n_mels): mean and standard deviation over frames of each log-mel band."""
    out = []
    for start in range(0, audio.shape[0], config.chunk):
        lm = log_mel(audio[start : start + config.chunk], config).astype(np.float64)
        out.append(np.concatenate([lm.mean(axis=1), lm.std(axis=1)], axis=1))
    return np.concatenate(out, axis=0) if out else np.zeros((0, 2 * config.n_mels))


def reference_features(batch: Windows, modality: str) -> np.ndarray:
    """The reference detector's feature matrix of a window batch for one of `MODALITIES`."""
    parts = []
    if modality in ("early", "audio"):
        parts.append(log_mel_statistics(batch.audio))
    if modality in ("early", "imu"):
        if batch.imu6 is None:
            raise WindowError("imu6 is None: the reference detector reads the six IMU axes (acc, gyro)")
        parts += [imu_features(batch.imu), imu6_features(batch.imu6)]
    return np.concatenate(parts, axis=1)


class GaussianReference(WindowDetector):
    """Standardised window statistics, Ledoit-Wolf covariance, squared Mahalanobis distance."""

    kind = "gaussian-reference"

    def __init__(self, modality: str = "early") -> None:
        super().__init__()
        if modality not in MODALITIES:
            raise ValueError(f"modality {modality!r} is unknown; allowed: {', '.join(MODALITIES)}")
        self.modality = modality
        self.mean = np.zeros(0)
        self.std = np.zeros(0)
        self.precision = np.zeros((0, 0))

    def _features(self, batch: Windows) -> np.ndarray:
        """(N, F) the window features the Gaussian is over."""
        return reference_features(batch, self.modality)

    def _standardised(self, batch: Windows) -> np.ndarray:
        x = self._features(batch)
        if x.shape[1] != self.mean.size:
            raise WindowError(f"the batch gives {x.shape[1]} features; the model was fit on {self.mean.size}")
        return (x - self.mean) / self.std

    def _fit(self, train: Windows, val: Windows | None) -> None:
        x = self._features(train)
        self.mean = x.mean(axis=0)
        self.std = np.maximum(x.std(axis=0), _STD_FLOOR)
        z = (x - self.mean) / self.std
        self.precision = LedoitWolf(assume_centered=True).fit(z).precision_

    def _score(self, batch: Windows) -> np.ndarray:
        z = self._standardised(batch)
        return np.einsum("ij,jk,ik->i", z, self.precision, z)

    def _state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        return {"modality": self.modality}, {"mean": self.mean, "std": self.std, "precision": self.precision}

    @classmethod
    def _from_state(cls, header: dict[str, Any], arrays: dict[str, np.ndarray]) -> Self:
        return cls(str(header["modality"]))._restored(arrays)

    def _restored(self, arrays: dict[str, np.ndarray]) -> Self:
        """This detector with the Gaussian `_state` saved."""
        self.mean, self.std, self.precision = arrays["mean"], arrays["std"], arrays["precision"]
        return self


def register_methods() -> None:
    """Register `gaussian-early`, `gaussian-audio` and `gaussian-imu`."""
    from benchmarks.methods.registry import register

    what = {"early": ("audio+imu", "log-mel + IMU"), "audio": ("audio", "log-mel"), "imu": ("imu", "IMU")}
    for modality, (reads, label) in what.items():
        register(
            f"gaussian-{modality}",
            lambda seed, scale, device, m=modality: GaussianReference(m),  # type: ignore[misc]
            cls=GaussianReference,
            family="reference",
            modality=reads,
            description=f"reference: Ledoit-Wolf Mahalanobis distance on {label} window statistics",
            label=f"Gaussian, {label} statistics",
            config=f"GaussianReference(modality={modality!r})",
        )
