"""The streaming scorer matches batch decimation, framing and scoring on the same windows."""

from __future__ import annotations

import numpy as np
import pytest

from msvdd.config import MSVDDConfig
from msvdd.contract import WindowError, Windows
from msvdd.model import MSVDD
from msvdd.preprocess import decimate_audio, frame_windows
from msvdd.stream import StreamingScorer


def _signals(rng: np.random.Generator, seconds: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(int(44100 * seconds)) / 44100
    tone = 0.3 * np.sin(2 * np.pi * 90 * t) + 0.05 * rng.standard_normal(t.size)
    n = int(200 * seconds)
    imu = 0.02 * np.sin(2 * np.pi * np.arange(n) / 200) + 0.005 * rng.standard_normal(n)
    imu6 = 0.05 * rng.standard_normal((n, 6)) + np.array([0, 0, 9.81, 0, 0, 0])
    return np.stack([tone, 0.8 * tone], axis=1), imu.astype(np.float32), imu6.astype(np.float32)


def test_streaming_equals_batch_for_log_mel_and_all_imu_axes(toy_train: Windows) -> None:
    model = MSVDD(MSVDDConfig.tiny(epochs=1, audio_frontend="logmel", imu_input="all")).fit(toy_train)
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
