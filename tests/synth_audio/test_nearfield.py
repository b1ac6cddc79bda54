"""Near-field environmental events (heard, not felt) and the robot's idle sound (fan, PWM holding current)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from audio_trace_kit import make_trace
from signal_oracles import peak_frequency, rms

from sim import simulate
from sim.scenario import Route, Scenario
from synth_audio import AudioConfig, AudioError, render
from synth_audio import nearfield as nf
from synth_audio.electronics import FAN_DB, unit_fan

SR = 44100
C = 343.0
MICS = np.array([[0.2, 0.1, 0.12], [0.2, -0.1, 0.12]])  # the kit robot's, at the origin facing +x


def _still_listener() -> nf.Listener:
    return nf.Listener(np.array([0.0, 10.0]), np.stack([MICS, MICS]))


def _receive(emission: nf.Emission, seconds: float = 2.0) -> np.ndarray:
    out = np.zeros((2, int(seconds * SR)), dtype=np.float32)
    nf.receive_into(out, emission, _still_listener(), SR, C)
    return out


def _db(x: np.ndarray) -> float:
    return float(20.0 * np.log10(rms(x)))


def test_spherical_spreading_and_propagation_delay() -> None:
    sound = nf.synthesise("door", np.random.default_rng(1), SR, 0.0, 0.0, "tile") * np.float32(0.01)
    heard = {}
    for d in (1.0, 4.0):  # on the left mic's axis, so its directivity gain is 1
        heard[d] = _receive(nf.Emission(sound, 0.1, MICS[0] + [0.0, d, 0.0], np.zeros(3)))[0]
    # 1 m from the source the mic hears the 1 m signal itself; at 4 m, 20 log10(4) = 12.04 dB less.
    assert abs(_db(heard[1.0]) - _db(sound) - 10 * np.log10(sound.size / heard[1.0].size)) < 0.1
    assert abs(_db(heard[1.0]) - _db(heard[4.0]) - 20 * np.log10(4.0)) < 0.5
    for d, x in heard.items():
        onset = int(np.argmax(np.abs(x) > 1e-7))
        assert abs(onset - (0.1 + d / C) * SR) <= 2


def test_moving_source_carries_its_doppler_shift() -> None:
    t = np.arange(SR) / SR
    tone = (0.01 * np.sin(2 * np.pi * 1000.0 * t)).astype(np.float32)
    approaching = nf.Emission(tone, 0.0, np.array([30.0, 0.0, 0.12]), np.array([-10.0, 0.0, 0.0]))
    left = _receive(approaching)[0, int(0.2 * SR) : int(0.9 * SR)]
    assert abs(peak_frequency(left, SR, 900.0, 1100.0) - 1000.0 * C / (C - 10.0)) < 1.0


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_event_on_the_left_is_louder_and_earlier_on_the_left(side: float) -> None:
    voice = nf.synthesise("voice", np.random.default_rng(2), SR, 1.0, 0.0, "tile") * np.float32(0.01)
    heard = _receive(nf.Emission(voice, 0.1, np.array([0.5, 2.0 * side, 1.6]), np.zeros(3)))
    near, far = (0, 1) if side > 0 else (1, 0)
    assert _db(heard[near]) - _db(heard[far]) > 1.0
    assert np.argmax(np.abs(heard[near]) > 1e-7) < np.argmax(np.abs(heard[far]) > 1e-7)


@pytest.mark.parametrize("environment", ["indoor", "outdoor"])
def test_event_count_is_poisson_with_the_configured_rate(environment: str) -> None:
    rate, duration, clips = 0.15, 300.0, 200
    counts, kinds = [], []
    for seed in range(clips):
        events = nf.schedule(np.random.default_rng(seed), rate, duration, environment)
        heard = [e for e in events if 0.0 <= e.onset < duration]
        counts.append(len(heard))
        kinds += [e.kind for e in heard]
    mean, expected = float(np.mean(counts)), rate * duration
    assert abs(mean - expected) < 4.0 * np.sqrt(expected / clips)
    assert 0.7 < float(np.var(counts, ddof=1)) / mean < 1.3  # Poisson: variance = mean
    for kind, weight in nf.WEIGHTS[environment].items():
        assert abs(kinds.count(kind) / len(kinds) - weight) < 0.03, kind


@pytest.mark.parametrize("environment", ["indoor", "outdoor"])
def test_levels_at_one_metre_are_the_stated_spl(environment: str) -> None:
    config = AudioConfig()
    for kind in nf.WEIGHTS[environment]:
        spec = nf.KINDS[kind]
        for seed in range(3):
            emission = nf.plan(nf.Event(kind, 1.0, seed), _still_listener(), "concrete", config, 10.0)
            assert emission is not None
            x = emission.signal.astype(np.float64)
            level = 20 * np.log10(np.max(np.abs(x)) if spec.impulsive else rms(x)) + config.full_scale_spl_db
            assert spec.level_db[0] - 0.01 <= level <= spec.level_db[1] + 0.01, (kind, level)
            offset = emission.origin[:2] - MICS.mean(axis=0)[:2]
            speed = float(np.linalg.norm(emission.velocity))
            if speed > 0:  # a passer-by: the closest approach of its straight line
                along = emission.velocity[:2] / speed
                offset = offset - np.dot(offset, along) * along
            assert spec.distance_m[0] - 0.01 <= np.linalg.norm(offset) <= spec.distance_m[1] + 0.01, kind
            assert spec.speed_mps[0] - 0.01 <= speed <= spec.speed_mps[1] + 0.01, kind


def test_same_seed_same_samples_rate_zero_and_no_ambience_render_nothing() -> None:
    trace = make_trace(3.0, 10.0)
    config = AudioConfig(stems=True, nearfield_rate_hz=1.0)
    a = render(trace, config, seed=5)
    b = render(trace, config, seed=5)
    np.testing.assert_array_equal(a.samples, b.samples)
    assert np.any(a.stems["nearfield"])
    off = render(trace, dataclasses.replace(config, nearfield_rate_hz=0.0), seed=5)
    assert not np.any(off.stems["nearfield"])
    for name, stem in off.stems.items():  # no other source changes with the near field
        if name != "nearfield":
            np.testing.assert_array_equal(stem, a.stems[name], err_msg=name)
    quiet = render(trace, dataclasses.replace(config, ambience=False), seed=5)
    assert not np.any(quiet.stems["nearfield"])


def test_nearfield_rate_is_validated() -> None:
    for bad in (-0.1, 5.0, float("nan")):
        with pytest.raises(AudioError, match="nearfield_rate_hz"):
            render(make_trace(0.3, 5.0), AudioConfig(nearfield_rate_hz=bad))


def test_standing_robot_hums_with_its_fan_and_holding_current() -> None:
    trace = make_trace(2.0, wheel_speed=0.0)
    config = AudioConfig(ambience=False, rt60_s=0.0, mic_noise_spl_db=float("-inf"), stems=True)
    audio = render(trace, config, seed=1)
    assert rms(audio.samples) > 0
    fan = unit_fan(trace.robot)
    assert 250.0 <= fan.blade_pass_hz <= 900.0
    found = peak_frequency(audio.samples[:, 0], SR, 0.8 * fan.blade_pass_hz, 1.2 * fan.blade_pass_hz)
    assert abs(found - fan.blade_pass_hz) < 1.0
    # The fan's level law: FAN_DB re the unit's reference drive at the mics.
    level = _db(audio.stems["electronics"]) + config.full_scale_spl_db
    assert abs(level - (config.reference_spl_db + FAN_DB)) < 0.1
    # The motor drivers still switch: a faint whine at the PWM carrier and nothing else from the motors.
    motor = audio.stems["motor"][:, 0].astype(np.float64)
    spectrum = np.abs(np.fft.rfft(motor)) ** 2
    freqs = np.fft.rfftfreq(motor.size, 1.0 / SR)
    pwm = np.abs(freqs - trace.robot.pwm_hz) < 50.0
    assert spectrum.sum() > 0 and spectrum[pwm].sum() > 0.99 * spectrum.sum()
    assert unit_fan(trace.robot) == fan and unit_fan(make_trace(0.1, 0.0, unit_id=3).robot) != fan


def test_render_leaves_the_trace_untouched() -> None:
    trace = simulate(Scenario(name="idle", seed=3, duration=1.5, route=Route(waypoints=())))
    before = {
        f.name: np.array(getattr(trace, f.name), copy=True)
        for f in dataclasses.fields(trace)
        if isinstance(getattr(trace, f.name), np.ndarray)
    }
    audio = render(trace, AudioConfig(nearfield_rate_hz=2.0), seed=2)
    assert rms(audio.samples) > 0
    for name, value in before.items():
        np.testing.assert_array_equal(getattr(trace, name), value, err_msg=name)
