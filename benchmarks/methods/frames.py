"""`frame-density` and `context-net-frames`: densities of the normalised input frames given their neighbours,
without any network of M-SVDD's; the references a learned representation of the normal has to beat.

They read the inputs `msvdd` reads (`msvdd.frontend.InputNormalizer`: the two channels' log-mel spectrograms
and the seven IMU axes, z-scored with training statistics and smoothed like M-SVDD's) and cuts them into the
frames of M-SVDD's tokens (a log-mel frame of both channels, 64 values; 8 IMU samples of seven axes, 56
values). Each modality gets a density of a frame given the frames on either side of it in the window:

- the log-mel frames' is a mixture density network (`msvdd.context_net.ContextNet`, trained on the training
  frames, its epoch chosen on the validation windows' frames);
- the IMU frames' is, in `context-net-frames`, a pair of Gaussian mixtures (`msvdd.context.ContextMixture`:
  p(x_t | c_t) from a mixture of (x_t, c_t) and one of c_t, c_t the principal components of the
  neighbouring frames); in `frame-density`, a mixture density network given the neighbouring IMU frames and
  the log-mel frames around them (`imu_net=True`).

A window's score is each modality's largest conditional frame distance in units of its training mean, summed
(`modality_scores` gives the two terms; `msvdd-bench terms` reads them). `frame-density` is exactly the
frame-density term of `frame-density-msvdd` (same inputs, same densities, same seeds) without the M-SVDD
network's distance: the pair shows what that network adds. On the dev dataset the learned density was ahead
of the fixed mixtures on the log-mel frames and behind them on the IMU frames without the audio context,
hence `context-net-frames`' split (docs/detectors.md).
"""

from __future__ import annotations

from typing import Any, Self

import numpy as np
import torch

from benchmarks.methods.base import WindowDetector
from msvdd.context import CONTEXT_DIM, CONTEXT_NEIGHBOURS, ContextMixture, fit_context_mixture
from msvdd.context import STATE_FIELDS as CONTEXT_STATE_FIELDS
from msvdd.context_net import ContextNet, fit_context_net
from msvdd.contract import NotFittedError, WindowError, Windows, check_windows
from msvdd.frontend import InputNormalizer
from msvdd.network import IMU_FRAME
from msvdd.residual import MIXTURE_COMPONENTS, cut_frames

_BATCH = 512
"""Windows per block of the front end (bounds the memory of the log-mel spectrograms)."""
MODALITY_NAMES: tuple[str, ...] = ("audio", "imu")
"""The modalities in frame order: log-mel frames, IMU frames."""
FrameDensity = ContextMixture | ContextNet
"""A modality's frame density given its neighbours."""
_NET_PREFIX = "audio_net_"
"""Prefix of the saved arrays of the audio `ContextNet`."""
_IMU_NET_PREFIX = "imu_net_"
"""Prefix of the saved arrays of the IMU `ContextNet` (`imu_net=True`)."""


def _frames(audio: torch.Tensor, imu: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Normalised log-mel (N, 2, T, M) and IMU (N, 400, 7) -> their frames (N, T, 64) and (N, 50, 56)."""
    return cut_frames(audio, 2, 1), cut_frames(imu, 1, IMU_FRAME)


class ContextNetFrames(WindowDetector):
    """Densities of the normalised log-mel and IMU input frames given their neighbours (a `ContextNet` for
    the log-mel frames; for the IMU frames a `ContextMixture`, or with `imu_net` a `ContextNet` given the
    log-mel frames too); the largest conditional frame distances, each over its training mean, summed."""

    kind = "context-net-frames"

    def __init__(self, seed: int = 0, components: int = MIXTURE_COMPONENTS, imu_net: bool = False) -> None:
        super().__init__()
        if components < 1:
            raise ValueError(f"components = {components} is invalid; allowed: 1 or more")
        self.seed = seed
        self.components = components
        self.imu_net = imu_net
        self.normalizer: InputNormalizer | None = None
        self.densities: list[FrameDensity] = []
        self.scale = np.ones(2)

    def _modality_frames(self, batch: Windows) -> list[torch.Tensor]:
        """The batch's frames per modality, front end applied block by block."""
        if self.normalizer is None:
            raise RuntimeError(f"{self.kind} has no input statistics")
        blocks = [
            _frames(*self.normalizer.tensors(batch.subset(slice(s, s + _BATCH))))
            for s in range(0, len(batch), _BATCH)
        ]
        return [torch.cat([b[m] for b in blocks]) for m in range(2)]

    def _peaks(self, frames: list[torch.Tensor]) -> np.ndarray:
        """(N, 2) each modality's largest frame distance under its density."""
        peaks = [
            m.peak_distance(f, frames[0] if m.cross_p > 0 else None)
            if isinstance(m, ContextNet)
            else m.peak_distance(f)
            for m, f in zip(self.densities, frames, strict=True)
        ]
        return np.stack([p.numpy() for p in peaks], axis=1)

    def _fit(self, train: Windows, val: Windows | None) -> None:
        self.normalizer = InputNormalizer.fit(train, "logmel", "all")
        audio, imu = self._modality_frames(train)
        if imu.shape[0] * imu.shape[1] < self.components:
            raise WindowError(
                f"{self.kind} needs at least {self.components} training frames per modality; "
                f"got {imu.shape[0] * imu.shape[1]}"
            )
        val_frames = self._modality_frames(val) if val is not None and len(val) else None
        val_audio = None if val_frames is None else val_frames[0]
        imu_density: FrameDensity
        if self.imu_net:
            val_imu = None if val_frames is None else val_frames[1]
            imu_density = fit_context_net(imu, val_imu, self.seed, cross=(audio, val_audio))
        else:
            imu_density = fit_context_mixture(imu, self.components, self.seed)
        self.densities = [fit_context_net(audio, val_audio, self.seed), imu_density]
        self.scale = self._peaks([audio, imu]).mean(axis=0)

    def modality_scores(self, batch: Windows) -> np.ndarray:
        """(N, 2) float64: each modality's term of the score, in `MODALITY_NAMES` order; a row's sum is the
        window's `score` (the fusion ablation of this reference costs no training: `msvdd-bench terms`)."""
        if not self._fitted:
            raise NotFittedError(f"{type(self).__name__} is not fitted; call fit(train) or load(path) first")
        check_windows(batch, "batch")
        return self._terms(batch)

    def _terms(self, batch: Windows) -> np.ndarray:
        return np.asarray(self._peaks(self._modality_frames(batch)) / self.scale, dtype=np.float64)

    def _score(self, batch: Windows) -> np.ndarray:
        return self._terms(batch).sum(axis=1)

    def _state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        if self.normalizer is None:
            raise RuntimeError(f"{self.kind} has no input statistics")
        arrays = {**self.normalizer.arrays(), "scale": self.scale}
        for field, value in self.densities[0].state().items():
            arrays[f"{_NET_PREFIX}{field}"] = value.numpy()
        imu_prefix = _IMU_NET_PREFIX if self.imu_net else "imu_"
        for field, value in self.densities[1].state().items():
            arrays[f"{imu_prefix}{field}"] = value.numpy()
        return {"seed": self.seed, "components": self.components, "imu_net": self.imu_net}, arrays

    @classmethod
    def _from_state(cls, header: dict[str, Any], arrays: dict[str, np.ndarray]) -> Self:
        detector = cls(int(header["seed"]), int(header["components"]), bool(header.get("imu_net", False)))
        detector.normalizer = InputNormalizer.from_arrays(arrays, "logmel", "all")
        detector.scale = np.asarray(arrays["scale"], dtype=np.float64)
        net = {
            k.removeprefix(_NET_PREFIX): torch.from_numpy(np.asarray(v))
            for k, v in arrays.items()
            if k.startswith(_NET_PREFIX)
        }
        cpu = torch.device("cpu")
        imu_density: FrameDensity
        if detector.imu_net:
            imu_state = {
                k.removeprefix(_IMU_NET_PREFIX): torch.from_numpy(np.asarray(v))
                for k, v in arrays.items()
                if k.startswith(_IMU_NET_PREFIX)
            }
            imu_density = ContextNet.from_state(imu_state, cpu)
        else:
            imu = {k: torch.from_numpy(np.asarray(arrays[f"imu_{k}"])) for k in CONTEXT_STATE_FIELDS}
            imu_density = ContextMixture.from_state(imu, cpu)
        detector.densities = [ContextNet.from_state(net, cpu), imu_density]
        return detector


def register_methods() -> None:
    """Register `frame-density` and `context-net-frames`."""
    from benchmarks.methods.registry import register

    register(
        "frame-density",
        lambda seed, scale, device: ContextNetFrames(seed, imu_net=True),
        cls=ContextNetFrames,
        family="reference",
        modality="audio+imu",
        description="reference: frame-density-msvdd's frame term without its network: densities of the "
        "normalised log-mel and IMU input frames given their neighbours (a mixture density network per "
        "modality, the IMU's given the log-mel frames too; largest conditional frame distance)",
        label="frame densities, no network (`frame-density`)",
        config=f"ContextNetFrames(imu_net=True), {CONTEXT_NEIGHBOURS} neighbours on each side",
    )
    register(
        "context-net-frames",
        lambda seed, scale, device: ContextNetFrames(seed),
        cls=ContextNetFrames,
        family="reference",
        modality="audio+imu",
        description="reference: densities of the normalised log-mel and IMU input frames given their "
        "neighbours (a mixture density network for the log-mel frames, Gaussian mixtures for the IMU's; "
        "largest conditional frame distance)",
        label="frame densities given their neighbours (`context-net-frames`)",
        config=f"ContextNetFrames(components={MIXTURE_COMPONENTS}), {CONTEXT_NEIGHBOURS} neighbours on each "
        f"side, IMU context on {CONTEXT_DIM} principal axes",
    )
