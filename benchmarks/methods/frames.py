"""`gaussian-frames` and `mixture-frames`: frame-wise density models of `msvdd`'s inputs, references to beat.

`gaussian-frames` is `msvdd`'s frame-wise Mahalanobis term without the network.

It reads the inputs `msvdd` reads (`msvdd.frontend.InputNormalizer`: the two channels' log-mel spectrograms
and the seven IMU axes, z-scored with training statistics and smoothed like M-SVDD's), cuts them into the
frames of M-SVDD's tokens (a log-mel frame of both channels, 64 values; 8 IMU samples of seven axes, 56
values), fits a Gaussian per modality over every frame of the training windows (mean and Ledoit-Wolf
covariance, `msvdd.residual`), and scores a window by each modality's largest frame distance in units of its
training mean, summed. That is `msvdd`'s reconstruction term with the reconstruction x_hat = 0: the comparison
says what the trained network adds to frame-wise Mahalanobis scoring. No hyper-parameter is tuned.

`mixture-frames` replaces each modality's single Gaussian by a Gaussian mixture (scikit-learn's
`GaussianMixture`, `MIXTURE_COMPONENTS` full-covariance components fitted on a seeded sample of
`MIXTURE_FRAMES` training frames) and scores a window by each modality's largest frame negative
log-likelihood, standardised with its training mean and standard deviation, summed. Nominal driving has
several regimes (standing, turning, straight runs over different floors); one ellipsoid covers them all,
a mixture can follow them. It is the bar a learned representation of the normal has to clear. Its one
hyper-parameter, the number of components, was chosen on the dev dataset (seed 1) among 1, 4, 8, 16, 32.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Self

import numpy as np
import torch

from benchmarks.methods.base import WindowDetector
from msvdd.contract import WindowError, Windows
from msvdd.frontend import InputNormalizer
from msvdd.network import IMU_FRAME
from msvdd.residual import FrameGaussian, cut_frames, fit_frame_gaussian

if TYPE_CHECKING:
    from sklearn.mixture import GaussianMixture

_BATCH = 512
"""Windows per block of the front end (bounds the memory of the log-mel spectrograms)."""
MIXTURE_COMPONENTS = 16
"""Components of each modality's Gaussian mixture (`mixture-frames`; chosen on the dev dataset)."""
MIXTURE_FRAMES = 60_000
"""Training frames per modality the mixture is fitted on (a seeded sample; all when there are fewer)."""
MIXTURE_REG = 1e-3
"""Added to each component's covariance diagonal (the inputs are z-scored: 0.1 % of their variance)."""
MODALITY_NAMES: tuple[str, ...] = ("audio", "imu")
"""The modalities in frame order: log-mel frames, IMU frames."""


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

    def _peaks(self, frames: list[torch.Tensor]) -> np.ndarray:
        """(N, 2) each modality's largest frame distance."""
        return np.stack([g.peak_distance(f).numpy() for g, f in zip(self.gauss, frames, strict=True)], axis=1)

    def _fit(self, train: Windows, val: Windows | None) -> None:
        self.normalizer = InputNormalizer.fit(train, "logmel", "all")
        frames = self._modality_frames(train)
        self.gauss = [fit_frame_gaussian(f.reshape(-1, f.shape[2])) for f in frames]
        self.scale = self._peaks(frames).mean(axis=0)

    def _score(self, batch: Windows) -> np.ndarray:
        return (self._peaks(self._modality_frames(batch)) / self.scale).sum(axis=1)

    def _state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        if self.normalizer is None:
            raise RuntimeError("gaussian-frames has no input statistics")
        arrays = {**self.normalizer.arrays(), "scale": self.scale}
        for name, g in zip(MODALITY_NAMES, self.gauss, strict=True):
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
            for n in MODALITY_NAMES
        ]
        return detector


class MixtureFrameReference(FrameReference):
    """Frame-wise Gaussian mixtures of the normalised log-mel and IMU inputs; the largest frame negative
    log-likelihoods, standardised, summed."""

    kind = "mixture-frames"

    def __init__(self, seed: int = 0, components: int = MIXTURE_COMPONENTS) -> None:
        super().__init__()
        if components < 1:
            raise ValueError(f"components = {components} is invalid; allowed: 1 or more")
        self.seed = seed
        self.components = components
        self.mixtures: list[GaussianMixture] = []
        self.offset = np.zeros(2)

    def _peaks(self, frames: list[torch.Tensor]) -> np.ndarray:
        """(N, 2) each modality's largest frame negative log-likelihood."""
        out = []
        for mixture, f in zip(self.mixtures, frames, strict=True):
            n, t, d = f.shape
            nll = -mixture.score_samples(f.reshape(-1, d).numpy().astype(np.float64))
            out.append(nll.reshape(n, t).max(axis=1))
        return np.stack(out, axis=1)

    def _fit(self, train: Windows, val: Windows | None) -> None:
        from sklearn.mixture import GaussianMixture

        self.normalizer = InputNormalizer.fit(train, "logmel", "all")
        rng = np.random.default_rng(self.seed)
        self.mixtures = []
        frames = self._modality_frames(train)
        for f in frames:
            x = f.reshape(-1, f.shape[2]).numpy().astype(np.float64)
            if len(x) > MIXTURE_FRAMES:
                x = x[np.sort(rng.choice(len(x), MIXTURE_FRAMES, replace=False))]
            if len(x) < self.components:
                raise WindowError(
                    f"mixture-frames needs at least {self.components} training frames per modality; "
                    f"got {len(x)}"
                )
            mixture = GaussianMixture(
                self.components, covariance_type="full", reg_covar=MIXTURE_REG, random_state=self.seed
            )
            self.mixtures.append(mixture.fit(x))
        peaks = self._peaks(frames)
        self.offset = peaks.mean(axis=0)
        self.scale = np.maximum(peaks.std(axis=0), 1e-12)

    def _score(self, batch: Windows) -> np.ndarray:
        return ((self._peaks(self._modality_frames(batch)) - self.offset) / self.scale).sum(axis=1)

    def _state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        if self.normalizer is None:
            raise RuntimeError("mixture-frames has no input statistics")
        arrays = {**self.normalizer.arrays(), "offset": self.offset, "scale": self.scale}
        for name, m in zip(MODALITY_NAMES, self.mixtures, strict=True):
            arrays[f"{name}_weights"], arrays[f"{name}_means"] = m.weights_, m.means_
            arrays[f"{name}_covariances"], arrays[f"{name}_precisions_cholesky"] = (
                m.covariances_,
                m.precisions_cholesky_,
            )
        return {"seed": self.seed, "components": self.components}, arrays

    @classmethod
    def _from_state(cls, header: dict[str, Any], arrays: dict[str, np.ndarray]) -> Self:
        from sklearn.mixture import GaussianMixture

        detector = cls(int(header["seed"]), int(header["components"]))
        detector.normalizer = InputNormalizer.from_arrays(arrays, "logmel", "all")
        detector.offset = np.asarray(arrays["offset"], dtype=np.float64)
        detector.scale = np.asarray(arrays["scale"], dtype=np.float64)
        for name in MODALITY_NAMES:
            # the fitted attributes `GaussianMixture.score_samples` reads, as the fit left them
            mixture = GaussianMixture(detector.components, covariance_type="full")
            for field in ("weights", "means", "covariances", "precisions_cholesky"):
                setattr(mixture, f"{field}_", np.asarray(arrays[f"{name}_{field}"], dtype=np.float64))
            detector.mixtures.append(mixture)
        return detector


def register_methods() -> None:
    """Register `gaussian-frames` and `mixture-frames`."""
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
    register(
        "mixture-frames",
        lambda seed, scale, device: MixtureFrameReference(seed),
        cls=MixtureFrameReference,
        family="reference",
        modality="audio+imu",
        description=f"reference: {MIXTURE_COMPONENTS}-component Gaussian mixture on msvdd's log-mel and IMU "
        "input frames (largest frame negative log-likelihood)",
    )
