"""Mahalanobis SVDD with audio-IMU fusion (the paper's method), and the detector contract."""

from msvdd.config import MSVDDConfig
from msvdd.contract import Detector, NotFittedError, WindowError, Windows
from msvdd.frontend import InputNormalizer
from msvdd.mcd import MCDError, MCDResult, SingularCovarianceError, mahalanobis, min_cov_det
from msvdd.model import MSVDD, ModelFormatError
from msvdd.network import AudioDecoder, AudioEncoder, Fusion, FusionNet, ImuDecoder, ImuEncoder, NetOutput
from msvdd.preprocess import decimate_audio, frame_windows
from msvdd.stream import StreamingScorer
from msvdd.training import TrainResult, train_network

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
