"""A recording's time-stamped streams laid out on sample grids by the streaming scorer's policy.

A stream (audio chunks, IMU samples, joint states) arrives as messages in the order the recorder received
them, each timed by the time of its first sample (a header stamp), or untimed (an unstamped audio chunk, which
follows straight on). `assemble` places every message with `msvdd.stream.GapPolicy.place`, the rule the
streaming scorer applies live, so an import and a deployed scorer treat the same stamps alike:

- within the policy's jitter of where the stream ends: contiguous (nothing counted);
- a gap up to the policy's longest fill: filled, audio with zeros, the other streams holding their last
  sample (counted: `gaps_filled`, `samples_filled`);
- a longer gap (a reset): filled the same way but no window may overlap it (counted: `resets`; the dataset
  writer counts the windows left out). A gap over `MAX_GAP_S` is refused: split the bag there;
- timed before the stream's end (a duplicate, a late or out-of-order message): its samples timed before the
  end are dropped (counted: `messages_dropped` for a message dropped whole, `samples_dropped`).

A stream's rate is its declared one (audio: `AudioInfo`) or, for one sample a message, what its stamps show,
rounded to a whole hertz (`nominal_rate`); what the rounding leaves is timing the policy absorbs.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from benchmarks.importers.config import SourceError
from benchmarks.importers.signals import resample_to_grid
from msvdd.contract import IMU_RATE
from msvdd.stream import GapPolicy

MAX_GAP_S = 60.0
"""Longest gap a recording may hold (stored filled and left out of every window); a longer one is refused."""

Span = tuple[float, float]
"""[start, end) on a recording's clock, s."""


@dataclass
class StreamCount:
    """What laying out one stream met."""

    messages: int = 0
    """Non-empty messages read."""
    gaps_filled: int = 0
    """Gaps filled (longer than the policy's jitter, at most its longest fill)."""
    samples_filled: int = 0
    """Samples filled in those gaps (at the stream's rate)."""
    resets: int = 0
    """Gaps longer than the policy fills: stored, and no window overlaps them."""
    messages_dropped: int = 0
    """Messages dropped whole: every sample timed before the stream's end (duplicates, late messages)."""
    samples_dropped: int = 0
    """Samples dropped as timed before the stream's end (whole messages and overlapping heads)."""


@dataclass(frozen=True)
class Series:
    """One stream on its own sample grid: sample i at `start_s + i / rate`."""

    start_s: float
    """Time of sample 0, s on the recording's clock."""
    rate: float
    """Sample rate, Hz."""
    values: np.ndarray
    """(n, ...) samples, fills included."""
    filled: tuple[tuple[int, int], ...]
    """Sample ranges [lo, hi) filled in short gaps."""
    resets: tuple[tuple[int, int], ...]
    """Sample ranges [lo, hi) filled in gaps longer than the policy fills."""
    count: StreamCount
    """What laying it out met."""

    @property
    def end_s(self) -> float:
        """Time one past its last sample, s."""
        return self.start_s + self.values.shape[0] / self.rate

    def spans(self, ranges: tuple[tuple[int, int], ...], t0: float) -> list[Span]:
        """Sample ranges as [start, end) seconds from `t0`."""
        return [(self.start_s + lo / self.rate - t0, self.start_s + hi / self.rate - t0) for lo, hi in ranges]


@dataclass(frozen=True)
class StreamReport:
    """What laying out a recording's streams met, for its windows and the dataset's manifest."""

    counts: dict[str, StreamCount]
    """Per stream (`imu`, `audio`, ...)."""
    filled_s: tuple[Span, ...] = ()
    """Spans holding filled samples, s of the episode."""
    reset_s: tuple[Span, ...] = ()
    """Spans no window may overlap (resets), s of the episode."""


def nominal_rate(stamps_s: np.ndarray, where: str) -> float:
    """A one-sample-a-message stream's rate, to a whole hertz: the sample periods between its distinct stamps
    (each step in whole median steps, so that gaps count) over the time they span.

    Raises:
        SourceError: fewer than two distinct stamps.
    """
    t = np.unique(np.asarray(stamps_s, dtype=np.float64))
    if t.size < 2:
        raise SourceError(f"{where}: fewer than two distinct time stamps; allowed: a stream of samples")
    steps = np.diff(t)
    periods = np.rint(steps / float(np.median(steps))).sum()
    return float(max(1, round(periods / (t[-1] - t[0]))))


def assemble(
    chunks: Iterable[tuple[float | None, np.ndarray]], rate: float, policy: GapPolicy, hold: bool, where: str
) -> Series:
    """Lay out a stream's messages (time of the first sample or None, (k, ...) samples) in arrival order.

    Args:
        chunks: the messages; the first non-empty one must be timed.
        rate: the stream's sample rate, Hz.
        policy: the gap policy (`msvdd.stream.GapPolicy`).
        hold: fill gaps by holding the last sample (else zeros: audio).
        where: the bag and topic, for messages.

    Raises:
        SourceError: no samples, an untimed first message, or a gap longer than `MAX_GAP_S`.
    """
    parts: list[np.ndarray] = []
    filled: list[tuple[int, int]] = []
    resets: list[tuple[int, int]] = []
    count = StreamCount()
    start: float | None = None
    end = 0
    last: np.ndarray | None = None
    for t, samples in chunks:
        x = np.asarray(samples, dtype=np.float64)
        n = x.shape[0]
        if n == 0:
            continue
        count.messages += 1
        if start is None:
            if t is None:
                raise SourceError(f"{where}: its first message has no time; allowed: a timed first message")
            start = t
        place = policy.place(None if t is None else (t - start) - end / rate, n, rate)
        if place.dropped:
            count.samples_dropped += place.dropped
            count.messages_dropped += int(place.dropped == n)
            x = x[place.dropped :]
        gap = place.filled or place.reset
        if gap:
            if gap > MAX_GAP_S * rate:
                raise SourceError(
                    f"{where}: a gap of {gap / rate:.1f} s at {end / rate:.3f} s of the stream; allowed: "
                    f"gaps up to {MAX_GAP_S:g} s (split the bag there, e.g. with `mcap filter`)"
                )
            held = last if hold and last is not None else np.zeros(x.shape[1:])
            parts.append(np.broadcast_to(held, (gap, *x.shape[1:])))
            (filled if place.filled else resets).append((end, end + gap))
            count.gaps_filled += int(bool(place.filled))
            count.samples_filled += place.filled
            count.resets += int(bool(place.reset))
            end += gap
        if x.shape[0]:
            parts.append(x)
            end += x.shape[0]
            last = x[-1]
    if start is None:
        raise SourceError(f"{where}: no samples")
    return Series(start, rate, np.concatenate(parts), tuple(filled), tuple(resets), count)


def on_imu_grid(series: Series, t0: float, n: int) -> np.ndarray:
    """(n, ...) samples of `series` at t0 + k / 200 Hz: taken as they are when the stream runs at 200 Hz
    (shifted by whole samples), else resampled (`benchmarks.importers.signals.resample_to_grid`)."""
    values = series.values.reshape(series.values.shape[0], -1)
    if series.rate == IMU_RATE:
        i0 = round((t0 - series.start_s) * IMU_RATE)
        idx = np.clip(np.arange(i0, i0 + n), 0, values.shape[0] - 1)
        out = values[idx]
    else:
        times = series.start_s + np.arange(values.shape[0]) / series.rate
        out = resample_to_grid(times, values, t0 + np.arange(n) / IMU_RATE, series.rate)
    return out.reshape(n, *series.values.shape[1:])


def common_span(series: list[Series], imu: Series) -> tuple[float, int]:
    """(t0, n): the episode every stream covers, on the IMU's grid where it runs at 200 Hz.

    t0 is the first IMU sample at or after every stream's start (the latest start where the IMU is resampled),
    and n the 200 Hz samples from t0 until the first stream ends.
    """
    latest = max(s.start_s for s in series)
    if imu.rate == IMU_RATE:
        t0 = imu.start_s + math.ceil((latest - imu.start_s) * IMU_RATE - 1e-6) / IMU_RATE
    else:
        t0 = latest
    end = min(s.end_s for s in series)
    return t0, max(0, math.floor((end - t0) * IMU_RATE + 1e-6))
