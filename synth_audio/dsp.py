"""Small vectorised signal-processing helpers shared by the source modules."""

from __future__ import annotations

import functools
import math
import zlib

import numpy as np
import scipy.fft as sfft
from scipy.signal import butter

from synth_audio import kernels

_INT16_STD = float(np.sqrt((2.0**32 - 1.0) / 12.0))
BED_SEGMENT = 2**16
"""Length of the shaped segments noise beds are woven from, samples (1.5 s at 44.1 kHz)."""
BED_POOL = 8
"""Shaped segments per noise bed; every overlap-add snippet picks one at a random circular offset."""
TABLE_SIZE = 2**16
"""Points per cycle of the harmonic wavetables (a power of two)."""
MODE_FLOOR_DB = 140.0
"""Decay after which `damped_modes` stops computing a mode, dB: float32 resolves 2^-24 (-144 dB) of a peak."""


def white(rng: np.random.Generator, n: int, out: np.ndarray | None = None) -> np.ndarray:
    """Unit-variance uniform white noise, float32 (fast: built from the generator's raw bytes), written into
    `out` ((n,) float32) when given."""
    raw = np.frombuffer(rng.bytes(2 * max(n, 0)), dtype=np.int16)
    if out is None:
        out = np.empty(raw.shape[0], dtype=np.float32)
    elif out.shape != raw.shape or out.dtype != np.float32:
        raise ValueError(f"out must be ({raw.shape[0]},) float32, got {out.shape} {out.dtype}")
    kernels.scale_int16(raw, np.float32(1.0 / _INT16_STD), out)
    return out


def shaped_noise(
    rng: np.random.Generator,
    n: int,
    sample_rate: int,
    points_hz: tuple[float, ...],
    gains_db: tuple[float, ...],
) -> np.ndarray:
    """Gaussian-like noise of length n whose magnitude spectrum follows (points_hz, gains_db), unit RMS.

    The spectrum is interpolated linearly in log-frequency between the points and held flat outside them.
    """
    if n <= 0:
        return np.zeros(0, dtype=np.float32)
    nfft = sfft.next_fast_len(n, real=True)
    nbins = nfft // 2 + 1
    freqs = np.arange(nbins, dtype=np.float64) * (sample_rate / nfft)
    logf = np.log(np.maximum(freqs, 1.0))
    shape = 10.0 ** (np.interp(logf, np.log(points_hz), gains_db) / 20.0)
    shape[0] = 0.0
    spectrum = np.empty(nbins, dtype=np.complex64)
    spectrum.real = white(rng, nbins) * shape
    spectrum.imag = white(rng, nbins) * shape
    out = sfft.irfft(spectrum, nfft)[:n].astype(np.float32, copy=False)
    return normalise_rms(out)


@functools.lru_cache(maxsize=32)
def bed_pool(sample_rate: int, points_hz: tuple[float, ...], gains_db: tuple[float, ...]) -> np.ndarray:
    """(BED_POOL, BED_SEGMENT) independently shaped unit-RMS segments for `noise_bed`, read-only.

    A library, as a sound designer keeps one: the segments depend only on the spectral shape (their
    generator is seeded by it), so every episode's beds of one shape are woven from the same segments,
    each bed drawing its own snippets and offsets from the episode's generator (`noise_bed`), and the
    library is made once per process. Two beds share a stretch of noise only if they draw the same segment
    and offset (1 in BED_POOL x BED_SEGMENT per snippet), in one episode or across episodes.
    """
    key = repr((int(sample_rate), tuple(float(p) for p in points_hz), tuple(float(g) for g in gains_db)))
    rng = np.random.default_rng([zlib.crc32(key.encode()), 0xBED])
    parts = [shaped_noise(rng, BED_SEGMENT, sample_rate, points_hz, gains_db) for _ in range(BED_POOL)]
    pool = np.stack(parts)
    pool.setflags(write=False)
    return pool


def noise_bed(rng: np.random.Generator, n: int, pool: np.ndarray) -> np.ndarray:
    """(n,) unit-RMS stationary noise woven from `pool` that does not repeat (cheap for long renders).

    Sine-windowed snippets overlap by half (their squared windows sum to one, so the power is constant);
    each snippet is a pool segment read from a random circular offset. Two snippets are the same stretch of
    noise only if they draw the same segment and offset (1 in BED_POOL x BED_SEGMENT), so the bed has no
    autocorrelation peak at any lag, and beds drawn from one pool with different generators are
    uncorrelated with each other.
    """
    k, size = pool.shape
    if n <= 0:
        return np.zeros(0, dtype=np.float32)
    hop = size // 2
    count = -(-(n + hop) // hop)  # out[hop:] is the bed: every sample is covered by two snippets
    segments = rng.integers(0, k, count)
    offsets = rng.integers(0, size, count)
    out = np.zeros(count * hop + size, dtype=np.float32)
    kernels.weave(out, pool, segments, offsets, _sine_window(size), hop)
    return out[hop : hop + n]


@functools.lru_cache(maxsize=4)
def _sine_window(size: int) -> np.ndarray:
    """sin(pi (i + 0.5) / size), float32, read-only: squared, two copies half a window apart sum to one."""
    window = np.sin(np.pi * (np.arange(size) + 0.5) / size).astype(np.float32)
    window.setflags(write=False)
    return window


def harmonic_table(
    harmonics: np.ndarray, amps: np.ndarray, phases: np.ndarray, size: int = TABLE_SIZE
) -> np.ndarray:
    """One period of sum_k amps[k] sin(2 pi harmonics[k] x + phases[k]) on `size` points (one inverse FFT).

    Harmonic numbers must be positive integers below size / 2.
    """
    spectrum = np.zeros(size // 2 + 1, dtype=np.complex128)
    for k, a, p in zip(np.asarray(harmonics), np.asarray(amps), np.asarray(phases), strict=True):
        spectrum[round(float(k))] += 0.5 * size * a * np.exp(1j * (p - 0.5 * np.pi))
    return sfft.irfft(spectrum, size).astype(np.float32)


def unit_table(harmonics: np.ndarray, amps: np.ndarray, phases: np.ndarray) -> np.ndarray:
    """`harmonic_table` of a robot unit's fixed tones (motor, fan), made once per process for each set of
    tones and read-only: a unit sounds the same in every episode."""
    return _unit_table(
        tuple(float(k) for k in harmonics), tuple(float(a) for a in amps), tuple(float(p) for p in phases)
    )


@functools.lru_cache(maxsize=64)
def _unit_table(
    harmonics: tuple[float, ...], amps: tuple[float, ...], phases: tuple[float, ...]
) -> np.ndarray:
    table = harmonic_table(np.array(harmonics), np.array(amps), np.array(phases))
    table.setflags(write=False)
    return table


def wavetable(phase: np.ndarray, table: np.ndarray) -> np.ndarray:
    """Periodic waveform `table` (power-of-two size, one cycle) read at `phase` cycles (>= 0).

    Nearest-point lookup: with the default 65536-point table the phase error is below 1e-4 cycle, so
    even the 40th harmonic is reproduced with spurious content under -50 dB.
    """
    return np.take(table, table_index(phase, table.size))


def block_wavetable(cycles: np.ndarray, block: int, n: int, table: np.ndarray) -> np.ndarray:
    """(n,) `wavetable(frac_phase(cycles, block, n), table)` for one tone's cycle counts at block
    boundaries (1-D), the same samples in one pass (`kernels.wavetable_read`)."""
    out = np.empty(n, dtype=np.float32)
    kernels.wavetable_read(np.ascontiguousarray(cycles, dtype=np.float64), block, table, out)
    return out


def table_index(phase: np.ndarray, size: int) -> np.ndarray:
    """Nearest-point index into a power-of-two wavetable of `size` points for `phase` cycles (>= 0)."""
    idx = (phase * np.float32(size)).astype(np.int32)
    idx &= size - 1
    return idx


def normalise_rms(x: np.ndarray) -> np.ndarray:
    """x scaled to unit RMS in place (all-zero input is returned unchanged)."""
    value = rms(x)
    if value > 0.0:
        x *= np.float32(1.0 / value)
    return x


def rms(x: np.ndarray) -> float:
    """Root mean square over every element."""
    return math.sqrt(kernels.sum_squares(x.reshape(-1)) / x.size) if x.size else 0.0


def block_ramp(values: np.ndarray, block: int, n: int) -> np.ndarray:
    """Per-sample linear interpolation of control values given at block boundaries (..., nb+1) -> (..., n)."""
    v = np.asarray(values, dtype=np.float32)
    ramp = np.arange(block, dtype=np.float32) / np.float32(block)
    start = v[..., :-1, None]
    step = (v[..., 1:] - v[..., :-1])[..., None]
    out = start + step * ramp
    return out.reshape(*v.shape[:-1], -1)[..., :n]


def frac_phase(cycles: np.ndarray, block: int, n: int) -> np.ndarray:
    """Per-sample phase in cycles, wrapped near [0, 1), from float64 cycle counts at block boundaries.

    The fractional part is taken in float64 at the boundaries and the per-block increment is ramped in
    float32, so long signals keep full phase precision and the phase is continuous across blocks.
    """
    c = np.asarray(cycles, dtype=np.float64)
    base = c[..., :-1] - np.floor(c[..., :-1])
    inc = c[..., 1:] - c[..., :-1]
    ramp = np.arange(block, dtype=np.float32) / np.float32(block)
    out = base.astype(np.float32)[..., None] + inc.astype(np.float32)[..., None] * ramp
    return out.reshape(*c.shape[:-1], -1)[..., :n]


def damped_modes(
    freqs: np.ndarray, t60: np.ndarray, amps: np.ndarray, phases: np.ndarray, sample_rate: int, length: int
) -> np.ndarray:
    """Sum of exponentially damped sinusoids a exp(-6.91 t / T60) sin(2 pi f t + phase) (a modal bank),
    float32 of the given length (`kernels.damped_modes_into`).

    Each mode is computed until it has decayed by `MODE_FLOOR_DB` (2.3 x its T60), past which it lies under
    float32's resolution of its own peak: a short mode of a bank with a long one costs its own length only.
    """
    nyq = 0.48 * sample_rate
    keep = (freqs > 0) & (freqs < nyq) & (amps != 0)
    t60_s = np.maximum(np.asarray(t60, dtype=np.float64)[keep], 1e-4)
    lengths = np.ceil(MODE_FLOOR_DB / 60.0 * t60_s * sample_rate).astype(np.int64) + 1
    out = np.zeros(length, dtype=np.float32)
    kernels.damped_modes_into(
        out, 2.0 * np.pi * np.asarray(freqs, dtype=np.float64)[keep] / sample_rate,
        6.907755 / (t60_s * sample_rate), np.asarray(amps, dtype=np.float64)[keep],
        np.asarray(phases, dtype=np.float64)[keep], lengths,
    )  # fmt: skip
    return out


def modal_length(t60: np.ndarray, sample_rate: int, cap_s: float = 1.5) -> int:
    """Samples needed for the slowest mode to decay by 60 dB (capped)."""
    longest = float(np.max(t60)) if np.size(t60) else 0.01
    return max(int(min(longest, cap_s) * sample_rate), 16)


def overlap_add(n: int, positions: np.ndarray, amps: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """Sum of `amps[i] * kernel` placed at integer sample `positions[i]`, truncated to n samples."""
    out = np.zeros(n, dtype=np.float32)
    overlap_add_into(out, positions, amps, kernel)
    return out


def overlap_add_into(out: np.ndarray, positions: np.ndarray, amps: np.ndarray, kernel: np.ndarray) -> None:
    """out += sum of `amps[i] * kernel` placed at integer sample `positions[i]` (in place, clipped)."""
    if positions.size == 0 or kernel.size == 0:
        return
    kernels.overlap_add_into(
        out,
        np.ascontiguousarray(positions, dtype=np.int64),
        np.ascontiguousarray(amps, dtype=np.float32),
        np.ascontiguousarray(kernel, dtype=np.float32),
    )


def add_at(out: np.ndarray, start: int, signal: np.ndarray) -> None:
    """out[start : start + len(signal)] += signal, clipped to out's bounds (in place)."""
    n = out.shape[0]
    a, b = max(start, 0), min(start + signal.shape[0], n)
    if b > a:
        out[a:b] += signal[a - start : b - start]


def fractional_taps(delay: float) -> tuple[int, np.ndarray]:
    """Third-order Lagrange fractional delay: (first integer shift m, 4 taps) with y[n] = sum h_k x[n-m-k]."""
    d = max(float(delay), 1.0)
    m = int(np.floor(d)) - 1
    frac = d - m
    k = np.arange(4)
    taps = np.ones(4)
    for j in range(4):
        other = k != j
        taps[other] *= (frac - j) / (k[other] - j)
    return m, taps.astype(np.float32)


def delay_into(out: np.ndarray, x: np.ndarray, delay: float, gain: float, start: int = 0) -> None:
    """out[start + n] += gain * x delayed by a fractional number of samples (Lagrange, in place)."""
    m, taps = fractional_taps(delay)
    weights = (taps.astype(np.float64) * gain).astype(np.float32)
    kernels.fractional_delay_into(out, np.ascontiguousarray(x, dtype=np.float32), m, weights, start)


def bandpass_sos(low_hz: float, high_hz: float, sample_rate: float) -> np.ndarray:
    """Second-order Butterworth band-pass between `low_hz` and `high_hz`, as second-order sections
    (`scipy.signal.butter`), designed once per process for each band (the sources ask for a few bands,
    often); a copy, which `scipy.signal.sosfilt` may take (it wants a writable array)."""
    return _bandpass_sos(float(low_hz), float(high_hz), float(sample_rate)).copy()


@functools.lru_cache(maxsize=256)
def _bandpass_sos(low_hz: float, high_hz: float, sample_rate: float) -> np.ndarray:
    sos = np.asarray(butter(2, [low_hz, high_hz], btype="bandpass", fs=sample_rate, output="sos"))
    sos.setflags(write=False)
    return sos


def one_pole_lowpass(x: np.ndarray, cutoff_hz: float, sample_rate: float) -> np.ndarray:
    """First-order low-pass (cheap, for short segments)."""
    a = float(np.exp(-2.0 * np.pi * cutoff_hz / sample_rate))
    out = np.empty(np.shape(x), dtype=np.float32)
    kernels.two_pole_into(np.asarray(x), 1.0 - a, -a, 0.0, out)
    return out


def resonate(x: np.ndarray, freq_hz: float, damping_ratio: float, sample_rate: int) -> np.ndarray:
    """Two-pole resonator at freq_hz with the given damping ratio, unit gain at resonance (approx.)."""
    f = float(np.clip(freq_hz, 10.0, 0.45 * sample_rate))
    r = float(np.exp(-2.0 * np.pi * f * damping_ratio / sample_rate))
    w = 2.0 * np.pi * f / sample_rate
    out = np.empty(np.shape(x), dtype=np.float32)
    kernels.two_pole_into(np.asarray(x), 1.0 - r, -2.0 * r * math.cos(w), r * r, out)
    return out
