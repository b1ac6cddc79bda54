"""Decimation (anti-alias oracle: pass-band tones kept, alias tones removed), framing, z-score, smoothing."""

from __future__ import annotations

import numpy as np
import pytest

from msvdd.contract import WindowError, Windows
from msvdd.frontend import InputNormalizer
from msvdd.preprocess import decimate_audio, frame_windows, smooth

FS = 44100.0


def _tone(freq: float, seconds: float = 1.0) -> np.ndarray:
    t = np.arange(int(FS * seconds)) / FS
    x = np.sin(2 * np.pi * freq * t)
    return np.stack([x, 0.5 * x], axis=1)


def test_decimate_shape_and_rate() -> None:
    y = decimate_audio(np.zeros((44105, 2)))
    assert y.shape == (4410, 2) and y.dtype == np.float32


@pytest.mark.parametrize("freq", [100.0, 500.0, 1500.0])
def test_passband_tone_is_kept_in_phase(freq: float) -> None:
    y = decimate_audio(_tone(freq))
    t = np.arange(y.shape[0]) / 4410.0
    expected = np.sin(2 * np.pi * freq * t)
    core = slice(100, -100)  # away from the zero-padded ends
    np.testing.assert_allclose(y[core, 0], expected[core], atol=2e-3)  # zero phase: no delay
    np.testing.assert_allclose(y[core, 1], 0.5 * expected[core], atol=1e-3)


@pytest.mark.parametrize("freq", [2600.0, 3000.0, 6000.0, 15000.0])
def test_alias_tones_are_removed(freq: float) -> None:
    # Without an anti-alias filter these would fold to |freq - k 4410| with full amplitude.
    y = decimate_audio(_tone(freq))
    assert np.abs(y[100:-100]).max() < 1e-3


def test_decimate_bad_input() -> None:
    with pytest.raises(WindowError, match="44100"):
        decimate_audio(np.zeros((100, 2)), rate=48000.0)
    with pytest.raises(WindowError, match="shape"):
        decimate_audio(np.zeros((100, 3)))
    bad = np.zeros((100, 2))
    bad[5, 0] = np.nan
    with pytest.raises(WindowError, match="NaN"):
        decimate_audio(bad)


def test_frame_windows_cuts_at_start_times() -> None:
    audio = np.arange(4410 * 5 * 2, dtype=np.float32).reshape(-1, 2)
    imu = np.arange(200 * 5, dtype=np.float32)
    w = frame_windows(audio, imu, np.array([0.0, 1.5, 3.0]))
    assert len(w) == 3
    assert w.audio[1, 0, 0] == audio[int(1.5 * 4410), 0]
    assert w.imu[2, 0] == imu[600] and w.imu[2, -1] == imu[999]
    imu6 = np.zeros((1000, 6), dtype=np.float32)
    assert frame_windows(audio, imu, np.array([0.5]), imu6=imu6).imu6 is not None
    with pytest.raises(WindowError, match="past the end"):
        frame_windows(audio, imu, np.array([3.5]))
    with pytest.raises(WindowError, match=">= 0"):
        frame_windows(audio, imu, np.array([-0.5]))
    with pytest.raises(WindowError, match="imu_z shape"):
        frame_windows(audio, imu[:, None], np.array([0.0]))


def test_windows_contract_rejects_bad_batches() -> None:
    with pytest.raises(WindowError, match="audio shape"):
        Windows(audio=np.zeros((2, 8000, 2), np.float32), imu=np.zeros((2, 400), np.float32))
    with pytest.raises(WindowError, match="audio_rate"):
        Windows(
            audio=np.zeros((2, 8820, 2), np.float32), imu=np.zeros((2, 400), np.float32), audio_rate=44100
        )
    imu = np.zeros((2, 400), np.float32)
    imu[0, 3] = np.nan
    with pytest.raises(WindowError, match="NaN"):
        Windows(audio=np.zeros((2, 8820, 2), np.float32), imu=imu)


def _windows(n: int, seed: int, scale: float = 1.0, offset: float = 0.0) -> Windows:
    rng = np.random.default_rng(seed)
    return Windows(
        audio=(offset + scale * rng.standard_normal((n, 8820, 2))).astype(np.float32),
        imu=(offset + scale * rng.standard_normal((n, 400))).astype(np.float32),
    )


def test_normalizer_uses_training_statistics_only() -> None:
    train = _windows(4, 0, scale=3.0, offset=2.0)
    norm = InputNormalizer.fit(train)
    np.testing.assert_allclose(norm.audio_mean, 2.0, atol=0.08)
    np.testing.assert_allclose(norm.audio_std, 3.0, atol=0.08)
    other = _windows(3, 1, scale=10.0, offset=-5.0)
    audio = norm.tensors(other, smooth_window=0)[0].numpy()
    # The other batch is scaled with the training statistics, not its own.
    np.testing.assert_allclose(audio.mean(), (-5.0 - 2.0) / 3.0, atol=0.05)
    restored = InputNormalizer.from_state(norm.state())
    np.testing.assert_array_equal(restored.tensors(other, smooth_window=0)[0].numpy(), audio)


def test_smoothing_is_per_window() -> None:
    batch = _windows(3, 2)
    a1, i1 = InputNormalizer.fit(batch).tensors(batch)
    changed = Windows(audio=batch.audio.copy(), imu=batch.imu.copy())
    changed.audio[1] += 5.0 * np.sign(changed.audio[1])
    changed.imu[1] *= -3.0
    a2, i2 = InputNormalizer.fit(batch).tensors(changed)
    # Windows 0 and 2 are untouched by what happens in window 1 (no filter state crosses windows).
    assert np.array_equal(a1[[0, 2]].numpy(), a2[[0, 2]].numpy())
    assert np.array_equal(i1[[0, 2]].numpy(), i2[[0, 2]].numpy())


def test_smoothing_keeps_quadratics_and_attenuates_noise() -> None:
    t = np.linspace(-1, 1, 400)[None, :]
    quad = 3 * t**2 - t + 0.5
    np.testing.assert_allclose(smooth(quad, 5, 2)[:, 2:-2], quad[:, 2:-2], atol=1e-5)  # exact on degree 2
    noise = np.random.default_rng(0).standard_normal((1, 4000))
    assert smooth(noise, 5, 2).std() < 0.9 * noise.std()


def test_fit_tensors_equals_fit_then_tensors() -> None:
    batch = _windows(3, 4)
    norm, (audio, imu) = InputNormalizer.fit_tensors(batch)
    fitted = InputNormalizer.fit(batch)
    for key, value in fitted.arrays().items():
        np.testing.assert_array_equal(norm.arrays()[key], value)
    for got, want in zip((audio, imu), fitted.tensors(batch), strict=True):
        np.testing.assert_array_equal(got.numpy(), want.numpy())
