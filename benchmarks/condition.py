"""Condition monitoring of wheel faults: envelopes and order tracking against a wheel angle.

What a vibration analyst computes on a rotating machine, vectorised over a batch of windows:

- `squared_envelope`: the signal band-passed (in the frequency domain) to a band, then the squared magnitude
  of its analytic signal (the squared envelope of bearing diagnostics);
- `order_lines`: the complex demodulation of a signal at multiples of an order of the wheel's angle, i.e.
  the order spectrum's line at k x order, normalised by the signal's own standard deviation; it needs no
  resampling (each sample carries its own angle), so it works whatever the speed profile, reversals included;
- `revolutions`: how far a wheel turned, whichever way.

Each fault kind's indicators built on them are in `benchmarks.fault_indicators`.
"""

from __future__ import annotations

import numpy as np


def squared_envelope(x: np.ndarray, rate: float, band: tuple[float, float]) -> np.ndarray:
    """(N, n) squared envelope of (N, n) signals in `band` (Hz, low included, high excluded).

    The band is cut in the frequency domain (rfft bins outside it set to zero); the analytic signal is the
    inverse FFT of the one-sided, doubled spectrum. A band outside (0, rate / 2) raises ValueError.
    """
    x = np.atleast_2d(np.asarray(x, dtype=np.float64))
    n = x.shape[-1]
    lo, hi = band
    if not 0.0 <= lo < hi <= rate / 2:
        raise ValueError(f"band = {band} Hz is invalid; allowed: 0 <= low < high <= {rate / 2:g} Hz")
    spectrum = np.fft.fft(x, axis=-1)
    freqs = np.fft.fftfreq(n, 1.0 / rate)
    keep = (freqs >= lo) & (freqs < hi)
    analytic = np.fft.ifft(np.where(keep, 2.0 * spectrum, 0.0), axis=-1)
    return np.asarray(analytic.real**2 + analytic.imag**2)


def band_pass(x: np.ndarray, rate: float, band: tuple[float, float]) -> np.ndarray:
    """(N, n) signals with every rfft bin outside `band` (Hz, low included, high excluded) zeroed."""
    x = np.atleast_2d(np.asarray(x, dtype=np.float64))
    freqs = np.fft.rfftfreq(x.shape[-1], 1.0 / rate)
    keep = (freqs >= band[0]) & (freqs < band[1])
    return np.fft.irfft(np.where(keep, np.fft.rfft(x, axis=-1), 0.0), n=x.shape[-1], axis=-1)


def order_lines(x: np.ndarray, angle: np.ndarray, orders: np.ndarray) -> np.ndarray:
    """(N, K) amplitude of the lines at `orders` (K,) of (N, n) signals sampled at wheel angles `angle` (rad).

    Each line is |mean((x - mean x) exp(-i k angle))| / std(x): 1 / sqrt(2) for a pure tone locked to the
    angle at order k, about 1 / sqrt(n) for noise, and 0 when the wheel stands still (the line needs turning).
    """
    x = np.atleast_2d(np.asarray(x, dtype=np.float64))
    centred = x - x.mean(axis=-1, keepdims=True)
    scale = np.maximum(centred.std(axis=-1), 1e-30)
    phase = np.asarray(angle, dtype=np.float64)[:, None, :] * np.asarray(orders, dtype=np.float64)[:, None]
    demod = np.einsum("nj,nkj->nk", centred, np.exp(-1j * phase)) / x.shape[-1]
    return np.asarray(np.abs(demod) / scale[:, None])


def revolutions(angle: np.ndarray, axis: int = -1) -> np.ndarray:
    """Revolutions a wheel turned over each angle trace (rad) along `axis` (time), whichever way it turned:
    (N,) of (N, n) traces, (N, W) of (N, n, W) with axis=1."""
    a = np.atleast_2d(np.asarray(angle, dtype=np.float64))
    return np.asarray(np.abs(np.diff(a, axis=axis)).sum(axis=axis) / (2 * np.pi))


SPLIT_HZ = 4.0
"""IMU content below this is the chassis' smooth motion (tracked as it is), above it vibration (its power)."""
ENVELOPE_BLOCK = 21
"""Audio samples averaged into one envelope sample (4410 Hz / 21 = 210 Hz)."""


def block_envelope(
    audio: np.ndarray, rate: float, band: tuple[float, float]
) -> tuple[np.ndarray, np.ndarray]:
    """The (N, n / `ENVELOPE_BLOCK`) squared envelope of (N, n) audio in `band`, averaged over blocks of
    `ENVELOPE_BLOCK` samples, and the (n / `ENVELOPE_BLOCK`,) times of its samples (block centres), s."""
    env = squared_envelope(audio, rate, band)
    env = env.reshape(len(env), -1, ENVELOPE_BLOCK).mean(axis=-1)
    return env, (np.arange(env.shape[1]) + 0.5) * ENVELOPE_BLOCK / rate
