"""Handcrafted window features for the shallow baselines: log-mel audio statistics and IMU statistics.

Audio: a numpy mel filterbank (HTK mel scale, triangles with unit peak) on the power spectrogram of the
4410 Hz window (Hann, 256-sample frames, hop 128), channel powers averaged; per band the mean, standard
deviation and maximum over frames of the log-mel energy, plus the mean and maximum spectral flux (frame
to frame change of the log-mel vector). IMU: amplitude, shape and derivative statistics of the z-velocity
window and log band powers over octave bands.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from msvdd.contract import AUDIO_RATE, IMU_RATE, Windows
from msvdd.logmel import log_mel_frames

_EPS = 1e-10


@dataclass(frozen=True)
class FeatureConfig:
    """Settings of the handcrafted features."""

    n_fft: int = 256
    """STFT frame length, samples at 4410 Hz (58 ms)."""
    hop: int = 128
    """STFT hop, samples."""
    n_mels: int = 32
    """Mel bands."""
    f_min: float = 20.0
    """Lowest mel band edge, Hz."""
    f_max: float = AUDIO_RATE / 2
    """Highest mel band edge, Hz (at most Nyquist)."""
    imu_band_edges: tuple[float, ...] = (0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0, 100.0)
    """Edges of the IMU log band powers, Hz (at most 100 Hz, the IMU Nyquist)."""
    chunk: int = 128
    """Windows per vectorised chunk (bounds memory)."""


IMU_STAT_NAMES: tuple[str, ...] = (
    "mean",
    "std",
    "rms",
    "peak_to_peak",
    "max_abs_dev",
    "skewness",
    "kurtosis",
    "crest",
    "diff_std",
    "diff_max_abs",
    "diff_kurtosis",
)
"""Names of the IMU statistics, in feature order (followed by the log band powers)."""


def log_mel(audio: np.ndarray, config: FeatureConfig = FeatureConfig()) -> np.ndarray:
    """(N, frames, n_mels) log mel energies of (N, T) or (N, T, C) 4410 Hz audio, channel powers averaged."""
    return log_mel_frames(
        audio, AUDIO_RATE, config.n_fft, config.hop, config.n_mels, config.f_min, config.f_max
    )


def audio_features(audio: np.ndarray, config: FeatureConfig = FeatureConfig()) -> np.ndarray:
    """(N, 3 n_mels + 2) float64: per-band mean, std and max of log-mel over frames; mean and max flux."""
    out = []
    for start in range(0, audio.shape[0], config.chunk):
        lm = log_mel(audio[start : start + config.chunk], config).astype(np.float64)
        flux = np.linalg.norm(np.diff(lm, axis=1), axis=2)
        out.append(
            np.concatenate(
                [
                    lm.mean(axis=1),
                    lm.std(axis=1),
                    lm.max(axis=1),
                    flux.mean(1, keepdims=True),
                    flux.max(1, keepdims=True),
                ],
                axis=1,
            )
        )
    if not out:
        return np.zeros((0, 3 * config.n_mels + 2))
    return np.concatenate(out, axis=0)


def _moments(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Row-wise mean, std, skewness and excess kurtosis (0 for a constant row)."""
    mean = x.mean(axis=1)
    dev = x - mean[:, None]
    var = (dev**2).mean(axis=1)
    std = np.sqrt(var)
    safe = np.where(var > _EPS**2, var, 1.0)
    skew = np.where(var > _EPS**2, (dev**3).mean(axis=1) / safe**1.5, 0.0)
    kurt = np.where(var > _EPS**2, (dev**4).mean(axis=1) / safe**2 - 3.0, 0.0)
    return mean, std, skew, kurt


def imu_features(imu: np.ndarray, config: FeatureConfig = FeatureConfig()) -> np.ndarray:
    """(N, 11 + bands) float64 statistics of (N, 400) IMU z-velocity windows at 200 Hz.

    The columns are `IMU_STAT_NAMES` then the log mean power of the mean-removed, Hann-windowed
    spectrum in each band of `imu_band_edges`.
    """
    x = np.asarray(imu, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] < 8:
        raise ValueError(f"imu shape {x.shape}; expected (N, T >= 8)")
    edges = np.asarray(config.imu_band_edges)
    if edges.size < 2 or np.any(np.diff(edges) <= 0) or edges[0] < 0 or edges[-1] > IMU_RATE / 2:
        raise ValueError(f"imu_band_edges {config.imu_band_edges} must increase within 0..{IMU_RATE / 2} Hz")
    mean, std, skew, kurt = _moments(x)
    dev = x - mean[:, None]
    rms = np.sqrt((x**2).mean(axis=1))
    max_abs_dev = np.abs(dev).max(axis=1)
    crest = max_abs_dev / (std + _EPS)
    dx = np.diff(x, axis=1)
    _, d_std, _, d_kurt = _moments(dx)
    freqs = np.fft.rfftfreq(x.shape[1], d=1.0 / IMU_RATE)
    power = np.abs(np.fft.rfft(dev * np.hanning(x.shape[1]), axis=1)) ** 2
    band = (freqs[None, :] >= edges[:-1, None]) & (freqs[None, :] < edges[1:, None])
    band[-1] |= freqs == edges[-1]
    counts = band.sum(axis=1)
    if np.any(counts == 0):
        raise ValueError(
            f"imu bands {np.flatnonzero(counts == 0).tolist()} hold no FFT bin of {x.shape[1]} samples"
        )
    band_power = np.log(power @ band.T / counts + _EPS)
    stats = np.stack(
        [
            mean,
            std,
            rms,
            np.ptp(x, axis=1),
            max_abs_dev,
            skew,
            kurt,
            crest,
            d_std,
            np.abs(dx).max(axis=1),
            d_kurt,
        ],
        axis=1,
    )
    return np.concatenate([stats, band_power], axis=1)


IMU6_STAT_NAMES: tuple[str, ...] = ("mean", "std", "max_abs_dev", "diff_std", "kurtosis")
"""Statistics of each of the six IMU axes (acc xyz, gyro xyz), in feature order (axis-major)."""


def imu6_features(imu6: np.ndarray) -> np.ndarray:
    """(N, 6 x 5) float64: per axis of (N, T, 6) accelerometer/gyro windows, `IMU6_STAT_NAMES`."""
    x = np.asarray(imu6, dtype=np.float64)
    if x.ndim != 3 or x.shape[2] != 6 or x.shape[1] < 8:
        raise ValueError(f"imu6 shape {x.shape}; expected (N, T >= 8, 6)")
    cols = []
    for axis in range(6):
        a = x[:, :, axis]
        mean, std, _, kurt = _moments(a)
        _, d_std, _, _ = _moments(np.diff(a, axis=1))
        cols += [mean, std, np.abs(a - mean[:, None]).max(axis=1), d_std, kurt]
    return np.stack(cols, axis=1)


@dataclass(frozen=True)
class WindowFeatures:
    """Handcrafted features of a window batch, one row per window."""

    audio: np.ndarray
    """(N, Da) float64 log-mel statistics."""
    imu: np.ndarray
    """(N, Di) float64 IMU statistics."""

    def early(self) -> np.ndarray:
        """(N, Da + Di) both modalities concatenated (early fusion)."""
        return np.concatenate([self.audio, self.imu], axis=1)


def window_features(windows: Windows, config: FeatureConfig = FeatureConfig()) -> WindowFeatures:
    """Audio and IMU features of every window."""
    return WindowFeatures(audio=audio_features(windows.audio, config), imu=imu_features(windows.imu, config))
