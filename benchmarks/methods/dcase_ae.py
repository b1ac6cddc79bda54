"""The DCASE 2020 Task 2 baseline (Koizumi et al., 2020): a dense autoencoder on log-mel frame vectors.

As the DCASE baseline: the log-mel spectrogram of the audio, `context` consecutive frames concatenated into
one vector (5 x 32 = 160 values), a fully connected autoencoder (Dense 128 with BatchNorm and ReLU four
times, a bottleneck Dense 8 with BatchNorm and ReLU, Dense 128 with BatchNorm and ReLU four times, a linear
output) trained with the mean squared error on nominal frame vectors by Adam (lr 1e-3, batch 512, shuffled);
the score of a window is the mean over its frame vectors of the mean squared reconstruction error.

Adapted to our windows: the log-mel of the 4410 Hz window audio (`benchmarks.features.log_mel`: Hann
frames of 256 samples, hop 128, 32 mel bands, channel powers averaged), 67 frames and so 63 frame vectors
per 2 s window; every input dimension is standardised with the mean and standard deviation of the training
vectors (the error is measured in these units). Audio only, as the DCASE baseline. The loop is
`msvdd.training.train_network`; with validation windows (the benchmark's nominal validation split) the
epoch with the lowest validation error is kept, else the last. All random draws happen inside a forked
torch RNG seeded from the method's seed, so a seed gives the same model bit for bit on one machine. Model
files are `.npz` (weights and standardisation as arrays, config as JSON): no pickle.
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass
from typing import Any, Self

import numpy as np
import torch
from torch import nn

from benchmarks.features import FeatureConfig, log_mel
from benchmarks.methods.base import WindowDetector, check_scale
from msvdd.contract import Windows
from msvdd.training import resolve_device, train_network

_STD_FLOOR = 1e-8
SCORE_VECTORS = 65_536
"""Frame vectors per forward pass when scoring (bounds memory)."""


@dataclass(frozen=True)
class DcaseAEConfig:
    """Features, network and training budget of the DCASE autoencoder baseline."""

    seed: int = 0
    """Seed of the initialisation and of the batch shuffling."""
    epochs: int = 20
    """Training epochs over all frame vectors (DCASE: 100; see `for_scale`)."""
    batch_size: int = 512
    """Frame vectors per training step (DCASE: 512)."""
    lr: float = 1e-3
    """Adam learning rate (DCASE: the Keras default 1e-3), constant."""
    cosine_decay: bool = False
    """Cosine learning-rate decay per step (DCASE: none)."""
    n_fft: int = 256
    """STFT frame length, samples at 4410 Hz (as `benchmarks.features`)."""
    hop: int = 128
    """STFT hop, samples."""
    n_mels: int = 32
    """Mel bands."""
    context: int = 5
    """Consecutive log-mel frames concatenated into one input vector (DCASE: 5)."""
    hidden: int = 128
    """Width of the hidden dense layers (DCASE: 128)."""
    depth: int = 4
    """Hidden layers on each side of the bottleneck (DCASE: 4)."""
    bottleneck: int = 8
    """Width of the bottleneck layer (DCASE: 8)."""
    device: str = "cpu"
    """Torch device: cpu, cuda or auto."""
    progress: bool = False
    """Show a training progress bar."""

    @property
    def dim(self) -> int:
        """Length of one frame vector: context x n_mels."""
        return self.context * self.n_mels

    @property
    def features(self) -> FeatureConfig:
        """The log-mel settings as a `FeatureConfig`."""
        return FeatureConfig(n_fft=self.n_fft, hop=self.hop, n_mels=self.n_mels)

    @classmethod
    def for_scale(cls, seed: int, scale: str, device: str = "cpu") -> DcaseAEConfig:
        """smoke 5 epochs (the tests' few windows), short 20, full 20 (DCASE: 100).

        Why not DCASE's 100 epochs: a full-scale training set holds ~5000 windows, ~315 000 frame vectors,
        615 steps of 512 per epoch, so 20 epochs are already ~12 000 Adam steps, and 100 would take five
        times as long on a CPU (`make bench` trains it with three seeds).
        """
        check_scale(scale)
        epochs = {"smoke": 5, "short": 20, "full": 20}[scale]
        return cls(seed=seed, epochs=epochs, device=device)

    def to_dict(self) -> dict[str, Any]:
        """JSON-able fields."""
        return dataclasses.asdict(self)


def frame_vectors(audio: np.ndarray, config: DcaseAEConfig) -> np.ndarray:
    """(N, V, context x n_mels) float32: every run of `context` consecutive log-mel frames, frame-major.

    Vector t of a window is [frame t, frame t + 1, ..., frame t + context - 1], each n_mels long, as the
    DCASE baseline's `file_to_vector_array`.
    """
    mel = log_mel(audio, config.features)
    if mel.shape[1] < config.context:
        raise ValueError(f"{mel.shape[1]} log-mel frames per window; context {config.context} needs more")
    runs = np.lib.stride_tricks.sliding_window_view(mel, config.context, axis=1)  # (N, V, M, context)
    return np.ascontiguousarray(runs.transpose(0, 1, 3, 2)).reshape(mel.shape[0], -1, config.dim)


def build_autoencoder(config: DcaseAEConfig) -> nn.Sequential:
    """The DCASE baseline's dense autoencoder: (Dense, BatchNorm, ReLU) blocks and a linear output."""
    widths = (
        [config.dim] + [config.hidden] * config.depth + [config.bottleneck] + [config.hidden] * config.depth
    )
    layers: list[nn.Module] = []
    for n_in, n_out in itertools.pairwise(widths):
        layers += [nn.Linear(n_in, n_out), nn.BatchNorm1d(n_out), nn.ReLU()]
    layers.append(nn.Linear(config.hidden, config.dim))
    return nn.Sequential(*layers)


def _mse_loss(module: nn.Module, batch: tuple[torch.Tensor, ...]) -> torch.Tensor:
    x = batch[0]
    return ((module(x) - x) ** 2).mean()


class DcaseAutoencoder(WindowDetector):
    """DCASE 2020 Task 2 baseline: dense autoencoder on standardised 5-frame log-mel vectors."""

    kind = "dcase-ae"

    def __init__(self, config: DcaseAEConfig) -> None:
        super().__init__()
        self.config = config
        self.device = resolve_device(config.device)
        self.module: nn.Sequential = nn.Sequential()
        self.mean = np.zeros(config.dim, dtype=np.float32)
        self.std = np.ones(config.dim, dtype=np.float32)

    def _raw_vectors(self, batch: Windows) -> np.ndarray:
        """(N, V, dim) float32 frame vectors of a window batch, computed in chunks of windows."""
        chunk = self.config.features.chunk
        return np.concatenate(
            [frame_vectors(batch.audio[s : s + chunk], self.config) for s in range(0, len(batch), chunk)]
        )

    def _standardise(self, raw: np.ndarray) -> np.ndarray:
        return (raw - self.mean) / self.std

    def vectors(self, batch: Windows) -> torch.Tensor:
        """(N, V, dim) float32 standardised frame vectors of a window batch, on the CPU."""
        return torch.from_numpy(self._standardise(self._raw_vectors(batch)))

    def _fit(self, train: Windows, val: Windows | None) -> None:
        cfg = self.config
        raw = self._raw_vectors(train).reshape(-1, cfg.dim)  # log-mel once: statistics and training set
        self.mean = raw.mean(axis=0, dtype=np.float64).astype(np.float32)
        self.std = np.maximum(raw.std(axis=0, dtype=np.float64), _STD_FLOOR).astype(np.float32)
        x = torch.from_numpy(self._standardise(raw))
        del raw
        val_x = self.vectors(val).reshape(-1, cfg.dim) if val is not None else None
        budget = dataclasses.replace(cfg, batch_size=min(cfg.batch_size, x.shape[0]))
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(cfg.seed)
            self.module = build_autoencoder(cfg).to(self.device)
            train_network(self.module, _mse_loss, (x,), None if val_x is None else (val_x,), budget)
        self.module.eval()

    def errors(self, batch: Windows) -> np.ndarray:
        """(N, V) float64 mean squared reconstruction error of every frame vector of every window."""
        x = self.vectors(batch)
        flat = x.reshape(-1, self.config.dim)
        self.module.eval()
        with torch.no_grad():
            parts = [
                ((self.module(v.to(self.device)) - v.to(self.device)) ** 2).mean(dim=1).cpu()
                for v in flat.split(SCORE_VECTORS)
            ]
        return torch.cat(parts).double().numpy().reshape(x.shape[0], x.shape[1])

    def _score(self, batch: Windows) -> np.ndarray:
        return self.errors(batch).mean(axis=1)

    def _state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        arrays = {f"net/{k}": v.detach().cpu().numpy() for k, v in self.module.state_dict().items()}
        arrays |= {"mean": self.mean, "std": self.std}
        return {"config": self.config.to_dict(), "torch": torch.__version__}, arrays

    @classmethod
    def _from_state(cls, header: dict[str, Any], arrays: dict[str, np.ndarray]) -> Self:
        detector = cls(DcaseAEConfig(**header["config"]))
        with torch.random.fork_rng(devices=[]):
            detector.module = build_autoencoder(detector.config).to(detector.device)
        state = {k[4:]: torch.from_numpy(v.copy()) for k, v in arrays.items() if k.startswith("net/")}
        detector.module.load_state_dict({k: v.to(detector.device) for k, v in state.items()})
        detector.module.eval()
        detector.mean, detector.std = arrays["mean"], arrays["std"]
        return detector


def register_methods() -> None:
    """Register `dcase-ae`."""
    from benchmarks.methods.registry import register
    from benchmarks.methods.spec import PaperRow

    def make(seed: int, scale: str, device: str) -> DcaseAutoencoder:
        return DcaseAutoencoder(DcaseAEConfig.for_scale(seed, scale, device))

    register(
        "dcase-ae",
        make,
        cls=DcaseAutoencoder,
        family="deep",
        modality="audio",
        description="DCASE 2020 Task 2 baseline: dense autoencoder on 5-frame log-mel vectors, audio only",
        paper=(PaperRow("Table I", 7, "DCASE AE (log-mel)"),),
        config="DcaseAEConfig",
    )
