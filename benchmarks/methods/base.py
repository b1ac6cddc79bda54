"""What every baseline shares: input checks, the training-score threshold, predict, save and load."""

from __future__ import annotations

import abc
import os
from typing import Any, ClassVar, Self

import numpy as np

from benchmarks.errors import UserError
from benchmarks.methods._io import load_npz, save_npz
from msvdd.contract import Windows

SCALES: tuple[str, ...] = ("tiny", "quick", "paper")
"""Training budgets every method understands: tiny (seconds, tests), quick (make demo), paper."""

THRESHOLD_PERCENTILE = 95.0
"""The paper's decision threshold: this percentile of the training scores."""


def check_scale(scale: str) -> str:
    """Return `scale` if it is one of `SCALES`, else raise a UserError naming the allowed values."""
    if scale not in SCALES:
        raise UserError(f"scale {scale!r} is unknown; allowed: {', '.join(SCALES)}")
    return scale


def check_windows(batch: object, what: str, minimum: int = 1) -> Windows:
    """Return `batch` if it is a `Windows` with at least `minimum` windows; else a clear error."""
    if not isinstance(batch, Windows):
        raise TypeError(f"{what} must be msvdd.contract.Windows, got {type(batch).__name__}")
    if len(batch) < minimum:
        raise UserError(f"{what} has {len(batch)} windows; at least {minimum} needed")
    return batch


def training_threshold(train_scores: np.ndarray) -> float:
    """The paper's threshold: the 95th percentile (linear interpolation) of the training scores."""
    return float(np.percentile(np.asarray(train_scores, dtype=np.float64), THRESHOLD_PERCENTILE))


class WindowDetector(abc.ABC):
    """Base of the baselines: subclasses implement `_fit`, `_score`, `_state` and `_from_state`.

    `fit` fits the model, then sets `threshold_` to the 95th percentile of the scores of the training
    windows; it never changes afterwards. Model files are `.npz` with a JSON header (no pickle).
    """

    kind: ClassVar[str] = "window-detector"
    """Model kind written into and checked in the model file."""
    format_version: ClassVar[int] = 1
    """Model file format version; bumped when the stored state changes meaning."""
    min_train: ClassVar[int] = 2
    """Fewest training windows `fit` accepts."""

    def __init__(self) -> None:
        self.threshold_: float = float("nan")
        self._fitted = False

    @abc.abstractmethod
    def _fit(self, train: Windows, val: Windows | None) -> None:
        """Fit the model on nominal training windows."""

    @abc.abstractmethod
    def _score(self, batch: Windows) -> np.ndarray:
        """(N,) scores of a fitted model, higher = more anomalous."""

    @abc.abstractmethod
    def _state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """JSON-able header fields and numeric arrays that rebuild the fitted model."""

    @classmethod
    @abc.abstractmethod
    def _from_state(cls, header: dict[str, Any], arrays: dict[str, np.ndarray]) -> Self:
        """Rebuild a fitted model from `_state`'s output (without the threshold)."""

    def fit(self, train: Windows, val: Windows | None = None) -> Self:
        """Fit on nominal windows and set `threshold_` from the training scores only."""
        check_windows(train, "train", self.min_train)
        if val is not None:
            check_windows(val, "val")
        self._fit(train, val)
        self._fitted = True
        self.threshold_ = training_threshold(self.score(train))
        return self

    def score(self, batch: Windows) -> np.ndarray:
        """(N,) float64 anomaly scores, higher = more anomalous."""
        if not self._fitted:
            raise RuntimeError(f"{type(self).__name__} is not fitted; call fit(train) first")
        check_windows(batch, "batch")
        scores = np.asarray(self._score(batch), dtype=np.float64)
        if scores.shape != (len(batch),):
            raise RuntimeError(f"{type(self).__name__} produced scores of shape {scores.shape}")
        return scores

    def predict(self, batch: Windows) -> np.ndarray:
        """(N,) bool: score > threshold_."""
        return self.score(batch) > self.threshold_

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the fitted model and its threshold to one `.npz` file, atomically."""
        if not self._fitted:
            raise RuntimeError(f"{type(self).__name__} is not fitted; nothing to save")
        header, arrays = self._state()
        save_npz(path, self.kind, self.format_version, {**header, "threshold": self.threshold_}, arrays)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Self:
        """Read a file written by `save`; refuses another kind or format version."""
        header, arrays = load_npz(path, cls.kind, cls.format_version)
        detector = cls._from_state(header, arrays)
        detector.threshold_ = float(header["threshold"])
        detector._fitted = True
        return detector
