"""Spatialisation, SNR mixing and determinism."""

from __future__ import annotations

import numpy as np
import pytest
from audio_trace_kit import contacts, make_trace, transients
from scipy.signal import correlate
from signal_oracles import rms

from synth_audio import AudioConfig, render
from synth_audio.drive import reference_torque

SR = 44100


def _lag_right_after_left(stereo: np.ndarray) -> int:
    """Samples by which the right channel lags the left (positive: left first)."""
    left, right = stereo[:, 0].astype(np.float64), stereo[:, 1].astype(np.float64)
    xc = correlate(right, left, mode="full", method="fft")
    return int(np.argmax(xc) - (left.size - 1))


@pytest.mark.parametrize("y", [0.3, 0.6])
def test_contact_on_the_left_arrives_first_and_louder_on_the_left(y: float, quiet: AudioConfig) -> None:
    trace = make_trace(0.6, 0.0, contact_events=contacts([0.2], [2.0], [(0.1, y, 0.1)], ["wood"]))
    stem = render(trace, quiet, seed=0).stems["impacts"]
    assert rms(stem[:, 0]) > 1.2 * rms(stem[:, 1])
    assert _lag_right_after_left(stem) > 0
    mirrored = make_trace(0.6, 0.0, contact_events=contacts([0.2], [2.0], [(0.1, -y, 0.1)], ["wood"]))
    stem_r = render(mirrored, quiet, seed=0).stems["impacts"]
    assert rms(stem_r[:, 1]) > 1.2 * rms(stem_r[:, 0])
    assert _lag_right_after_left(stem_r) < 0


def test_transient_at_the_left_wheel_is_louder_on_the_left(quiet: AudioConfig) -> None:
    # The wheels must roll: a wheel at rest meets a feature without striking it (see strike_impulse).
    trace = make_trace(0.6, 10.0, transient_events=transients([0.1], [2], [2.0], ["threshold"]))
    stem = render(trace, quiet, seed=0).stems["transients"]
    assert rms(stem[:, 0]) > rms(stem[:, 1])
    assert _lag_right_after_left(stem) > 0


@pytest.mark.parametrize("environment", ["indoor", "outdoor"])
@pytest.mark.parametrize("snr", [6.0, 0.0, -6.0])
def test_measured_snr_equals_requested(environment: str, snr: float) -> None:
    config = AudioConfig(snr_db=snr, stems=True, mic_noise_spl_db=float("-inf"))
    base = make_trace(2.0, config.reference_speed / 0.06, environment=environment, surface="concrete")
    trace = make_trace(
        2.0, config.reference_speed / 0.06, torque=reference_torque(base.robot), environment=environment,
        surface="concrete",
    )  # fmt: skip
    audio = render(trace, config, seed=7)
    robot = audio.stems["motor"] + audio.stems["rolling"]
    measured = 20 * np.log10(rms(robot) / rms(audio.stems["ambience"]))
    assert abs(measured - snr) < 0.5
    target = 10 ** (config.reference_level_dbfs / 20) / 10 ** (snr / 20)
    # The ambience is set to the target from its dry and reverberant energies (their small chance
    # correlation over a 2 s clip is not counted), so it lands within a fraction of a dB.
    assert abs(20 * np.log10(rms(audio.stems["ambience"]) / target)) < 0.25


def test_collision_does_not_change_the_ambience_level() -> None:
    config = AudioConfig(stems=True)
    plain = render(make_trace(1.0, 10.0), config, seed=3)
    hit = render(make_trace(1.0, 10.0, contact_events=contacts([0.5], [20.0])), config, seed=3)
    np.testing.assert_array_equal(plain.stems["ambience"], hit.stems["ambience"])


def test_same_seed_same_samples_and_other_seed_differs() -> None:
    trace = make_trace(1.0, 9.0, contact_events=contacts([0.4], [2.0]),
                       transient_events=transients([0.7], [1], [1.0], ["debris"]))  # fmt: skip
    a = render(trace, AudioConfig(), seed=11)
    b = render(trace, AudioConfig(), seed=11)
    c = render(trace, AudioConfig(), seed=12)
    np.testing.assert_array_equal(a.samples, b.samples)
    assert not np.array_equal(a.samples, c.samples)
    assert a.samples.dtype == np.float32 and a.samples.shape == (44100, 2)
    assert a.stems == {}


def test_stems_sum_to_the_mix_and_stems_do_not_change_it() -> None:
    trace = make_trace(1.0, 9.0, contact_events=contacts([0.4], [1.0]))
    with_stems = render(trace, AudioConfig(stems=True), seed=1)
    without = render(trace, AudioConfig(), seed=1)
    total = sum(with_stems.stems.values())
    np.testing.assert_allclose(with_stems.samples, total, atol=1e-5)
    np.testing.assert_allclose(with_stems.samples, without.samples, atol=1e-5)


@pytest.mark.parametrize("rate", [16000, 22050, 48000])
def test_length_is_duration_times_rate(rate: int) -> None:
    trace = make_trace(1.2345, 8.0)
    audio = render(trace, AudioConfig(sample_rate=rate), seed=0)
    assert audio.samples.shape == (round(1.2345 * rate), 2)
    assert audio.sample_rate == rate
    assert np.all(np.isfinite(audio.samples)) and np.max(np.abs(audio.samples)) <= 1.0
