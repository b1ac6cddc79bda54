"""What every baseline adds to `msvdd.contract.Detector`: the training scales and `.npz` model files."""

from __future__ import annotations

import abc
import os
from typing import Any, ClassVar, Self

import numpy as np

from benchmarks.errors import UserError
from benchmarks.methods._io import load_npz, save_npz
from msvdd.contract import Detector, NotFittedError, model_fields

SCALES: tuple[str, ...] = ("smoke", "short", "full")
"""Training budgets every method understands: smoke (seconds: tests), short (minutes: `make demo`), full
(the paper's budget). Named apart from the dataset presets (tiny, quick, paper, ...), whose `method_scale`
says which budget each uses by default."""


def check_scale(scale: str) -> str:
    """Return `scale` if it is one of `SCALES`, else raise a UserError naming the allowed values."""
    if scale not in SCALES:
        from benchmarks.presets import preset_names

        hint = " (that names a dataset preset; budgets are named apart)" if scale in preset_names() else ""
        raise UserError(f"scale {scale!r} is unknown; allowed: {', '.join(SCALES)}{hint}")
    return scale


class WindowDetector(Detector):
    """Base of the baselines: subclasses implement `_fit`, `_score`, `_state` and `_from_state`.

    Fitting and the threshold follow `msvdd.contract.Detector`. Model files are `.npz` with a JSON header
    (no pickle).
    """

    kind: ClassVar[str] = "window-detector"
    """Model kind written into and checked in the model file."""
    format_version: ClassVar[int] = 1
    """Model file format version; bumped when the stored state changes meaning."""

    @abc.abstractmethod
    def _state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """JSON-able header fields and numeric arrays that rebuild the fitted model."""

    @classmethod
    @abc.abstractmethod
    def _from_state(cls, header: dict[str, Any], arrays: dict[str, np.ndarray]) -> Self:
        """Rebuild a fitted model from `_state`'s output (without the threshold)."""

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the fitted model and its threshold to one `.npz` file, atomically."""
        if not self._fitted:
            raise NotFittedError(f"{type(self).__name__} is not fitted; nothing to save")
        header, arrays = self._state()
        header = {**header, "threshold": self.threshold_, "threshold_source": self.threshold_source_}
        save_npz(path, self.kind, self.format_version, header, arrays)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Self:
        """Read a file written by `save`.

        Raises:
            FileNotFoundError: the file does not exist.
            ModelFormatError: not such a model file, another kind or format version, a field missing or
                malformed, or a model that does not rebuild; the message names the file (and the field).
        """
        header, arrays = load_npz(path, cls.kind, cls.format_version)
        with model_fields(f"model file {path}"):
            detector = cls._from_state(header, arrays)
            detector._set_threshold(float(header["threshold"]), str(header.get("threshold_source", "train")))
        return detector
