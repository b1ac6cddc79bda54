"""A generic training loop shared by M-SVDD and the deep baselines (which only write a loss and a score).

Adam, optional cosine decay per step, fixed-size seeded shuffled batches (the last incomplete batch of an
epoch is dropped so that every batch has `batch_size` windows, which per-batch MCD needs), a progress bar, and
the weights of the epoch with the best validation loss restored at the end.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
import torch
from torch import nn
from tqdm.auto import tqdm

LossFn = Callable[[nn.Module, tuple[torch.Tensor, ...]], torch.Tensor]
"""loss_fn(module, batch) -> scalar loss; batch holds one slice of each training tensor, on the device."""
ValLossFn = Callable[[nn.Module, tuple[torch.Tensor, ...]], float]
"""val_loss_fn(module, val_tensors_on_cpu) -> validation loss (lower is better)."""
EpochProbe = Callable[[], dict[str, float]]
"""epoch_probe() -> named figures of the epoch just trained (e.g. the radius), kept in `TrainResult.epochs`.
"""


class TrainConfig(Protocol):
    """The fields of a config the loop reads (`MSVDDConfig` has them all)."""

    @property
    def batch_size(self) -> int: ...
    @property
    def lr(self) -> float: ...
    @property
    def cosine_decay(self) -> bool: ...
    @property
    def epochs(self) -> int: ...
    @property
    def seed(self) -> int: ...
    @property
    def device(self) -> str: ...
    @property
    def progress(self) -> bool: ...


@dataclass
class TrainResult:
    """What `train_network` did."""

    train_loss: list[float] = field(default_factory=list)
    """Mean training loss of each epoch."""
    val_loss: list[float] = field(default_factory=list)
    """Validation loss after each epoch (empty without validation tensors)."""
    best_epoch: int = -1
    """Epoch (0-based) whose weights were kept; the last one without validation."""
    seconds: float = 0.0
    """Wall time of the loop, s."""
    windows_per_s: float = 0.0
    """Training windows processed per second (forward + backward + step)."""
    epochs: dict[str, list[float]] = field(default_factory=dict)
    """Per-epoch figures returned by the epoch probe (name -> one value per epoch)."""

    def to_dict(self) -> dict[str, object]:
        """Plain lists and numbers, for a weights-only checkpoint."""
        return {
            "train_loss": list(self.train_loss),
            "val_loss": list(self.val_loss),
            "best_epoch": self.best_epoch,
            "seconds": self.seconds,
            "windows_per_s": self.windows_per_s,
            "epochs": {k: list(v) for k, v in self.epochs.items()},
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TrainResult:
        """Inverse of `to_dict`."""
        return cls(
            train_loss=[float(v) for v in data["train_loss"]],
            val_loss=[float(v) for v in data["val_loss"]],
            best_epoch=int(data["best_epoch"]),
            seconds=float(data["seconds"]),
            windows_per_s=float(data["windows_per_s"]),
            epochs={str(k): [float(x) for x in v] for k, v in data["epochs"].items()},
        )


def resolve_device(name: str) -> torch.device:
    """ "cpu", "cuda" or "auto" -> a torch device; "cuda" without CUDA is an error that says so."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cuda" and not torch.cuda.is_available():
        raise ValueError(
            "device 'cuda' requested but torch.cuda.is_available() is False; use 'cpu' or 'auto'"
        )
    if name not in ("cpu", "cuda"):
        raise ValueError(f"device {name!r}; allowed: cpu | cuda | auto")
    return torch.device(name)


def split_train_val(n: int, val_fraction: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Seeded (train indices, val indices) of n windows, each sorted; val gets round(n * val_fraction)."""
    n_val = round(n * val_fraction)
    perm = np.random.default_rng(seed).permutation(n)
    return np.sort(perm[n_val:]), np.sort(perm[:n_val])


def batched_loss(loss_fn: LossFn, batch_size: int, device: torch.device) -> ValLossFn:
    """A validation loss: mean of `loss_fn` over consecutive chunks of about `batch_size` (none smaller)."""

    def val_loss(module: nn.Module, tensors: tuple[torch.Tensor, ...]) -> float:
        n = tensors[0].shape[0]
        chunks = np.array_split(np.arange(n), max(1, n // batch_size))
        total = 0.0
        with torch.no_grad():
            for idx in chunks:
                t = torch.from_numpy(idx)
                total += float(loss_fn(module, tuple(x[t].to(device) for x in tensors))) * len(idx)
        return total / n

    return val_loss


def train_network(
    net: nn.Module,
    loss_fn: LossFn,
    train_tensors: Sequence[torch.Tensor],
    val_tensors: Sequence[torch.Tensor] | None,
    config: TrainConfig,
    val_loss_fn: ValLossFn | None = None,
    epoch_probe: EpochProbe | None = None,
) -> TrainResult:
    """Train `net` (already on the device) in place; keep the weights of the best validation epoch.

    Args:
        net: the module to train (all its parameters are optimised).
        loss_fn: loss of one batch.
        train_tensors: CPU tensors with the same first dimension N (e.g. audio, imu).
        val_tensors: validation tensors, or None (then the last epoch is kept).
        config: batch_size, lr, cosine_decay, epochs, seed, device, progress.
        val_loss_fn: validation loss; default the mean of `loss_fn` over batches of `batch_size`.
        epoch_probe: called after each epoch's last step; its figures go to `TrainResult.epochs`.

    Raises:
        ValueError: fewer training windows than one batch.
    """
    device = resolve_device(config.device)
    train = tuple(train_tensors)
    n = train[0].shape[0]
    if n < config.batch_size:
        raise ValueError(f"{n} training windows; at least batch_size={config.batch_size} are needed")
    steps_per_epoch = n // config.batch_size
    optimiser = torch.optim.Adam(net.parameters(), lr=config.lr)
    scheduler = (
        torch.optim.lr_scheduler.CosineAnnealingLR(optimiser, T_max=steps_per_epoch * config.epochs)
        if config.cosine_decay
        else None
    )
    gen = torch.Generator().manual_seed(config.seed)
    validate = val_loss_fn or batched_loss(loss_fn, config.batch_size, device)
    result = TrainResult()
    best = float("inf")
    best_state: dict[str, torch.Tensor] | None = None
    start = time.perf_counter()
    bar = tqdm(range(config.epochs), desc="train", disable=not config.progress, leave=False)
    for epoch in bar:
        net.train()
        perm = torch.randperm(n, generator=gen)
        epoch_loss = 0.0
        for b in range(steps_per_epoch):
            idx = perm[b * config.batch_size : (b + 1) * config.batch_size]
            loss = loss_fn(net, tuple(x[idx].to(device) for x in train))
            optimiser.zero_grad(set_to_none=True)
            loss.backward()
            optimiser.step()
            if scheduler is not None:
                scheduler.step()
            epoch_loss += float(loss.detach())
        result.train_loss.append(epoch_loss / steps_per_epoch)
        if epoch_probe is not None:
            for key, value in epoch_probe().items():
                result.epochs.setdefault(key, []).append(float(value))
        if val_tensors is not None and val_tensors[0].shape[0] > 0:
            net.eval()
            v = validate(net, tuple(val_tensors))
            result.val_loss.append(v)
            if v < best:
                best, result.best_epoch = v, epoch
                best_state = copy.deepcopy(net.state_dict())
        else:
            result.best_epoch = epoch
        bar.set_postfix(loss=f"{result.train_loss[-1]:.4g}")
    result.seconds = time.perf_counter() - start
    result.windows_per_s = steps_per_epoch * config.batch_size * config.epochs / max(result.seconds, 1e-9)
    if best_state is not None:
        net.load_state_dict(best_state)
    net.eval()
    return result
