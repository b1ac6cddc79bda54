"""Condition monitoring of wheel faults: envelopes, order tracking against a wheel angle, synchronous means.

What a vibration analyst computes on a rotating machine, vectorised over a batch of windows:

- `squared_envelope`: the signal band-passed (in the frequency domain) to a band, then the squared magnitude
  of its analytic signal (the squared envelope of bearing diagnostics);
- `order_lines`: the complex demodulation of a signal at multiples of an order of the wheel's angle, i.e.
  the order spectrum's line at k x order, normalised by the signal's own standard deviation; it needs no
  resampling (each sample carries its own angle), so it works whatever the speed profile, reversals included;
- `synchronous_strength`: the time-synchronous average over the defect's period (samples binned by the
  defect's phase), as the energy of the bin means over what the same number of independent samples would
  give: 1 for a signal unrelated to the angle, large for a defect that repeats at the same angle;
- `revolutions`: how far a wheel turned, whichever way.

The audit's privileged oracle (`benchmarks.audit.oracle`) feeds them the true wheel angle; the fault-aware
reference detector (`benchmarks.methods.orders`) feeds them the wheel encoders' angle.
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

    Each line is |mean((x - mean x) exp(-i k angle))| / std(x): 0.5 for a pure tone locked to the angle at
    order k, about 1 / sqrt(n) for noise, and 0 when the wheel stands still (the line needs turning).
    """
    x = np.atleast_2d(np.asarray(x, dtype=np.float64))
    centred = x - x.mean(axis=-1, keepdims=True)
    scale = np.maximum(centred.std(axis=-1), 1e-30)
    phase = np.asarray(angle, dtype=np.float64)[:, None, :] * np.asarray(orders, dtype=np.float64)[:, None]
    demod = np.einsum("nj,nkj->nk", centred, np.exp(-1j * phase)) / x.shape[-1]
    return np.asarray(np.abs(demod) / scale[:, None])


def synchronous_strength(x: np.ndarray, angle: np.ndarray, order: float, bins: int = 16) -> np.ndarray:
    """(N,) strength of the time-synchronous average of (N, n) signals over the period of `order` (per rev).

    Samples are binned by the defect's phase (order x angle, modulo one period) into `bins` bins; the
    strength is sum_b n_b (mean_b - mean)^2 / var(x) over (bins - 1): about 1 for a signal unrelated to the
    angle (for independent samples), larger for one that repeats at the same phase. A window in which the
    wheel does not turn fills one bin and gives 0.
    """
    x = np.atleast_2d(np.asarray(x, dtype=np.float64))
    n_win = x.shape[0]
    phase = np.mod(np.asarray(angle, dtype=np.float64) * order / (2 * np.pi), 1.0)
    index = np.minimum((phase * bins).astype(np.int64), bins - 1) + bins * np.arange(n_win)[:, None]
    counts = np.bincount(index.ravel(), minlength=n_win * bins).reshape(n_win, bins)
    sums = np.bincount(index.ravel(), weights=x.ravel(), minlength=n_win * bins).reshape(n_win, bins)
    mean = x.mean(axis=-1, keepdims=True)
    var = np.maximum(x.var(axis=-1), 1e-30)
    with np.errstate(invalid="ignore", divide="ignore"):
        bin_mean = np.where(counts > 0, sums / np.maximum(counts, 1), mean)
    between = (counts * (bin_mean - mean) ** 2).sum(axis=-1)
    return np.asarray(between / var / (bins - 1))


def revolutions(angle: np.ndarray) -> np.ndarray:
    """(N,) revolutions a wheel turned over each (N, n) angle trace (rad), whichever way it turned."""
    a = np.atleast_2d(np.asarray(angle, dtype=np.float64))
    return np.asarray(np.abs(np.diff(a, axis=-1)).sum(axis=-1) / (2 * np.pi))


SPLIT_HZ = 4.0
"""IMU content below this is the chassis' smooth motion (tracked as it is), above it vibration (its power)."""
ENVELOPE_BLOCK = 21
"""Audio samples averaged into one envelope sample (4410 Hz / 21 = 210 Hz)."""
MESH_NEIGHBOURS: tuple[float, ...] = (-5.5, -4.5, -3.5, -2.5, 2.5, 3.5, 4.5, 5.5)
"""Orders around a gear-mesh line (between its sidebands) whose lines give its noise floor."""


def log_lines(x: np.ndarray, angle: np.ndarray, orders: np.ndarray) -> np.ndarray:
    """(N, K) log of `order_lines`, floored at what noise gives (1 / sqrt(n)), which a still wheel gives."""
    lines = order_lines(x, angle, orders)
    return np.asarray(np.log(np.maximum(lines, 1.0 / np.sqrt(np.shape(x)[-1]))))


def block_envelope(
    audio: np.ndarray, rate: float, band: tuple[float, float]
) -> tuple[np.ndarray, np.ndarray]:
    """The (N, n / `ENVELOPE_BLOCK`) squared envelope of (N, n) audio in `band`, averaged over blocks of
    `ENVELOPE_BLOCK` samples, and the (n / `ENVELOPE_BLOCK`,) times of its samples (block centres), s."""
    env = squared_envelope(audio, rate, band)
    env = env.reshape(len(env), -1, ENVELOPE_BLOCK).mean(axis=-1)
    return env, (np.arange(env.shape[1]) + 0.5) * ENVELOPE_BLOCK / rate


def mesh_lines(audio: np.ndarray, angle: np.ndarray, mesh: float, shaft: float) -> np.ndarray:
    """(N, 3) log of the gear-mesh line of (N, n) audio at wheel angles `angle` and of its two motor-shaft
    sidebands (mesh -+ `shaft` orders), each over the median line at `MESH_NEIGHBOURS` around the mesh."""
    offsets = np.array([0.0, -shaft, shaft, *MESH_NEIGHBOURS])
    lines = order_lines(audio, angle, mesh + offsets)
    floor = np.maximum(np.median(lines[:, 3:], axis=1, keepdims=True), 1e-12)
    return np.asarray(np.log(np.maximum(lines[:, :3], 1e-12) / floor))
