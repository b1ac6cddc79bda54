"""Motor and rolling sources: the motor fundamental tracks wheel speed x gear ratio; standstill only hums."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from audio_trace_kit import contacts, make_trace
from signal_oracles import peak_frequency

from synth_audio import AudioConfig, render


@pytest.mark.parametrize("omega", [6.0, 10.0, 16.0])
def test_motor_fundamental_is_wheel_speed_times_gear_ratio(omega: float, quiet: AudioConfig) -> None:
    trace = make_trace(duration=2.0, wheel_speed=omega)
    audio = render(trace, quiet, seed=3)
    expected = omega / (2 * np.pi) * trace.robot.gear_ratio
    motor = audio.stems["motor"][:, 0]
    assert abs(peak_frequency(motor, 44100, 0.7 * expected, 1.3 * expected) - expected) < 1.0
    # The gear-mesh tone sits at pinion_teeth x the shaft rate.
    mesh = expected * trace.robot.pinion_teeth
    assert abs(peak_frequency(motor, 44100, 0.9 * mesh, 1.1 * mesh) - mesh) < 3.0


def test_motor_fundamental_tracks_a_speed_ramp(quiet: AudioConfig) -> None:
    def speed(t: np.ndarray) -> np.ndarray:
        return 5.0 + 3.0 * t  # 5 -> 14 rad/s over 3 s

    trace = make_trace(duration=3.0, wheel_speed=speed)
    motor = render(trace, quiet, seed=1).stems["motor"][:, 0]
    sr, frame = 44100, 11025
    for start in range(0, motor.size - frame, frame):
        mid = (start + frame / 2) / sr
        expected = float(speed(np.array(mid))) / (2 * np.pi) * trace.robot.gear_ratio
        found = peak_frequency(motor[start : start + frame], sr, 0.75 * expected, 1.25 * expected)
        assert abs(found - expected) < 3.0, (mid, found, expected)


def test_standing_still_leaves_only_the_idle_hum_and_the_environment() -> None:
    trace = make_trace(duration=1.5, wheel_speed=0.0)
    audio = render(trace, AudioConfig(stems=True), seed=2)
    for name in ("rolling", "transients", "impacts", "faults"):
        assert not np.any(audio.stems[name]), name
    # A powered robot at rest: the drivers' holding-current PWM whine and the fan (see test_nearfield).
    assert np.any(audio.stems["motor"]) and np.any(audio.stems["electronics"])
    assert np.max(np.abs(audio.stems["ambience"])) > 0
    np.testing.assert_allclose(audio.samples, sum(audio.stems.values()), atol=1e-6)


def test_rolling_noise_grows_with_speed(quiet: AudioConfig) -> None:
    levels = [float(np.std(render(make_trace(1.0, w), quiet, 0).stems["rolling"])) for w in (4.0, 8.0, 16.0)]
    assert levels[0] < levels[1] < levels[2]


def test_muting_the_strain_holds_the_motor_load_through_each_contact_only(quiet: AudioConfig) -> None:
    """The audit's deleted-sound render: over a contact the motors sound at the load they had before it (the
    obstacle's push on the drive taken out), elsewhere exactly as in the full render."""
    plain = make_trace(duration=2.0, wheel_speed=10.0, contact_events=contacts([1.0], durations=[0.4]))
    torque = plain.wheel_torque.copy()
    during = (plain.time >= 1.0) & (plain.time <= 1.4)
    torque[during] *= 4.0  # the motors strain against the obstacle
    strained = dataclasses.replace(plain, wheel_torque=torque)
    muted = AudioConfig(**{**quiet.__dict__, "muted": ("impacts", "strain")})
    impacts_only = AudioConfig(**{**quiet.__dict__, "muted": ("impacts",)})
    same = render(plain, impacts_only, seed=2).samples
    np.testing.assert_array_equal(render(strained, muted, seed=2).samples, same)
    louder = render(strained, impacts_only, seed=2).stems["motor"]
    held = render(strained, muted, seed=2).stems["motor"]
    sr = 44100
    inside = slice(int(1.05 * sr), int(1.35 * sr))
    assert np.std(louder[inside]) > 1.5 * np.std(held[inside])
    np.testing.assert_array_equal(louder[: int(0.95 * sr)], held[: int(0.95 * sr)])
