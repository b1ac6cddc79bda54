"""Streaming scoring: raw 44.1 kHz audio and 200 Hz IMU chunks in, one score per hop out.

The scorer decimates incrementally with exactly the filter of `msvdd.preprocess.decimate_audio` (each output
sample is one dot product of the 401 taps with the raw samples around it): output sample q is computed once
input samples up to 10 q + 200 have arrived (the centred FIR's look-ahead), so a window's audio equals what
batch decimation of the whole recording gives (away from the recording's end, where batch decimation
zero-pads). Windows start on the grid t_k = start_s + k hop_s; a window is scored as soon as its audio and IMU
are complete. Buffers are trimmed as windows are emitted. A model that reads all IMU axes
(`imu_input="all"`) needs the (j, 6) accelerometer and gyroscope chunk with every IMU chunk.

Backends: anything with `score(Windows) -> np.ndarray`, such as `msvdd.model.MSVDD` (torch) or
`msvdd.onnx_backend.OnnxScorer` (ONNX Runtime, one thread); the scores are the backend's.

Timestamps, gaps and late chunks (`GapPolicy`). Audio and IMU are two streams, each with its own clock
position: the index one past its last sample. `push` may give each chunk's start time (`audio_t`, `imu_t`,
seconds on the caller's clock, whose sample 0 is at `start_s`); a chunk without one follows straight on from
the previous chunk of its stream (the behaviour without timestamps). For a timed chunk, the offset from
where its stream ended is:

- within `jitter_s` (either side): contiguous; the timestamp's jitter is ignored and nothing is counted.
- a gap of up to `max_fill_s`: filled in, audio with zeros (silence; a held value would be a DC step the
  anti-alias filter rings on), the IMU by holding its last sample (at the very start, the chunk's first);
  counted (`audio_gaps_filled`, `audio_samples_filled`, ...), and every emitted window that contains a
  filled sample is counted in `windows_with_fill`.
- a longer gap: a reset. The stream restarts at the chunk's time T as a new recording would (the audio
  filter zero-padded before T), the other stream's samples before T are discarded, and no window starting
  before T is scored (counted in `windows_skipped`): the next score is that of the first grid window that
  starts at or after T, emitted once all of it (and the filter's look-ahead) has arrived. Counted in `resets`
  (once per stream with such a gap). A first chunk timed more than `max_fill_s` after `start_s` is one too.
- earlier than the stream's end (a duplicate, an out-of-order or an overlapping chunk): the samples timed
  before the stream's end are dropped (a stream never goes back in time); the rest of the chunk, if any,
  is appended. A chunk dropped whole counts in `audio_chunks_dropped` / `imu_chunks_dropped`, every
  dropped sample in `audio_samples_dropped` / `imu_samples_dropped`. So a chunk that arrives after a later
  one is dropped, the hole it leaves having been handled as a gap when the later chunk came. A device clock
  that drifts against the timestamps shows as occasional short fills or drops once the drift passes
  `jitter_s`.

Empty chunks change nothing (their timestamps are ignored). `counters` returns a `StreamCounters` snapshot.
`GapPolicy.place` is the rule itself; `msvdd-bench import --layout ros2` lays out a bag's streams with it.
Memory stays bounded as long as neither stream runs far ahead of the other.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from msvdd.contract import AUDIO_LEN, AUDIO_RATE, IMU_LEN, IMU_RATE, WindowError, Windows
from msvdd.preprocess import DECIMATION, FIR_HALF, FIR_TAPS, RAW_AUDIO_RATE

_TAPS_REVERSED = np.ascontiguousarray(FIR_TAPS[::-1])


class WindowScorer(Protocol):
    """A scoring backend: `MSVDD` or `OnnxScorer` (or anything with the same `score`)."""

    def score(self, batch: Windows) -> np.ndarray:
        """(N,) anomaly scores of a window batch."""
        ...


def backend_imu_input(scorer: object) -> str:
    """The IMU input ("z" or "all") a backend reads: `config.imu_input` (MSVDD), else `imu_input`, or "z"."""
    config = getattr(scorer, "config", None)
    value = getattr(config, "imu_input", None) if config is not None else getattr(scorer, "imu_input", None)
    return "z" if value is None else str(value)


@dataclass(frozen=True)
class GapPolicy:
    """How `StreamingScorer` treats chunk timestamps that do not follow on from their stream's end."""

    jitter_s: float = 0.002
    """Offsets up to this (either way) are timestamp jitter: the chunk is taken as contiguous."""
    max_fill_s: float = 0.1
    """Longest gap filled in (audio with zeros, IMU by holding its last sample); longer gaps reset."""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.jitter_s) and self.jitter_s >= 0):
            raise ValueError(f"GapPolicy.jitter_s = {self.jitter_s!r}; allowed: a finite value >= 0 s")
        if not (math.isfinite(self.max_fill_s) and self.max_fill_s >= self.jitter_s):
            raise ValueError(
                f"GapPolicy.max_fill_s = {self.max_fill_s!r}; allowed: finite and >= jitter_s "
                f"({self.jitter_s})"
            )

    def place(self, offset_s: float | None, n: int, rate: float) -> Placement:
        """Where a chunk of `n` samples at `rate` Hz goes, timed `offset_s` seconds after its stream's end
        (None: untimed, straight on); the module doc's rule, for the scorer and for `msvdd-bench import`."""
        if offset_s is None:
            return Placement()
        gap = 0 if abs(offset_s) <= self.jitter_s else round(offset_s * rate)
        if gap < 0:
            return Placement(dropped=min(-gap, n))
        if gap > round(self.max_fill_s * rate):
            return Placement(reset=gap)
        return Placement(filled=gap)


@dataclass(frozen=True)
class Placement:
    """Where `GapPolicy.place` puts a timed chunk; at most one field is non-zero."""

    dropped: int = 0
    """Leading samples dropped: timed before the stream's end (a duplicate, late or overlapping chunk)."""
    filled: int = 0
    """Samples filled in before the chunk: a gap longer than `jitter_s`, at most `max_fill_s`."""
    reset: int = 0
    """Samples between the stream's end and the chunk when the gap is longer than `max_fill_s` (a reset)."""


@dataclass
class StreamCounters:
    """What a `StreamingScorer` has received, filled, dropped and emitted so far."""

    windows_emitted: int = 0
    """Windows scored."""
    windows_skipped: int = 0
    """Grid windows never scored because a reset discarded some of their samples."""
    windows_with_fill: int = 0
    """Scored windows holding at least one filled-in audio or IMU sample."""
    audio_chunks: int = 0
    """Non-empty audio chunks pushed."""
    imu_chunks: int = 0
    """Non-empty IMU chunks pushed."""
    audio_gaps_filled: int = 0
    """Audio gaps filled with zeros (longer than `jitter_s`, at most `max_fill_s`)."""
    imu_gaps_filled: int = 0
    """IMU gaps filled by holding the last sample."""
    audio_samples_filled: int = 0
    """44.1 kHz audio samples filled in."""
    imu_samples_filled: int = 0
    """200 Hz IMU samples filled in."""
    resets: int = 0
    """Gaps longer than `max_fill_s`, one per stream that had one (a gap in both streams counts twice)."""
    audio_chunks_dropped: int = 0
    """Audio chunks dropped whole: every sample timed before the stream's end (duplicate, out of order)."""
    imu_chunks_dropped: int = 0
    """IMU chunks dropped whole, likewise."""
    audio_samples_dropped: int = 0
    """44.1 kHz samples dropped as late (whole chunks and the overlapping heads of others)."""
    imu_samples_dropped: int = 0
    """200 Hz IMU samples dropped as late."""


def _overlaps(spans: list[tuple[int, int]], lo: int, hi: int) -> bool:
    return any(a < hi and lo < b for a, b in spans)


class StreamingScorer:
    """Scores a live recording window by window (2 s windows every `hop_s` seconds); see the module doc."""

    def __init__(
        self,
        model: WindowScorer,
        hop_s: float = 0.5,
        policy: GapPolicy | None = None,
        start_s: float = 0.0,
    ) -> None:
        if not hop_s > 0:
            raise ValueError(f"hop_s {hop_s}; allowed: > 0 seconds")
        if not math.isfinite(start_s):
            raise ValueError(f"start_s {start_s}; allowed: a finite time in seconds")
        self.model = model
        self.hop_s = float(hop_s)
        self.policy = policy or GapPolicy()
        self.start_s = float(start_s)
        self._needs6 = backend_imu_input(model) == "all"
        self._counters = StreamCounters()
        # Audio: raw 44.1 kHz samples not yet consumed by the decimator (preceded at a start by the FIR's zero
        # padding), and the decimated samples still needed. Indices are global sample indices from start_s.
        self._raw = np.zeros((0, 2))
        self._raw0 = 0
        self._dec = np.zeros((0, 2), dtype=np.float32)
        self._dec0 = 0
        self._audio_end = 0
        """Global 44.1 kHz index one past the last audio sample received (or filled in)."""
        self._restart_audio(0)
        self._imu = np.zeros(0, dtype=np.float32)
        self._imu6 = np.zeros((0, 6), dtype=np.float32)
        self._imu0 = 0
        self._imu_last: tuple[np.float32, np.ndarray] | None = None
        self._fills_audio: list[tuple[int, int]] = []
        """Filled-in 44.1 kHz index ranges [lo, hi) not yet behind every future window."""
        self._fills_imu: list[tuple[int, int]] = []
        self._next = 0
        """Grid index k of the next window to consider."""

    @property
    def n_emitted(self) -> int:
        """Windows scored so far."""
        return self._counters.windows_emitted

    @property
    def counters(self) -> StreamCounters:
        """A snapshot of the counters (see `StreamCounters`)."""
        return dataclasses.replace(self._counters)

    # ---------------------------------------------------------------- input

    def push(
        self,
        audio44k_chunk: np.ndarray,
        imu_z_chunk: np.ndarray,
        imu6_chunk: np.ndarray | None = None,
        *,
        audio_t: float | None = None,
        imu_t: float | None = None,
    ) -> list[tuple[float, float]]:
        """Append (k, 2) 44.1 kHz audio, (j,) 200 Hz IMU z-velocity and, for a model that reads all IMU axes,
        (j, 6) accelerometer and gyroscope xyz; -> [(window_start_s, score), ...].

        `audio_t` and `imu_t` are the times of the chunks' first samples (s, the caller's clock); None means
        right after the previous chunk of that stream. Gaps, duplicates and out-of-order chunks follow the
        module doc's policy.

        Raises:
            WindowError: wrong shapes, NaN/inf samples or timestamps, or a missing imu6 chunk the model needs.
        """
        a = np.asarray(audio44k_chunk, dtype=np.float64)
        i = np.asarray(imu_z_chunk, dtype=np.float32)
        if a.ndim != 2 or a.shape[1] != 2:
            raise WindowError(f"audio chunk shape {a.shape}; expected (k, 2) at 44100 Hz")
        if i.ndim != 1:
            raise WindowError(f"imu chunk shape {i.shape}; expected (j,) at {IMU_RATE} Hz")
        if self._needs6 and imu6_chunk is None and i.shape[0] > 0:
            raise WindowError('the model reads all IMU axes (imu_input "all"): push an imu6 chunk (j, 6) too')
        i6 = (
            np.zeros((i.shape[0], 6), np.float32)
            if imu6_chunk is None
            else np.asarray(imu6_chunk, np.float32)
        )
        if i6.shape != (i.shape[0], 6):
            raise WindowError(f"imu6 chunk shape {i6.shape}; expected ({i.shape[0]}, 6), aligned with imu")
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(i)) and np.all(np.isfinite(i6))):
            raise WindowError("stream chunk holds NaN or inf")
        for name, value in (("audio_t", audio_t), ("imu_t", imu_t)):
            if value is not None and not math.isfinite(value):
                raise WindowError(f"{name} = {value!r}; allowed: a finite time in seconds")
        if a.shape[0]:
            self._push_audio(a, audio_t)
        if i.shape[0]:
            self._push_imu(i, i6, imu_t)
        scores = self._emit()
        self._trim()
        return scores

    def _place(self, t: float | None, end: int, n: int, rate: float) -> Placement:
        """Where a chunk of n samples timed t goes in a stream ending at sample `end` (the policy's rule)."""
        return self.policy.place(None if t is None else (t - self.start_s) - end / rate, n, rate)

    def _push_audio(self, a: np.ndarray, t: float | None) -> None:
        c = self._counters
        c.audio_chunks += 1
        place = self._place(t, self._audio_end, a.shape[0], RAW_AUDIO_RATE)
        gap = place.filled
        if place.dropped:
            late = place.dropped
            c.audio_samples_dropped += late
            c.audio_chunks_dropped += int(late == a.shape[0])
            a = a[late:]
        elif place.reset:
            c.resets += 1
            self._restart_audio(self._audio_end + place.reset)
        elif gap > 0:
            c.audio_gaps_filled += 1
            c.audio_samples_filled += gap
            self._fills_audio.append((self._audio_end, self._audio_end + gap))
            a = np.concatenate([np.zeros((gap, 2)), a])
        if a.shape[0]:
            self._raw = np.concatenate([self._raw, a])
            self._audio_end += a.shape[0]
            self._decimate_ready()

    def _push_imu(self, i: np.ndarray, i6: np.ndarray, t: float | None) -> None:
        c = self._counters
        c.imu_chunks += 1
        end = self._imu0 + self._imu.shape[0]
        place = self._place(t, end, i.shape[0], IMU_RATE)
        gap = place.filled
        if place.dropped:
            late = place.dropped
            c.imu_samples_dropped += late
            c.imu_chunks_dropped += int(late == i.shape[0])
            i, i6 = i[late:], i6[late:]
        elif place.reset:
            c.resets += 1
            self._imu = np.zeros(0, dtype=np.float32)
            self._imu6 = np.zeros((0, 6), dtype=np.float32)
            self._imu0 = end + place.reset
        elif gap > 0:
            c.imu_gaps_filled += 1
            c.imu_samples_filled += gap
            self._fills_imu.append((end, end + gap))
            last, last6 = self._imu_last if self._imu_last is not None else (i[0], i6[0])
            i = np.concatenate([np.full(gap, last, dtype=np.float32), i])
            i6 = np.concatenate([np.tile(last6, (gap, 1)), i6])
        if i.shape[0]:
            self._imu = np.concatenate([self._imu, i])
            self._imu6 = np.concatenate([self._imu6, i6])
            self._imu_last = (i[-1], i6[-1].copy())

    # ---------------------------------------------------------------- audio decimation

    def _restart_audio(self, first: int) -> None:
        """Start the decimator afresh at global 44.1 kHz index `first`, zero input before it."""
        q0 = -(-first // DECIMATION)
        self._dec = np.zeros((0, 2), dtype=np.float32)
        self._dec0 = q0
        self._raw0 = DECIMATION * q0 - FIR_HALF
        self._raw = np.zeros((first - self._raw0, 2))
        self._audio_end = first

    def _decimate_ready(self) -> None:
        n_dec = self._dec0 + self._dec.shape[0]
        raw_end = self._raw0 + self._raw.shape[0]
        q_last = (raw_end - 1 - FIR_HALF) // DECIMATION
        if q_last < n_dec:
            return
        start = DECIMATION * n_dec - FIR_HALF - self._raw0
        stop = DECIMATION * q_last + FIR_HALF + 1 - self._raw0
        # output q = sum_j h[j] x[10 q + 200 - j]: the reversed taps dotted with raw[10 q - 200 : 10 q + 201],
        # each channel; the frames are a strided view of the raw samples (every 10th of the sliding windows)
        raw = np.ascontiguousarray(self._raw[start:stop])
        row, col = raw.strides
        frames = np.lib.stride_tricks.as_strided(
            raw, (q_last + 1 - n_dec, 2, FIR_TAPS.size), (DECIMATION * row, col, row), writeable=False
        )
        new = (frames @ _TAPS_REVERSED).astype(np.float32)
        self._dec = np.concatenate([self._dec, new])
        keep_from = DECIMATION * (q_last + 1) - FIR_HALF - self._raw0
        self._raw = self._raw[keep_from:]
        self._raw0 += keep_from

    # ---------------------------------------------------------------- output

    def _starts(self, k: int) -> tuple[int, int]:
        """(audio 4410 Hz, IMU 200 Hz) global start indices of grid window k."""
        t = k * self.hop_s
        return round(t * AUDIO_RATE), round(t * IMU_RATE)

    def _first_complete_possible(self, k: int) -> int:
        """The first grid index >= k whose window starts at or after both buffers' starts (after a reset,
        earlier windows miss samples for good; otherwise k itself)."""
        t_min = max(self._dec0 / AUDIO_RATE, self._imu0 / IMU_RATE)
        k = max(k, math.floor(t_min / self.hop_s) - 1)
        while True:
            a0, i0 = self._starts(k)
            if a0 >= self._dec0 and i0 >= self._imu0:
                return k
            k += 1

    def _emit(self) -> list[tuple[float, float]]:
        dec_end = self._dec0 + self._dec.shape[0]
        imu_end = self._imu0 + self._imu.shape[0]
        ks: list[int] = []
        k = self._first_complete_possible(self._next)
        self._counters.windows_skipped += k - self._next
        while True:
            a0, i0 = self._starts(k)
            if a0 + AUDIO_LEN > dec_end or i0 + IMU_LEN > imu_end:
                break
            ks.append(k)
            k += 1
        self._next = k
        if not ks:
            return []
        starts = np.array([self._starts(j) for j in ks])
        if len(ks) == 1:  # the usual case: views of the buffers (never written in place), no gather
            a, i = int(starts[0, 0]) - self._dec0, int(starts[0, 1]) - self._imu0
            audio, imu = self._dec[None, a : a + AUDIO_LEN], self._imu[None, i : i + IMU_LEN]
            windows = Windows(audio=audio, imu=imu, imu6=self._imu6[None, i : i + IMU_LEN])
        else:
            a_idx = (starts[:, 0] - self._dec0)[:, None] + np.arange(AUDIO_LEN)
            i_idx = (starts[:, 1] - self._imu0)[:, None] + np.arange(IMU_LEN)
            windows = Windows(audio=self._dec[a_idx], imu=self._imu[i_idx], imu6=self._imu6[i_idx])
        scores = np.asarray(self.model.score(windows), dtype=np.float64)
        c = self._counters
        c.windows_emitted += len(ks)
        for a0, i0 in starts:
            raw0 = DECIMATION * int(a0) - FIR_HALF  # the filter spreads a raw sample over +-FIR_HALF
            raw1 = DECIMATION * (int(a0) + AUDIO_LEN) + FIR_HALF
            if _overlaps(self._fills_audio, raw0, raw1) or _overlaps(
                self._fills_imu, int(i0), int(i0) + IMU_LEN
            ):
                c.windows_with_fill += 1
        return [(self.start_s + j * self.hop_s, float(s)) for j, s in zip(ks, scores, strict=True)]

    def _trim(self) -> None:
        """Drop what no future window needs: samples before the start of grid window `_next`."""
        a0, i0 = self._starts(self._next)
        drop_a = min(max(a0 - self._dec0, 0), self._dec.shape[0])
        self._dec, self._dec0 = self._dec[drop_a:], self._dec0 + drop_a
        drop_i = min(max(i0 - self._imu0, 0), self._imu.shape[0])
        self._imu, self._imu6, self._imu0 = self._imu[drop_i:], self._imu6[drop_i:], self._imu0 + drop_i
        raw_keep = DECIMATION * a0 - FIR_HALF
        self._fills_audio = [(lo, hi) for lo, hi in self._fills_audio if hi > raw_keep]
        self._fills_imu = [(lo, hi) for lo, hi in self._fills_imu if hi > i0]
