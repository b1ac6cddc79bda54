"""The streaming scorer matches batch decimation, framing and scoring on the same windows, and follows its
stated policy for chunk timestamps: jitter ignored, short gaps filled and counted, long gaps reset, late
(duplicate, out-of-order, overlapping) samples dropped and counted."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from msvdd.config import MSVDDConfig
from msvdd.contract import WindowError, Windows
from msvdd.model import MSVDD
from msvdd.preprocess import decimate_audio, frame_windows
from msvdd.stream import GapPolicy, StreamingScorer


def _signals(rng: np.random.Generator, seconds: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(int(44100 * seconds)) / 44100
    tone = 0.3 * np.sin(2 * np.pi * 90 * t) + 0.05 * rng.standard_normal(t.size)
    n = int(200 * seconds)
    imu = 0.02 * np.sin(2 * np.pi * np.arange(n) / 200) + 0.005 * rng.standard_normal(n)
    imu6 = 0.05 * rng.standard_normal((n, 6)) + np.array([0, 0, 9.81, 0, 0, 0])
    return np.stack([tone, 0.8 * tone], axis=1), imu.astype(np.float32), imu6.astype(np.float32)


def test_streaming_equals_batch_for_log_mel_and_all_imu_axes(toy_train: Windows) -> None:
    model = MSVDD(MSVDDConfig.smoke(epochs=1, audio_frontend="logmel", imu_input="all")).fit(toy_train)
    audio, imu, imu6 = _signals(np.random.default_rng(1), 5.0)
    scorer = StreamingScorer(model, hop_s=0.5)
    with pytest.raises(WindowError, match="imu6 chunk"):
        scorer.push(audio[:100], imu[:1])
    emitted: list[tuple[float, float]] = []
    a_pos = i_pos = 0
    for a_len, i_len in [(30001, 150), (70000, 333), (44100, 200)]:
        sl = slice(i_pos, i_pos + i_len)
        emitted += scorer.push(audio[a_pos : a_pos + a_len], imu[sl], imu6[sl])
        a_pos, i_pos = a_pos + a_len, i_pos + i_len
    emitted += scorer.push(audio[a_pos:], imu[i_pos:], imu6[i_pos:])
    starts = np.array([s for s, _ in emitted])
    assert len(starts) >= 5
    batch = frame_windows(decimate_audio(audio), imu, starts, imu6=imu6)
    np.testing.assert_allclose([s for _, s in emitted], model.score(batch), rtol=1e-5)


def test_streaming_equals_batch(small_model: MSVDD) -> None:
    rng = np.random.default_rng(0)
    seconds = 6.0
    t = np.arange(int(44100 * seconds)) / 44100
    tone = 0.3 * np.sin(2 * np.pi * 90 * t) + 0.05 * rng.standard_normal(t.size)
    audio = np.stack([tone, 0.8 * tone], axis=1)
    imu = 0.02 * np.sin(2 * np.pi * np.arange(int(200 * seconds)) / 200) + 0.005 * rng.standard_normal(1200)
    scorer = StreamingScorer(small_model, hop_s=0.5)
    emitted: list[tuple[float, float]] = []
    a_pos = i_pos = 0
    for a_len, i_len in [(10000, 37), (30001, 150), (44100, 200), (70000, 333), (110000, 480)]:
        emitted += scorer.push(audio[a_pos : a_pos + a_len], imu[i_pos : i_pos + i_len])
        a_pos, i_pos = a_pos + a_len, i_pos + i_len
    emitted += scorer.push(audio[a_pos:], imu[i_pos:])
    starts = np.array([s for s, _ in emitted])
    np.testing.assert_allclose(starts, 0.5 * np.arange(len(starts)))
    assert len(starts) >= 7  # windows ending before the recording's last FIR look-ahead
    batch = frame_windows(decimate_audio(audio), imu.astype(np.float32), starts)
    np.testing.assert_allclose([s for _, s in emitted], small_model.score(batch), rtol=1e-5)


def test_streaming_bad_chunks(small_model: MSVDD) -> None:
    scorer = StreamingScorer(small_model)
    with pytest.raises(WindowError, match="audio chunk shape"):
        scorer.push(np.zeros((10, 1)), np.zeros(1))
    with pytest.raises(WindowError, match="NaN"):
        scorer.push(np.full((10, 2), np.nan), np.zeros(1))
    with pytest.raises(ValueError, match="hop_s"):
        StreamingScorer(small_model, hop_s=0.0)


# ---------------------------------------------------------------- timestamps: gaps, duplicates, order

A_RATE, I_RATE = 44100, 200


class _LinearScorer:
    """A stand-in backend whose score is a fixed, time-varying linear function of a window's samples, so a
    window shifted, zeroed or held anywhere scores differently (an exact oracle for the stream policy)."""

    imu_input = "all"

    def __init__(self) -> None:
        rng = np.random.default_rng(7)
        self.wa = rng.standard_normal((8820, 2))
        self.wi = rng.standard_normal(400)
        self.w6 = rng.standard_normal((400, 6))

    def score(self, batch: Windows) -> np.ndarray:
        assert batch.imu6 is not None
        a = np.einsum("nlc,lc->n", batch.audio.astype(np.float64), self.wa)
        return a + batch.imu.astype(np.float64) @ self.wi + np.einsum("nlc,lc->n", batch.imu6, self.w6)


def _recording(seconds: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return _signals(np.random.default_rng(3), seconds)


def _oracle(
    audio: np.ndarray, imu: np.ndarray, imu6: np.ndarray, starts: list[float], start_s: float = 0.0
) -> np.ndarray:
    """Scores of batch-decimated, batch-framed windows of the whole (edited) recording."""
    rel = np.asarray(starts) - start_s
    return _LinearScorer().score(frame_windows(decimate_audio(audio), imu, rel, imu6=imu6))


def _push_timed(
    scorer: StreamingScorer,
    audio: np.ndarray,
    imu: np.ndarray,
    imu6: np.ndarray,
    pieces: list[tuple[float, float]],
    offset_s: float = 0.0,
) -> list[tuple[float, float]]:
    """Push the recording's spans [t0, t1) (seconds), each stamped with offset_s + t0."""
    out: list[tuple[float, float]] = []
    for t0, t1 in pieces:
        a = audio[round(t0 * A_RATE) : round(t1 * A_RATE)]
        i = slice(round(t0 * I_RATE), round(t1 * I_RATE))
        out += scorer.push(a, imu[i], imu6[i], audio_t=offset_s + t0, imu_t=offset_s + t0)
    return out


def _spans(t_end: float, step: float, t_start: float = 0.0) -> list[tuple[float, float]]:
    edges = np.round(np.arange(t_start, t_end + step / 2, step), 6)
    return [(float(a), float(b)) for a, b in itertools.pairwise(edges)]


def test_timestamps_within_jitter_are_contiguous() -> None:
    audio, imu, imu6 = _recording(6.0)
    plain = StreamingScorer(_LinearScorer())
    expected = _push_timed(plain, audio, imu, imu6, _spans(6.0, 0.25))
    scorer = StreamingScorer(_LinearScorer(), policy=GapPolicy(jitter_s=0.002))
    got: list[tuple[float, float]] = []
    for j, (t0, t1) in enumerate(_spans(6.0, 0.25)):
        a, i = audio[round(t0 * A_RATE) : round(t1 * A_RATE)], slice(round(t0 * I_RATE), round(t1 * I_RATE))
        jitter = 0.0015 * (-1) ** j  # +-1.5 ms: under jitter_s
        got += scorer.push(a, imu[i], imu6[i], audio_t=t0 + jitter, imu_t=t0 - jitter)
    assert got == expected
    c = scorer.counters
    assert c.windows_emitted == len(expected) == 8
    assert (c.audio_samples_filled, c.imu_samples_filled, c.audio_samples_dropped, c.resets) == (0, 0, 0, 0)
    assert (c.audio_chunks, c.imu_chunks) == (24, 24)


def test_short_audio_gap_is_zero_filled_and_counted() -> None:
    audio, imu, imu6 = _recording(6.0)
    scorer = StreamingScorer(_LinearScorer())
    emitted = scorer.push(audio[: 3 * A_RATE], imu, imu6, audio_t=0.0, imu_t=0.0)
    emitted += scorer.push(audio[round(3.05 * A_RATE) :], imu[:0], imu6[:0], audio_t=3.05)
    starts = [s for s, _ in emitted]
    assert starts == [0.5 * k for k in range(8)]
    zeroed = audio.copy()
    zeroed[3 * A_RATE : round(3.05 * A_RATE)] = 0.0
    np.testing.assert_allclose([v for _, v in emitted], _oracle(zeroed, imu, imu6, starts), rtol=1e-9)
    c = scorer.counters
    assert (c.audio_gaps_filled, c.audio_samples_filled, c.resets) == (1, round(0.05 * A_RATE), 0)
    # windows reaching [3.0, 3.05) s (with the filter's 200-sample reach): starts 1.0 to 3.0 s
    assert c.windows_with_fill == 5


def test_short_imu_gap_holds_the_last_sample() -> None:
    audio, imu, imu6 = _recording(6.0)
    scorer = StreamingScorer(_LinearScorer())
    emitted = scorer.push(audio, imu[:600], imu6[:600], audio_t=0.0, imu_t=0.0)
    emitted += scorer.push(audio[:0], imu[610:], imu6[610:], imu_t=610 / I_RATE)
    held, held6 = imu.copy(), imu6.copy()
    held[600:610], held6[600:610] = imu[599], imu6[599]
    starts = [s for s, _ in emitted]
    assert starts == [0.5 * k for k in range(8)]
    np.testing.assert_allclose([v for _, v in emitted], _oracle(audio, held, held6, starts), rtol=1e-9)
    c = scorer.counters
    assert (c.imu_gaps_filled, c.imu_samples_filled, c.resets) == (1, 10, 0)
    assert c.windows_with_fill == 4  # starts 1.5 to 3.0 s hold samples 600-609


def test_long_audio_gap_resets_and_waits_for_a_full_window() -> None:
    audio, imu, imu6 = _recording(8.0)
    scorer = StreamingScorer(_LinearScorer(), policy=GapPolicy(max_fill_s=0.1))
    before = _push_timed(scorer, audio, imu, imu6, _spans(3.0, 0.25))
    assert [s for s, _ in before] == [0.0, 0.5]  # the window at 1 s still lacks the filter's look-ahead
    after: list[tuple[float, float]] = []
    for t0, t1 in _spans(8.0, 0.25, 3.0):
        a = audio[round(t0 * A_RATE) : round(t1 * A_RATE)] if t0 >= 3.5 else audio[:0]  # audio gap 3-3.5 s
        i = slice(round(t0 * I_RATE), round(t1 * I_RATE))
        got = scorer.push(a, imu[i], imu6[i], audio_t=t0, imu_t=t0)
        if t1 <= 5.5:  # the first window after the gap (3.5 s) is not complete before 5.5 s + look-ahead
            assert got == []
        after += got
    assert scorer.counters.resets == 1
    assert [s for s, _ in after] == [3.5, 4.0, 4.5, 5.0, 5.5]
    assert scorer.counters.windows_skipped == 5  # 1.0 to 3.0 s
    # after the reset the audio restarts like a new recording at 3.5 s (zero-padded filter)
    fresh = StreamingScorer(_LinearScorer(), start_s=3.5)
    tail = fresh.push(audio[round(3.5 * A_RATE) :], imu[700:], imu6[700:])
    assert [s for s, _ in tail] == [s for s, _ in after]
    np.testing.assert_allclose([v for _, v in after], [v for _, v in tail], rtol=1e-9)


def test_long_imu_gap_resets_the_windows() -> None:
    audio, imu, imu6 = _recording(8.0)
    scorer = StreamingScorer(_LinearScorer())
    emitted: list[tuple[float, float]] = []
    for t0, t1 in _spans(8.0, 0.25):
        i = slice(round(t0 * I_RATE), round(t1 * I_RATE)) if not 3.0 <= t0 < 3.5 else slice(0, 0)
        a = audio[round(t0 * A_RATE) : round(t1 * A_RATE)]
        emitted += scorer.push(a, imu[i], imu6[i], audio_t=t0, imu_t=t0)
    starts = [s for s, _ in emitted]
    assert starts == [0.0, 0.5, 1.0, 3.5, 4.0, 4.5, 5.0, 5.5]
    # the audio stayed continuous: the windows are those of batch decimation of the whole recording
    np.testing.assert_allclose([v for _, v in emitted], _oracle(audio, imu, imu6, starts), rtol=1e-9)
    c = scorer.counters
    assert (c.resets, c.windows_skipped, c.imu_samples_filled) == (1, 4, 0)


def test_duplicate_chunks_are_dropped_and_counted() -> None:
    audio, imu, imu6 = _recording(6.0)
    expected = _push_timed(StreamingScorer(_LinearScorer()), audio, imu, imu6, _spans(6.0, 0.25))
    spans = _spans(6.0, 0.25)
    spans.insert(5, spans[4])  # the chunk at 1.0 s arrives twice
    scorer = StreamingScorer(_LinearScorer())
    assert _push_timed(scorer, audio, imu, imu6, spans) == expected
    c = scorer.counters
    assert (c.audio_chunks_dropped, c.imu_chunks_dropped) == (1, 1)
    assert (c.audio_samples_dropped, c.imu_samples_dropped) == (round(0.25 * A_RATE), 50)
    assert (c.audio_samples_filled, c.resets) == (0, 0)


def test_out_of_order_chunk_is_dropped_after_its_hole_was_filled() -> None:
    audio, imu, imu6 = _recording(6.0)
    spans = _spans(6.0, 0.05)
    spans[20], spans[21] = spans[21], spans[20]  # 1.05 s arrives before 1.0 s
    scorer = StreamingScorer(_LinearScorer())
    emitted = _push_timed(scorer, audio, imu, imu6, spans)
    edited, held, held6 = audio.copy(), imu.copy(), imu6.copy()
    edited[A_RATE : round(1.05 * A_RATE)] = 0.0
    held[200:210], held6[200:210] = imu[199], imu6[199]
    starts = [s for s, _ in emitted]
    assert starts == [0.5 * k for k in range(8)]
    np.testing.assert_allclose([v for _, v in emitted], _oracle(edited, held, held6, starts), rtol=1e-9)
    c = scorer.counters
    assert (c.audio_gaps_filled, c.imu_gaps_filled, c.audio_chunks_dropped, c.imu_chunks_dropped) == (
        1,
        1,
        1,
        1,
    )
    assert (c.audio_samples_dropped, c.imu_samples_dropped) == (round(0.05 * A_RATE), 10)


def test_overlapping_chunk_keeps_only_its_new_samples() -> None:
    audio, imu, imu6 = _recording(6.0)
    expected = StreamingScorer(_LinearScorer()).push(audio, imu, imu6)
    scorer = StreamingScorer(_LinearScorer())
    got = scorer.push(audio[:100_000], imu[:500], imu6[:500], audio_t=0.0, imu_t=0.0)
    got += scorer.push(audio[90_000:], imu[450:], imu6[450:], audio_t=90_000 / A_RATE, imu_t=450 / I_RATE)
    np.testing.assert_allclose([v for _, v in got], [v for _, v in expected], rtol=1e-9)
    c = scorer.counters
    assert (c.audio_samples_dropped, c.imu_samples_dropped, c.audio_chunks_dropped) == (10_000, 50, 0)


def test_caller_clock_and_a_late_first_chunk() -> None:
    audio, imu, imu6 = _recording(6.0)
    expected = StreamingScorer(_LinearScorer()).push(audio, imu, imu6)
    t0 = 1.7e9  # e.g. Unix time: start_s says where the stream's sample 0 is
    scorer = StreamingScorer(_LinearScorer(), start_s=t0)
    got = _push_timed(scorer, audio, imu, imu6, _spans(6.0, 0.25), offset_s=t0)
    assert [s for s, _ in got] == [t0 + s for s, _ in expected]
    np.testing.assert_allclose([v for _, v in got], [v for _, v in expected], rtol=1e-9)
    late = StreamingScorer(_LinearScorer())  # clock zero at 0, first samples at 100 s: a long gap
    got = _push_timed(late, audio, imu, imu6, _spans(6.0, 0.25), offset_s=100.0)
    assert [s for s, _ in got] == [100.0 + s for s, _ in expected]
    assert (late.counters.resets, late.counters.windows_skipped) == (2, 200)  # audio and IMU both restart


def test_hop_longer_than_a_window() -> None:
    audio, imu, imu6 = _recording(8.0)
    scorer = StreamingScorer(_LinearScorer(), hop_s=2.5)
    emitted = _push_timed(scorer, audio, imu, imu6, _spans(8.0, 0.25))
    starts = [s for s, _ in emitted]
    assert starts == [0.0, 2.5, 5.0]
    np.testing.assert_allclose([v for _, v in emitted], _oracle(audio, imu, imu6, starts), rtol=1e-9)


def test_bad_timestamps_and_policy() -> None:
    scorer = StreamingScorer(_LinearScorer())
    with pytest.raises(WindowError, match="audio_t"):
        scorer.push(np.zeros((10, 2)), np.zeros(1), np.zeros((1, 6)), audio_t=float("nan"))
    with pytest.raises(ValueError, match="max_fill_s"):
        GapPolicy(jitter_s=0.01, max_fill_s=0.001)
    with pytest.raises(ValueError, match="jitter_s"):
        GapPolicy(jitter_s=-1.0)
    with pytest.raises(ValueError, match="start_s"):
        StreamingScorer(_LinearScorer(), start_s=float("inf"))


def test_short_gap_with_the_real_model(small_model: MSVDD) -> None:
    audio, imu, _ = _recording(5.0)
    scorer = StreamingScorer(small_model)
    emitted = scorer.push(audio[: 2 * A_RATE], imu, audio_t=0.0, imu_t=0.0)
    emitted += scorer.push(audio[round(2.08 * A_RATE) :], imu[:0], audio_t=2.08)
    zeroed = audio.copy()
    zeroed[2 * A_RATE : round(2.08 * A_RATE)] = 0.0
    starts = np.array([s for s, _ in emitted])
    assert len(starts) == 6
    batch = frame_windows(decimate_audio(zeroed), imu, starts)
    np.testing.assert_allclose([s for _, s in emitted], small_model.score(batch), rtol=1e-5)
    assert scorer.counters.audio_gaps_filled == 1
