"""What the deep baselines share: M-SVDD's network, normaliser and training loop, seeding, scoring, files.

Every deep baseline is `msvdd.network.FusionNet` (the paper's CRNN audio encoder, LSTM IMU encoder,
fusion and decoders) plus a small method-specific head and loss, trained by `msvdd.training.train_network`
with the same budget as M-SVDD at each scale (`MSVDDConfig.smoke()`, `.short()`, `.full()`). Inputs are
z-scored with `msvdd.frontend.InputNormalizer` statistics of the training windows and smoothed per window as
M-SVDD does. All random draws (initialisation, dropout, sampling, shuffling) happen inside a forked torch RNG
seeded from the method's seed, so the same seed gives the same model bit for bit. Model files are `.npz`
(weights as float arrays, config as JSON): no pickle. They train and score on `config.device` (cpu, cuda or
auto), saved weights are on the CPU.
"""

from __future__ import annotations

import abc
from typing import Any, ClassVar, Self

import numpy as np
import torch
from torch import nn

from benchmarks.errors import UserError
from benchmarks.methods.base import WindowDetector, check_scale
from msvdd.config import MSVDDConfig
from msvdd.contract import Windows
from msvdd.frontend import InputNormalizer
from msvdd.losses import reconstruction_loss
from msvdd.network import NetOutput
from msvdd.training import resolve_device, split_train_val, train_network

SCORE_CHUNK = 256
"""Windows per forward pass when scoring."""


def scale_config(scale: str, seed: int, **overrides: Any) -> MSVDDConfig:
    """M-SVDD's budget at `scale` (smoke, short, full: `MSVDDConfig.smoke`, `.short`, `.full`)."""
    check_scale(scale)
    factory = {"smoke": MSVDDConfig.smoke, "short": MSVDDConfig.short, "full": MSVDDConfig.full}[scale]
    return factory(seed=seed, **overrides)


def reconstruction_error(out: NetOutput, audio: torch.Tensor, imu: torch.Tensor) -> torch.Tensor:
    """(N,) M-SVDD's per-window Huber reconstruction loss over the modalities the network reconstructs."""
    return reconstruction_loss(audio, out.audio_rec, imu, out.imu_rec)


class DeepDetector(WindowDetector):
    """Base of the deep baselines: subclasses build a module, a loss, post-training statistics and a score."""

    kind: ClassVar[str] = "deep"
    extra_keys: ClassVar[tuple[str, ...]] = ()
    """Names of the post-training tensors (`self.extra`) saved with the weights."""

    def __init__(self, config: MSVDDConfig) -> None:
        super().__init__()
        self.config = config
        self.device = resolve_device(config.device)
        self.module: nn.Module = nn.Module()
        self.normalizer: InputNormalizer | None = None
        self.extra: dict[str, torch.Tensor] = {}

    @abc.abstractmethod
    def build(self) -> nn.Module:
        """A freshly initialised module (called inside the seeded RNG)."""

    @abc.abstractmethod
    def loss(self, module: nn.Module, batch: tuple[torch.Tensor, ...]) -> torch.Tensor:
        """Training loss of one batch (audio, imu)."""

    @abc.abstractmethod
    def batch_scores(self, audio: torch.Tensor, imu: torch.Tensor) -> torch.Tensor:
        """(N,) anomaly scores of normalised tensors, using `self.module` and `self.extra`."""

    def before_training(self, audio: torch.Tensor, imu: torch.Tensor) -> None:
        """Hook run after `build`, before training (e.g. Deep SVDD's centre); default nothing."""
        return None

    def after_training(self, audio: torch.Tensor, imu: torch.Tensor) -> None:
        """Hook run on all training tensors after training (statistics the score needs); default nothing."""
        return None

    def chunks(self, audio: torch.Tensor, imu: torch.Tensor) -> list[tuple[torch.Tensor, torch.Tensor]]:
        """Consecutive slices of at most `SCORE_CHUNK` windows of (audio, imu), moved to the device."""
        return [
            (audio[i : i + SCORE_CHUNK].to(self.device), imu[i : i + SCORE_CHUNK].to(self.device))
            for i in range(0, audio.shape[0], SCORE_CHUNK)
        ]

    @property
    def min_windows(self) -> int:
        """Fewest training windows: one full batch after the validation split."""
        return int(np.ceil(self.config.batch_size / (1.0 - self.config.val_fraction))) + 1

    def _tensors(self, batch: Windows) -> tuple[torch.Tensor, torch.Tensor]:
        if self.normalizer is None:
            raise RuntimeError(f"{type(self).__name__} has no normaliser; fit it first")
        return self.normalizer.tensors(batch, self.config.smooth_window, self.config.smooth_polyorder)

    def _fit(self, train: Windows, val: Windows | None) -> None:
        if len(train) < self.min_windows:
            raise UserError(
                f"train has {len(train)} windows; {type(self).__name__} needs at least {self.min_windows} "
                f"(batch {self.config.batch_size} after a {self.config.val_fraction:.0%} validation split)"
            )
        cfg = self.config
        if val is None:
            tr_idx, va_idx = split_train_val(len(train), cfg.val_fraction, cfg.seed)
            train_part, val_part = train.subset(tr_idx), train.subset(va_idx)
        else:
            train_part, val_part = train, val
        self.normalizer, (audio, imu) = InputNormalizer.fit_tensors(
            train_part, cfg.audio_frontend, cfg.imu_input, cfg.smooth_window, cfg.smooth_polyorder
        )
        val_tensors = self._tensors(val_part) if len(val_part) else None
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(cfg.seed)
            self.module = self.build().to(self.device)
            self.before_training(audio, imu)
            train_network(self.module, self.loss, (audio, imu), val_tensors, cfg)
            self.module.eval()
            with torch.no_grad():
                self.after_training(*self._tensors(train))

    def _score(self, batch: Windows) -> np.ndarray:
        audio, imu = self._tensors(batch)
        self.module.eval()
        with torch.no_grad():
            parts = [self.batch_scores(a, i).cpu() for a, i in self.chunks(audio, imu)]
        return torch.cat(parts).double().numpy()

    def _state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        if self.normalizer is None:
            raise RuntimeError("not fitted")
        arrays = {f"net/{k}": v.detach().cpu().numpy() for k, v in self.module.state_dict().items()}
        arrays |= {f"norm/{k}": v for k, v in self.normalizer.arrays().items()}
        arrays |= {f"extra/{k}": self.extra[k].detach().cpu().numpy() for k in self.extra_keys}
        return {"config": self.config.to_dict(), "torch": torch.__version__}, arrays

    @classmethod
    def _from_state(cls, header: dict[str, Any], arrays: dict[str, np.ndarray]) -> Self:
        detector = cls(MSVDDConfig.from_dict(header["config"]))
        with torch.random.fork_rng(devices=[]):
            detector.module = detector.build().to(detector.device)
        state = {k[4:]: torch.from_numpy(v.copy()) for k, v in arrays.items() if k.startswith("net/")}
        detector.module.load_state_dict({k: v.to(detector.device) for k, v in state.items()})
        detector.module.eval()
        cfg = detector.config
        detector.normalizer = InputNormalizer.from_arrays(
            {k[5:]: v for k, v in arrays.items() if k.startswith("norm/")}, cfg.audio_frontend, cfg.imu_input
        )
        detector.extra = {
            k: torch.from_numpy(arrays[f"extra/{k}"].copy()).to(detector.device) for k in cls.extra_keys
        }
        return detector
