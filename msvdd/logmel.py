"""Log-mel spectrograms of window audio: an HTK mel filterbank on the power STFT (numpy, no state).

Used by M-SVDD's spectrogram front end (`msvdd.frontend`) and by the benchmark's handcrafted features
(`benchmarks.features`), so both see the same spectrogram.
"""

from __future__ import annotations

import functools

import numpy as np

LOG_MEL_FLOOR = 1e-6
"""Added to mel energies before the log (about -60 dB re a full-scale frame), so silent bands do not
turn float rounding into large log swings."""


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


@functools.lru_cache(maxsize=8)
def _bank32(n_mels: int, n_fft: int, sample_rate: float, f_min: float, f_max: float) -> np.ndarray:
    return mel_filterbank(n_mels, n_fft, sample_rate, f_min, f_max).astype(np.float32)


def log_mel_frames(
    audio: np.ndarray,
    sample_rate: float,
    n_fft: int,
    hop: int,
    n_mels: int,
    f_min: float,
    f_max: float,
    average_channels: bool = True,
) -> np.ndarray:
    """Log mel energies of (N, T) or (N, T, C) audio: (N, frames, n_mels), or (N, C, frames, n_mels).

    Hann frames of `n_fft` samples every `hop`; with `average_channels` the channels' powers are averaged
    before the filterbank, otherwise each channel keeps its own spectrogram.
    """
    x = np.asarray(audio, dtype=np.float32)
    if x.ndim == 2:
        x = x[:, :, None]
    if x.ndim != 3 or x.shape[1] < n_fft:
        raise ValueError(f"audio shape {x.shape}; expected (N, T >= {n_fft}) or (N, T, C)")
    bank = _bank32(n_mels, n_fft, float(sample_rate), float(f_min), float(f_max))
    window = np.hanning(n_fft + 1)[:-1].astype(np.float32)
    frames = np.lib.stride_tricks.sliding_window_view(x, n_fft, axis=1)[:, ::hop]
    spectrum = np.fft.rfft(frames * window, axis=-1)
    power = spectrum.real**2 + spectrum.imag**2
    if average_channels:
        return np.log(power.mean(axis=2) @ bank.T + LOG_MEL_FLOOR)
    return np.log(np.moveaxis(power, 2, 1) @ bank.T + LOG_MEL_FLOOR)
