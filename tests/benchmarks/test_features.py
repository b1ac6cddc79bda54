"""Handcrafted features against analytic oracles: mel scale, filterbank, pure tones, sine IMU statistics."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks import features
from msvdd import logmel
from msvdd.contract import AUDIO_LEN, AUDIO_RATE, IMU_LEN, IMU_RATE
from msvdd.synthetic import toy_windows

CFG = features.FeatureConfig()


def test_mel_scale_known_points_and_round_trip() -> None:
    assert logmel.hz_to_mel(0.0) == pytest.approx(0.0)
    assert logmel.hz_to_mel(1000.0) == pytest.approx(1000.0, abs=0.05)  # HTK: 1000 Hz ~ 1000 mel
    f = np.linspace(0.0, 2205.0, 50)
    np.testing.assert_allclose(logmel.mel_to_hz(logmel.hz_to_mel(f)), f, atol=1e-9)


def test_filterbank_triangles_partition_unity() -> None:
    bank = logmel.mel_filterbank(CFG.n_mels, CFG.n_fft, AUDIO_RATE, CFG.f_min, CFG.f_max)
    assert bank.shape == (CFG.n_mels, CFG.n_fft // 2 + 1)
    assert bank.min() >= 0.0 and bank.max() <= 1.0 + 1e-12
    edges = logmel.mel_to_hz(
        np.linspace(logmel.hz_to_mel(CFG.f_min), logmel.hz_to_mel(CFG.f_max), CFG.n_mels + 2)
    )
    freqs = np.fft.rfftfreq(CFG.n_fft, 1.0 / AUDIO_RATE)
    inner = (freqs >= edges[1]) & (freqs <= edges[-2])
    np.testing.assert_allclose(bank[:, inner].sum(axis=0), 1.0, atol=1e-12)
    # band centres increase: each filter peaks at a higher bin than the one before
    assert np.all(np.diff(np.argmax(bank, axis=1)) >= 0)
    with pytest.raises(ValueError, match="cover no FFT bin"):
        logmel.mel_filterbank(128, 64, AUDIO_RATE, 20.0, 2205.0)


@pytest.mark.parametrize("freq", [150.0, 600.0, 1500.0])
def test_pure_tone_lands_in_its_band_and_is_steady(freq: float) -> None:
    t = np.arange(AUDIO_LEN) / AUDIO_RATE
    tone = np.sin(2 * np.pi * freq * t)[None, :, None].repeat(2, axis=2).astype(np.float32)
    lm = features.log_mel(tone, CFG)[0]
    edges = logmel.mel_to_hz(
        np.linspace(logmel.hz_to_mel(CFG.f_min), logmel.hz_to_mel(CFG.f_max), CFG.n_mels + 2)
    )
    centres = edges[1:-1]
    band = int(np.argmax(lm.mean(axis=0)))
    assert abs(band - int(np.argmin(np.abs(centres - freq)))) <= 1
    feats = features.audio_features(tone, CFG)[0]
    # a stationary tone: per-band std over frames ~ 0 in its band; its spectral flux is far below that of
    # the same tone switched on half-way (an onset)
    assert feats[CFG.n_mels + band] < 1e-3
    gated = tone * (t >= 1.0)[None, :, None].astype(np.float32)
    assert feats[-1] < 0.05 * features.audio_features(gated, CFG)[0, -1]


def test_imu_statistics_of_a_sine() -> None:
    amp, freq = 0.5, 5.0
    t = np.arange(IMU_LEN) / IMU_RATE
    x = (amp * np.sin(2 * np.pi * freq * t))[None]  # 10 full periods
    f = dict(zip(features.IMU_STAT_NAMES, features.imu_features(x, CFG)[0], strict=False))
    assert f["mean"] == pytest.approx(0.0, abs=1e-12)
    assert f["rms"] == pytest.approx(amp / np.sqrt(2), rel=1e-9)
    assert f["kurtosis"] == pytest.approx(-1.5, abs=1e-9)  # excess kurtosis of a sine
    assert f["skewness"] == pytest.approx(0.0, abs=1e-9)
    assert f["crest"] == pytest.approx(np.sqrt(2), rel=1e-3)
    bands = features.imu_features(x, CFG)[0, len(features.IMU_STAT_NAMES) :]
    edges = np.asarray(CFG.imu_band_edges)
    assert int(np.argmax(bands)) == int(np.searchsorted(edges, freq, side="right") - 1)


def test_window_features_shapes_chunking_and_constant_input() -> None:
    windows, _ = toy_windows(6, 2, seed=0)
    f = features.window_features(windows, CFG)
    assert f.audio.shape == (8, 3 * CFG.n_mels + 2)
    assert f.imu.shape == (8, len(features.IMU_STAT_NAMES) + len(CFG.imu_band_edges) - 1)
    assert f.early().shape == (8, f.audio.shape[1] + f.imu.shape[1])
    assert np.all(np.isfinite(f.early()))
    # chunking does not change the result
    small = features.FeatureConfig(chunk=3)
    np.testing.assert_allclose(features.audio_features(windows.audio, small), f.audio, rtol=1e-6, atol=1e-9)
    constant = np.zeros((1, IMU_LEN))
    assert np.all(np.isfinite(features.imu_features(constant, CFG)))
