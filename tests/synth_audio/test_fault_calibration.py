"""The wheel faults' level laws and their detectability, measured on a simulated drive and its stems.

See `fault_calibration_kit`: the levels follow from the defects' physical sizes (`synth_audio.faults`);
the criterion held here is that severity 1 of every kind is detectable in principle, in audio or IMU.
"""

from __future__ import annotations

import numpy as np
import pytest
from audio_trace_kit import make_trace
from fault_calibration_kit import audio_level_db, imu_ratio, trace

from sim.trace import BEARING_BALL_DIAMETER, BEARING_PITCH_DIAMETER, IMBALANCE_ME, FaultRecord
from sim.vocab import FAULT_KINDS
from synth_audio import AudioConfig, render
from synth_audio.drive import build_drive
from synth_audio.faults import (
    DETECTOR_NYQUIST_HZ,
    FLAT_DEPTH_M,
    PLAY_M,
    SPALL_M,
    WHEEL_MASS,
    fault_band,
    strike_impulses,
)

DETECTABLE_DB = 6.0
"""Severity 1 stands at least this far over the healthy drive in its band (audio), or ..."""
DETECTABLE_RATIO = 2.0
"""... its IMU signature is at least this many times the healthy drive's."""


@pytest.mark.parametrize("kind", FAULT_KINDS)
def test_severity_one_is_detectable_in_principle_in_audio_or_imu(kind: str) -> None:
    assert audio_level_db(kind, 1.0) >= DETECTABLE_DB or imu_ratio(kind, 1.0) >= DETECTABLE_RATIO


@pytest.mark.parametrize("kind", FAULT_KINDS)
def test_the_fault_sound_grows_with_severity(kind: str) -> None:
    assert audio_level_db(kind, 0.3) < audio_level_db(kind, 0.6) < audio_level_db(kind, 1.0)


def test_strike_impulses_follow_the_defect_geometry() -> None:
    tr = make_trace(0.5, 10.0)
    drive = build_drive(tr.robot, tr.time, tr.wheel_angle, tr.wheel_speed, tr.wheel_torque, 4410, 44100)
    corner = tr.robot.mass / 4
    r = float(tr.robot.wheel_radius[0])
    v = np.array([0.5, 1.0])

    def record(kind: str, severity: float) -> FaultRecord:
        return FaultRecord(kind, 0, severity, 0.0, 1.0, 3.0, 1000.0, 0.05)

    # A flat of depth h strikes like a step of height h: dv = v sin(acos(1 - h / r)).
    h = 0.5 * FLAT_DEPTH_M
    expected = corner * v * np.sqrt(1.0 - (1.0 - h / r) ** 2)
    np.testing.assert_allclose(strike_impulses(drive, record("flat_spot", 0.5), v), expected, rtol=1e-12)
    # A hub falling through its play: J = m_wheel sqrt(2 g delta), whatever the speed.
    loose = strike_impulses(drive, record("loose_wheel", 1.0), v)
    np.testing.assert_allclose(loose, WHEEL_MASS * np.sqrt(2 * 9.81 * PLAY_M), rtol=1e-12)
    # A ball over a spall of length l: its speed over the race times l / d.
    ball = v / r * BEARING_PITCH_DIAMETER / 4
    expected = corner * ball * SPALL_M / BEARING_BALL_DIAMETER
    np.testing.assert_allclose(strike_impulses(drive, record("bearing", 1.0), v), expected, rtol=1e-12)
    with pytest.raises(ValueError, match="not an impulsive fault"):
        strike_impulses(drive, record("imbalance", 1.0), v)


def test_imbalance_modulates_its_wheel_by_the_centrifugal_load() -> None:
    # Depth of the 1x/rev modulation = m e omega^2 / (m g / W): the tyre's noise follows its load.
    omega = 12.0
    fault = FaultRecord("imbalance", 0, 1.0, 0.0, 3.0, 1.0, 28.0, 0.12)
    config = AudioConfig(ambience=False, rt60_s=0.0, mic_noise_spl_db=float("-inf"), stems=True)
    tr = make_trace(2.0, omega, faults=(fault,))
    stems = render(tr, config, seed=1).stems
    healthy = render(make_trace(2.0, omega), config, seed=1).stems
    wheel = (healthy["motor"] + healthy["rolling"]).astype(np.float64)
    ratio = np.sqrt(np.mean(stems["faults"].astype(np.float64) ** 2) / np.mean(wheel**2))
    depth = IMBALANCE_ME * omega**2 / (tr.robot.mass * 9.81 / 4)
    # The modulated part is one wheel's sound (a quarter of the power of four similar wheels) times
    # cos(phase): its RMS is depth x sqrt(1/2) x sqrt(1/4) of the four wheels' sound.
    assert ratio == pytest.approx(depth * np.sqrt(0.5) * 0.5, rel=0.35)


@pytest.mark.parametrize("kind", FAULT_KINDS)
def test_every_fault_band_lies_below_the_detectors_nyquist(kind: str) -> None:
    record = trace(kind, 1.0).faults[0]
    low, high = fault_band(record, 1.6, 44100)
    assert 20.0 <= low < high <= DETECTOR_NYQUIST_HZ
    assert record.resonance_hz < DETECTOR_NYQUIST_HZ


def test_fault_band_centres_on_the_resonance_or_the_mesh_tone() -> None:
    bearing = FaultRecord("bearing", 0, 1.0, 0.0, 1.0, 3.5, 1000.0, 0.03)
    low, high = fault_band(bearing, 2.0, 44100)
    assert np.sqrt(low * high) == pytest.approx(1000.0) and high / low == pytest.approx(2.0)
    gears = FaultRecord("motor_degradation", 0, 1.0, 0.0, 1.0, 200.0, 1150.0, 0.04)
    low, high = fault_band(gears, 2.0, 44100)
    assert (low, high) == pytest.approx((400.0 / 1.2, 480.0))
    with pytest.raises(ValueError, match="empty"):
        fault_band(FaultRecord("bearing", 0, 1.0, 0.0, 1.0, 3.5, 4000.0, 0.03), 2.0, 44100)
