"""`gaussian-frames`: `msvdd`'s frame-wise Mahalanobis term without the network, a reference to beat.

It reads the inputs `msvdd` reads (`msvdd.frontend.InputNormalizer`: the two channels' log-mel spectrograms
and the seven IMU axes, z-scored with training statistics and smoothed like M-SVDD's), cuts them into the
frames of M-SVDD's tokens (a log-mel frame of both channels, 64 values; 8 IMU samples of seven axes, 56
values), fits a Gaussian per modality over every frame of the training windows (mean and Ledoit-Wolf
covariance, `msvdd.residual`), and scores a window by each modality's largest frame distance in units of its
training mean, summed. That is `msvdd`'s reconstruction term with the reconstruction x_hat = 0: the comparison
says what the trained network adds to frame-wise Mahalanobis scoring. No hyper-parameter is tuned.
"""

from __future__ import annotations

from typing import Any, Self

import numpy as np
import torch

from benchmarks.methods.base import WindowDetector
from msvdd.contract import Windows
from msvdd.frontend import InputNormalizer
from msvdd.network import IMU_FRAME
from msvdd.residual import FrameGaussian, cut_frames, fit_frame_gaussian

_BATCH = 512
"""Windows per block of the front end (bounds the memory of the log-mel spectrograms)."""


def _frames(audio: torch.Tensor, imu: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Normalised log-mel (N, 2, T, M) and IMU (N, 400, 7) -> their frames (N, T, 64) and (N, 50, 56)."""
    return cut_frames(audio, 2, 1), cut_frames(imu, 1, IMU_FRAME)


class FrameReference(WindowDetector):
    """Frame-wise Gaussians of the normalised log-mel and IMU inputs; the largest frame distances, summed."""

    kind = "gaussian-frames"

    def __init__(self) -> None:
        super().__init__()
        self.normalizer: InputNormalizer | None = None
        self.gauss: list[FrameGaussian] = []
        self.scale = np.ones(2)

    def _modality_frames(self, batch: Windows) -> list[torch.Tensor]:
        """The batch's frames per modality, front end applied block by block."""
        if self.normalizer is None:
            raise RuntimeError("gaussian-frames has no input statistics")
        blocks = [
            _frames(*self.normalizer.tensors(batch.subset(slice(s, s + _BATCH))))
            for s in range(0, len(batch), _BATCH)
        ]
        return [torch.cat([b[m] for b in blocks]) for m in range(2)]

    def _distances(self, batch: Windows) -> np.ndarray:
        """(N, 2) each modality's largest frame distance."""
        frames = self._modality_frames(batch)
        return np.stack([g.peak_distance(f).numpy() for g, f in zip(self.gauss, frames, strict=True)], axis=1)

    def _fit(self, train: Windows, val: Windows | None) -> None:
        self.normalizer = InputNormalizer.fit(train, "logmel", "all")
        frames = self._modality_frames(train)
        self.gauss = [fit_frame_gaussian(f.reshape(-1, f.shape[2])) for f in frames]
        self.scale = self._distances(train).mean(axis=0)

    def _score(self, batch: Windows) -> np.ndarray:
        return (self._distances(batch) / self.scale).sum(axis=1)

    def _state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        if self.normalizer is None:
            raise RuntimeError("gaussian-frames has no input statistics")
        arrays = {**self.normalizer.arrays(), "scale": self.scale}
        for name, g in zip(("audio", "imu"), self.gauss, strict=True):
            arrays[f"frame_{name}_mean"], arrays[f"frame_{name}_whiten"] = g.mean.numpy(), g.whiten.numpy()
        return {}, arrays

    @classmethod
    def _from_state(cls, header: dict[str, Any], arrays: dict[str, np.ndarray]) -> Self:
        detector = cls()
        detector.normalizer = InputNormalizer.from_arrays(arrays, "logmel", "all")
        detector.scale = np.asarray(arrays["scale"], dtype=np.float64)
        detector.gauss = [
            FrameGaussian(
                mean=torch.from_numpy(arrays[f"frame_{n}_mean"]).double(),
                whiten=torch.from_numpy(arrays[f"frame_{n}_whiten"]).double(),
            )
            for n in ("audio", "imu")
        ]
        return detector


def register_methods() -> None:
    """Register `gaussian-frames`."""
    from benchmarks.methods.registry import register

    register(
        "gaussian-frames",
        lambda seed, scale, device: FrameReference(),
        cls=FrameReference,
        family="reference",
        modality="audio+imu",
        description="reference: frame-wise Ledoit-Wolf Mahalanobis distance on msvdd's log-mel and IMU "
        "input frames (largest over the window)",
    )
