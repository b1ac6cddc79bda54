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

_EPS = 1e-10
_LOG_MEL_FLOOR = 1e-6
"""Added to mel energies before the log (about -60 dB re a full-scale frame), so silent bands do not
turn float rounding into large log swings."""


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


def hz_to_mel(f: np.ndarray | float) -> np.ndarray:
    """HTK mel scale: 2595 log10(1 + f / 700)."""
    return 2595.0 * np.log10(1.0 + np.asarray(f, dtype=np.float64) / 700.0)


def mel_to_hz(m: np.ndarray | float) -> np.ndarray:
    """Inverse of `hz_to_mel`."""
    return 700.0 * (10.0 ** (np.asarray(m, dtype=np.float64) / 2595.0) - 1.0)


def mel_filterbank(n_mels: int, n_fft: int, sample_rate: float, f_min: float, f_max: float) -> np.ndarray:
    """(n_mels, n_fft // 2 + 1) triangular filters, unit peak, equally spaced on the mel scale.

    Filter m rises linearly (in Hz) from edge m to edge m + 1 and falls to edge m + 2, where the
    n_mels + 2 edges are equally spaced in mel between f_min and f_max; between the first and the last
    centre, neighbouring filters sum to one.

    Raises:
        ValueError: bad frequencies, or a filter that covers no FFT bin (too many bands for n_fft).
    """
    if not 0.0 <= f_min < f_max <= sample_rate / 2:
        raise ValueError(f"need 0 <= f_min < f_max <= {sample_rate / 2} Hz, got f_min={f_min}, f_max={f_max}")
    edges = mel_to_hz(np.linspace(hz_to_mel(f_min), hz_to_mel(f_max), n_mels + 2))
    freqs = np.fft.rfftfreq(n_fft, d=1.0 / sample_rate)
    lower, centre, upper = edges[:-2, None], edges[1:-1, None], edges[2:, None]
    rising = (freqs[None, :] - lower) / (centre - lower)
    falling = (upper - freqs[None, :]) / (upper - centre)
    bank = np.clip(np.minimum(rising, falling), 0.0, None)
    empty = np.flatnonzero(bank.sum(axis=1) == 0)
    if empty.size:
        raise ValueError(f"mel bands {empty.tolist()} cover no FFT bin: use fewer n_mels or a larger n_fft")
    return bank


def log_mel(audio: np.ndarray, config: FeatureConfig = FeatureConfig()) -> np.ndarray:
    """(N, frames, n_mels) log mel energies of (N, T) or (N, T, C) 4410 Hz audio, channel powers averaged."""
    x = np.asarray(audio, dtype=np.float32)
    if x.ndim == 2:
        x = x[:, :, None]
    if x.ndim != 3 or x.shape[1] < config.n_fft:
        raise ValueError(f"audio shape {x.shape}; expected (N, T >= {config.n_fft}) or (N, T, C)")
    bank = mel_filterbank(config.n_mels, config.n_fft, AUDIO_RATE, config.f_min, config.f_max).astype(
        np.float32
    )
    window = np.hanning(config.n_fft + 1)[:-1].astype(np.float32)
    frames = np.lib.stride_tricks.sliding_window_view(x, config.n_fft, axis=1)[:, :: config.hop]
    spectrum = np.fft.rfft(frames * window, axis=-1)
    power = (spectrum.real**2 + spectrum.imag**2).mean(axis=2)
    return np.log(power @ bank.T + _LOG_MEL_FLOOR)


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
