"""Scoring-time perturbations of one episode's continuous streams: pure functions on arrays.

Time convention (the one `msvdd.preprocess.frame_windows` cuts windows by): sample i of a stream at `rate` Hz
is at episode time i / rate, and t = 0 is the episode start. Every perturbation keeps a stream's length, so
the windows are cut again, at the same starts, from the perturbed episode streams (never rolled inside a
window: what a shift brings into a window comes from the stream beside it).

- offset (ms): the IMU stream is delayed by d relative to the audio: an IMU event at t appears at t + d
  (negative: earlier). A whole number of IMU samples (every default) is an exact integer shift.
- drift (ppm): the IMU time axis is stretched about the episode start by (1 + p 1e-6): an IMU event at t
  appears at t (1 + p 1e-6), so the misalignment grows with time in the episode (t p 1e-6).
- jitter (ms rms): every IMU sample keeps its value but gets a time stamp off by N(0, s^2); the consumer
  puts the samples back on the nominal grid by linear interpolation through the stamped samples (in
  stamp order).
- imu-drop (%): every IMU sample (all channels of it: one packet) is lost independently with that
  probability and the consumer holds the last sample received (the first received one before any).
- audio-gap (ms per s): in every second of the audio, one span of that length at a uniformly drawn place is
  zeroed (both channels); over an episode of n samples exactly round(n g / 1000) samples are zeroed.
- audio-missing, imu-missing (%): that modality's whole stream reads zero; 100 is the only non-zero severity.

Off-grid values (fractional offsets, drift) are read by band-limited interpolation (a Kaiser-windowed sinc of
`SINC_HALF` taps a side, weights normalised to unit DC gain); a position on the grid is copied exactly and a
position outside the recording reads its mirror image about the end sample (`mirror`: a shift or a negative
drift needs samples past the episode's end, which the recording does not hold; mirrored data keeps the
signal's local statistics, where holding the end sample would add a flat stretch a detector may flag; how
many test windows this touches is reported). A severity of 0 returns the streams unchanged, bit for bit.
"""

from __future__ import annotations

import math
import struct
import zlib
from dataclasses import dataclass

import numpy as np

from benchmarks.errors import UserError

SINC_HALF = 16
"""Taps on each side of the band-limited interpolator."""
SINC_BETA = 8.0
"""Kaiser window shape of the interpolator (sidelobes about -80 dB)."""


@dataclass(frozen=True)
class KindSpec:
    """One kind of perturbation: its unit, default severities and allowed range."""

    name: str
    """Name on the command line and in the outputs."""
    unit: str
    """Unit of the severity."""
    severities: tuple[float, ...]
    """Default severities, in plot order."""
    low: float
    """Smallest allowed severity."""
    high: float
    """Largest allowed severity."""
    modality: str
    """Stream it changes: `imu` or `audio`."""
    description: str
    """One line: what a severity s does."""


KINDS: dict[str, KindSpec] = {
    k.name: k
    for k in (
        KindSpec("offset", "ms", (-200.0, -50.0, -10.0, 10.0, 50.0, 200.0), -1000.0, 1000.0, "imu",
                 "IMU stream delayed by s ms relative to the audio (negative: IMU early)"),
        KindSpec("drift", "ppm", (100.0, 500.0, 2000.0), -100000.0, 100000.0, "imu",
                 "IMU time stretched by (1 + s 1e-6) about the episode start: misalignment t s 1e-6"),
        KindSpec("jitter", "ms rms", (0.1, 0.5, 2.0), 0.0, 10.0, "imu",
                 "IMU time stamps off by N(0, s^2) ms, linearly resampled to the nominal 200 Hz grid"),
        KindSpec("imu-drop", "%", (1.0, 5.0, 20.0), 0.0, 99.0, "imu",
                 "each IMU sample lost with probability s %, the last received sample held"),
        KindSpec("audio-gap", "ms per s", (10.0, 50.0, 200.0), 0.0, 1000.0, "audio",
                 "one zeroed span of s ms in every second of audio, at a random place"),
        KindSpec("audio-missing", "%", (100.0,), 0.0, 100.0, "audio",
                 "the whole audio stream reads zero (severity 100 only)"),
        KindSpec("imu-missing", "%", (100.0,), 0.0, 100.0, "imu",
                 "the whole IMU stream (z velocity and the 6 axes) reads zero (severity 100 only)"),
    )
}  # fmt: skip
"""Every perturbation kind, by name, in report order."""


@dataclass(frozen=True)
class Perturbation:
    """One kind at one severity; checked on construction."""

    kind: str
    """A name of `KINDS`."""
    severity: float
    """In the kind's unit."""

    def __post_init__(self) -> None:
        spec = KINDS.get(self.kind)
        if spec is None:
            raise UserError(f"--perturbations: kind = {self.kind!r} is unknown; allowed: {', '.join(KINDS)}")
        s = self.severity
        if not (isinstance(s, int | float) and math.isfinite(s) and spec.low <= s <= spec.high):
            raise UserError(
                f"--perturbations {self.kind}: severity = {s!r} is invalid; allowed: {spec.low:g} to "
                f"{spec.high:g} {spec.unit}"
            )
        if self.kind.endswith("-missing") and s not in (0.0, 100.0):
            raise UserError(
                f"--perturbations {self.kind}: severity = {s!r} is invalid; allowed: 0 or 100 {spec.unit}"
            )

    @property
    def spec(self) -> KindSpec:
        """The kind's description."""
        return KINDS[self.kind]

    @property
    def label(self) -> str:
        """Severity with its unit, e.g. `-50 ms`."""
        return f"{self.severity:g} {self.spec.unit}"


def rng_for(seed: int, perturbation: Perturbation, episode_index: int) -> np.random.Generator:
    """The generator of one perturbation of one episode, seeded by (seed, kind, severity, episode index).

    The kind enters as its CRC-32 and the severity as the 64 bits of its float, so every (kind, severity)
    draws independently and the same inputs always give the same draws, on any machine.
    """
    severity_bits = int.from_bytes(struct.pack("<d", float(perturbation.severity)), "little")
    kind_code = zlib.crc32(perturbation.kind.encode())
    return np.random.default_rng(np.random.SeedSequence([seed, kind_code, severity_bits, episode_index]))


@dataclass(frozen=True)
class Streams:
    """One episode's continuous streams, as windows are cut from them."""

    audio: np.ndarray
    """(n, 2) float32 audio at 4410 Hz (decimated)."""
    imu: np.ndarray
    """(m,) float32 IMU z-axis velocity at 200 Hz."""
    imu6: np.ndarray
    """(m, 6) float32 accelerometer and gyro at 200 Hz."""


# --- resampling -------------------------------------------------------------------------------------------


def resample_at(x: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """`x` (along axis 0) read at fractional sample `positions`, band-limited; same dtype as `x`.

    Positions (and the interpolator's taps) outside [0, len(x) - 1] are mirrored into it (`mirror`); a
    whole-number position returns that sample exactly.
    """
    arr = np.asarray(x)
    n = arr.shape[0]
    pos = mirror(np.asarray(positions, dtype=np.float64), n)
    base = np.floor(pos)
    frac = pos - base
    taps = np.arange(-SINC_HALF + 1, SINC_HALF + 1)
    index = mirror(base.astype(np.int64)[:, None] + taps[None, :], n)
    u = frac[:, None] - taps[None, :]
    window = np.i0(SINC_BETA * np.sqrt(np.clip(1.0 - (u / SINC_HALF) ** 2, 0.0, None))) / np.i0(SINC_BETA)
    weights = np.sinc(u) * window
    weights /= weights.sum(axis=1, keepdims=True)
    flat = arr.reshape(n, -1).astype(np.float64)
    out = np.einsum("kt,ktc->kc", weights, flat[index])
    exact = frac == 0.0
    out[exact] = flat[base[exact].astype(np.int64)]
    return out.reshape(pos.shape + arr.shape[1:]).astype(arr.dtype)


def mirror(positions: np.ndarray, n: int) -> np.ndarray:
    """Sample positions folded into [0, n - 1] by reflection about the end samples (-1 -> 1, n -> n - 2)."""
    if n < 2:
        return np.zeros_like(positions)
    period = 2 * (n - 1)
    folded = np.mod(positions, period)
    return np.where(folded > n - 1, period - folded, folded)


def outside(positions: np.ndarray, n: int) -> np.ndarray:
    """Which positions lie outside the recording's [0, n - 1] samples."""
    return (positions < 0) | (positions > n - 1)


def warp_positions(n: int, rate: float, offset_s: float = 0.0, ppm: float = 0.0) -> np.ndarray:
    """Where output sample k reads the input: an input event at t lands at t (1 + ppm 1e-6) + offset_s."""
    t = np.arange(n) / rate
    return (t - offset_s) / (1.0 + ppm * 1e-6) * rate


def shift(x: np.ndarray, rate: float, offset_ms: float) -> np.ndarray:
    """`x` delayed by `offset_ms` (an event at t moves to t + offset); exact for whole samples."""
    if offset_ms == 0:
        return x
    steps = offset_ms * 1e-3 * rate
    if steps == round(steps):
        index = mirror(np.arange(x.shape[0]) - round(steps), x.shape[0])
        return x[index]
    return resample_at(x, warp_positions(x.shape[0], rate, offset_s=offset_ms * 1e-3))


def drift(x: np.ndarray, rate: float, ppm: float) -> np.ndarray:
    """`x` with its time axis stretched by (1 + ppm 1e-6) about sample 0 (band-limited)."""
    if ppm == 0:
        return x
    return resample_at(x, warp_positions(x.shape[0], rate, ppm=ppm))


def jittered_stamps(n: int, rate: float, sigma_ms: float, rng: np.random.Generator) -> np.ndarray:
    """(n,) time stamps, s, of samples taken on the nominal grid: k / rate + N(0, sigma^2)."""
    return np.arange(n) / rate + rng.normal(0.0, sigma_ms * 1e-3, size=n)


def regrid(x: np.ndarray, stamps: np.ndarray, rate: float) -> np.ndarray:
    """`x`, whose samples carry time `stamps`, linearly interpolated onto the grid k / rate (edges held)."""
    order = np.argsort(stamps, kind="stable")
    s = stamps[order]
    grid = np.arange(x.shape[0]) / rate
    flat = np.asarray(x).reshape(x.shape[0], -1)[order].astype(np.float64)
    out = np.stack([np.interp(grid, s, flat[:, c]) for c in range(flat.shape[1])], axis=1)
    return out.reshape(x.shape).astype(x.dtype)


def drop_mask(n: int, percent: float, rng: np.random.Generator) -> np.ndarray:
    """(n,) bool: each sample lost independently with probability `percent` / 100."""
    return rng.random(n) < percent / 100.0


def hold_last(x: np.ndarray, dropped: np.ndarray) -> np.ndarray:
    """`x` with every dropped sample replaced by the last kept one (the first kept one before any kept)."""
    kept = np.flatnonzero(~dropped)
    if kept.size == 0:
        return np.zeros_like(x)
    if kept.size == x.shape[0]:
        return x
    source = np.maximum.accumulate(np.where(dropped, -1, np.arange(x.shape[0])))
    source[source < 0] = kept[0]
    return x[source]


def gap_mask(n: int, rate: float, ms_per_s: float, rng: np.random.Generator) -> np.ndarray:
    """(n,) bool: one zeroed span per second of the stream, exactly round(n * ms_per_s / 1000) in all.

    Second b covers samples [b L, min((b + 1) L, n)) with L = round(rate); its span has
    round(f end) - round(f start) samples (f = ms_per_s / 1000, rounding half up), at a uniform place.
    """
    fraction = ms_per_s / 1000.0
    block = round(rate)
    mask = np.zeros(n, dtype=bool)

    def count(i: int) -> int:
        return math.floor(fraction * i + 0.5)

    for start in range(0, n, block):
        end = min(start + block, n)
        length = count(end) - count(start)
        if length <= 0:
            continue
        at = start + int(rng.integers(0, end - start - length + 1))
        mask[at : at + length] = True
    return mask


# --- one episode --------------------------------------------------------------------------------------------


def reads_outside(perturbation: Perturbation, m: int, imu_rate: float) -> np.ndarray:
    """(m,) bool: the IMU samples that `perturbation` reads from outside the recording (mirrored data)."""
    s = float(perturbation.severity)
    if perturbation.kind == "offset":
        return outside(warp_positions(m, imu_rate, offset_s=s * 1e-3), m)
    if perturbation.kind == "drift":
        return outside(warp_positions(m, imu_rate, ppm=s), m)
    return np.zeros(m, dtype=bool)


def apply(
    streams: Streams, perturbation: Perturbation, rng: np.random.Generator, audio_rate: float, imu_rate: float
) -> Streams:
    """The episode's streams under `perturbation` (the inputs untouched; severity 0: the same arrays)."""
    kind, s = perturbation.kind, float(perturbation.severity)
    if s == 0:
        return streams
    audio, imu, imu6 = streams.audio, streams.imu, streams.imu6
    if kind == "offset":
        return Streams(audio, shift(imu, imu_rate, s), shift(imu6, imu_rate, s))
    if kind == "drift":
        return Streams(audio, drift(imu, imu_rate, s), drift(imu6, imu_rate, s))
    if kind == "jitter":
        stamps = jittered_stamps(imu.shape[0], imu_rate, s, rng)
        return Streams(audio, regrid(imu, stamps, imu_rate), regrid(imu6, stamps, imu_rate))
    if kind == "imu-drop":
        dropped = drop_mask(imu.shape[0], s, rng)
        return Streams(audio, hold_last(imu, dropped), hold_last(imu6, dropped))
    if kind == "audio-gap":
        gaps = gap_mask(audio.shape[0], audio_rate, s, rng)
        return Streams(np.where(gaps[:, None], np.float32(0.0), audio).astype(audio.dtype), imu, imu6)
    if kind == "audio-missing":
        return Streams(np.zeros_like(audio), imu, imu6)
    if kind == "imu-missing":
        return Streams(audio, np.zeros_like(imu), np.zeros_like(imu6))
    raise AssertionError(f"unhandled perturbation kind {kind!r}")  # Perturbation refuses unknown kinds
