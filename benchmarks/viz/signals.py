"""Display signal processing (numpy only): audio envelopes, band spectrograms, resampling, state runs."""

from __future__ import annotations

import numpy as np


def minmax_envelope(x: np.ndarray, block: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-block minimum and maximum of a 1-D signal; the last block may be shorter.

    Args:
        x: (n,) samples.
        block: samples per block (>= 1).

    Returns:
        (mins, maxs), each (ceil(n / block),).
    """
    if block < 1:
        raise ValueError(f"envelope block must be >= 1 sample, got {block}")
    x = np.asarray(x).reshape(-1)
    n_full = x.size // block
    head = x[: n_full * block].reshape(n_full, block)
    mins, maxs = head.min(axis=1), head.max(axis=1)
    if x.size > n_full * block:
        tail = x[n_full * block :]
        mins = np.append(mins, tail.min())
        maxs = np.append(maxs, tail.max())
    return mins, maxs


def display_indices(time: np.ndarray, rate_hz: float) -> np.ndarray:
    """Indices into a sorted time axis that sample it at about `rate_hz` (first and last kept).

    Samples already sparser than `rate_hz` are all kept.
    """
    t = np.asarray(time, dtype=np.float64).reshape(-1)
    if t.size == 0:
        return np.zeros(0, dtype=np.int64)
    targets = np.arange(t[0], t[-1], 1.0 / rate_hz)
    idx = np.clip(np.searchsorted(t, targets), 0, t.size - 1)
    return np.unique(np.append(idx, t.size - 1)).astype(np.int64)


def band_edges(rate: float, nfft: int, bands: int, fmin: float, fmax: float) -> np.ndarray:
    """Start FFT bin of each log-spaced band plus the end bin: strictly increasing, (<= bands + 1,).

    Bands narrower than one bin are merged, so fewer than `bands` may come back at low frequencies.
    """
    nyquist = rate / 2.0
    fmax = min(fmax, nyquist)
    edges_hz = np.geomspace(fmin, fmax, bands + 1)
    bins = np.rint(edges_hz * nfft / rate).astype(np.int64)
    bins = np.clip(bins, 1, nfft // 2 + 1)
    return np.unique(bins)


def band_spectrogram(
    mono: np.ndarray, rate: float, nfft: int, hop_s: float, bands: int, fmin: float, fmax: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Hann-windowed power spectrogram pooled into log-spaced bands.

    Args:
        mono: (n,) samples.
        rate: sample rate, Hz.
        nfft: frame length, samples.
        hop_s: hop between frames, s.
        bands: number of log-spaced bands requested.
        fmin: lowest band edge, Hz.
        fmax: highest band edge, Hz (clipped to Nyquist).

    Returns:
        (frame_times (F,) centre of each frame in s, band_centres (B,) geometric band centres in Hz,
        power_db (B, F) mean power per FFT bin of each band, dB re 1; a sine of amplitude A has a
        total power A**2 / 2 over its bins).
    """
    x = np.asarray(mono, dtype=np.float64).reshape(-1)
    hop = max(1, round(hop_s * rate))
    if x.size < nfft:
        x = np.pad(x, (0, nfft - x.size))
    frames = np.lib.stride_tricks.sliding_window_view(x, nfft)[::hop]
    spectrum = np.abs(np.fft.rfft(frames * np.hanning(nfft), axis=1)) ** 2
    spectrum *= 2.0 / np.sum(np.hanning(nfft) ** 2) / nfft
    edges = band_edges(rate, nfft, bands, fmin, fmax)
    sums = np.add.reduceat(spectrum, edges[:-1], axis=1)
    # reduceat's last segment runs to the end of the axis; restrict it to the last band's end bin.
    sums[:, -1] = spectrum[:, edges[-2] : edges[-1]].sum(axis=1)
    power = sums / np.diff(edges)
    times = (np.arange(frames.shape[0]) * hop + nfft / 2.0) / rate
    centres = np.sqrt(edges[:-1] * edges[1:]) * rate / nfft
    return times, centres, (10.0 * np.log10(power + 1e-20)).T


def colorize_db(power_db: np.ndarray, range_db: float, lut: np.ndarray) -> np.ndarray:
    """(B, F) dB -> (B, F, 3) uint8 image, highest band on the top row, the loudest cell at full scale.

    Args:
        power_db: band power, dB, low bands first.
        range_db: dynamic range mapped onto the colour table.
        lut: (256, 3) uint8 colour table, dark first.
    """
    db = np.asarray(power_db, dtype=np.float64)
    top = float(db.max()) if db.size else 0.0
    level = np.clip((db - (top - range_db)) / range_db, 0.0, 1.0)
    codes = np.rint(level * 255).astype(np.uint8)
    return np.ascontiguousarray(lut[codes[::-1]])


def run_starts(keys: np.ndarray) -> np.ndarray:
    """Indices where a run of equal values starts (0 first); empty for an empty input."""
    k = np.asarray(keys).reshape(-1)
    if k.size == 0:
        return np.zeros(0, dtype=np.int64)
    return np.concatenate([[0], np.flatnonzero(k[1:] != k[:-1]) + 1]).astype(np.int64)
