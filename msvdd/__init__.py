"""Mahalanobis SVDD with audio-IMU fusion (the paper's method), and the detector contract.

The names below are imported on first use (PEP 562), so that `import msvdd.contract` or
`from msvdd import preprocess` does not import torch: dataset generation, and every worker process it
spawns, reads only the window contract and the decimation.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from msvdd.config import MSVDDConfig
    from msvdd.contract import Detector, ModelFormatError, NotFittedError, WindowError, Windows
    from msvdd.frontend import InputNormalizer
    from msvdd.mcd import MCDError, MCDResult, SingularCovarianceError, mahalanobis, min_cov_det
    from msvdd.model import MSVDD
    from msvdd.network import (
        AudioDecoder,
        AudioEncoder,
        Fusion,
        FusionNet,
        ImuDecoder,
        ImuEncoder,
        NetOutput,
    )
    from msvdd.preprocess import decimate_audio, frame_windows
    from msvdd.stream import StreamingScorer
    from msvdd.training import TrainResult, train_network

_HOME = {
    "msvdd.config": ("MSVDDConfig",),
    "msvdd.contract": ("Detector", "ModelFormatError", "NotFittedError", "WindowError", "Windows"),
    "msvdd.frontend": ("InputNormalizer",),
    "msvdd.mcd": ("MCDError", "MCDResult", "SingularCovarianceError", "mahalanobis", "min_cov_det"),
    "msvdd.model": ("MSVDD",),
    "msvdd.network": (
        "AudioDecoder",
        "AudioEncoder",
        "Fusion",
        "FusionNet",
        "ImuDecoder",
        "ImuEncoder",
        "NetOutput",
    ),
    "msvdd.preprocess": ("decimate_audio", "frame_windows"),
    "msvdd.stream": ("StreamingScorer",),
    "msvdd.training": ("TrainResult", "train_network"),
}
_MODULE_OF = {name: module for module, names in _HOME.items() for name in names}

__all__ = [
    "MSVDD",
    "AudioDecoder",
    "AudioEncoder",
    "Detector",
    "Fusion",
    "FusionNet",
    "ImuDecoder",
    "ImuEncoder",
    "InputNormalizer",
    "MCDError",
    "MCDResult",
    "MSVDDConfig",
    "ModelFormatError",
    "NetOutput",
    "NotFittedError",
    "SingularCovarianceError",
    "StreamingScorer",
    "TrainResult",
    "WindowError",
    "Windows",
    "decimate_audio",
    "frame_windows",
    "mahalanobis",
    "min_cov_det",
    "train_network",
]


def __getattr__(name: str) -> Any:
    module = _MODULE_OF.get(name)
    if module is None:
        raise AttributeError(f"module 'msvdd' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])
