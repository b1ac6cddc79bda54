"""Mahalanobis SVDD with audio-IMU fusion (the paper's method), and the detector contract."""

from msvdd.contract import Detector, WindowError, Windows

__all__ = ["Detector", "WindowError", "Windows"]
