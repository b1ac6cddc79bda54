"""Small signal-analysis helpers the audio tests measure with."""

from __future__ import annotations

import numpy as np
from scipy.signal import butter, hilbert, sosfiltfilt


def peak_frequency(x: np.ndarray, sr: int, lo: float, hi: float, pad: int = 8) -> float:
    """Frequency of the largest Hann-windowed spectrum bin in [lo, hi] Hz (zero-padded for interpolation)."""
    nfft = pad * x.size
    spec = np.abs(np.fft.rfft(x * np.hanning(x.size), nfft))
    freqs = np.fft.rfftfreq(nfft, 1.0 / sr)
    band = (freqs >= lo) & (freqs <= hi)
    return float(freqs[band][np.argmax(spec[band])])


def envelope_spectrum(x: np.ndarray, sr: int, band: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """(frequencies, magnitude) of the Hilbert envelope of x band-passed to `band` (bearing diagnostics)."""
    sos = butter(4, band, btype="bandpass", fs=sr, output="sos")
    env = np.abs(hilbert(sosfiltfilt(sos, x)))
    env = env - env.mean()
    nfft = 8 * env.size
    return np.fft.rfftfreq(nfft, 1.0 / sr), np.abs(np.fft.rfft(env * np.hanning(env.size), nfft))


def rms(x: np.ndarray) -> float:
    """Root mean square over all elements."""
    return float(np.sqrt(np.mean(np.square(x, dtype=np.float64))))
