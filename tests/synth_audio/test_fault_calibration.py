"""The wheel faults' level laws and their detectability, measured on a simulated drive and its stems.

See `fault_calibration_kit`: the levels follow from the defects' physical sizes (`synth_audio.faults`);
the criterion held here is that severity 1 of every kind is detectable in principle, in audio or IMU.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from audio_trace_kit import make_trace
from fault_calibration_kit import audio_level_db, imu_ratio, trace

from sim.faults import (
    FLAT_DEPTH_M,
    HUB_SPAN,
    PLAY_M,
    SPALL_M,
    TYRE_CORNERING,
    WHEEL_MASS,
    defect_size,
    strike_impulse,
)
from sim.trace import BEARING_BALL_DIAMETER, BEARING_PITCH_DIAMETER, FaultRecord, FaultStrikes
from sim.vocab import FAULT_KINDS
from synth_audio import AudioConfig, render
from synth_audio.faults import DETECTOR_NYQUIST_HZ, fault_band

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


def _record(kind: str, severity: float, **extra: float) -> FaultRecord:
    size = defect_size(kind, severity)
    return FaultRecord(kind, 0, severity, 0.0, 3.0, 1.0, 1000.0, 0.05, size=size, **extra)


def test_strike_impulses_follow_the_defect_geometry() -> None:
    corner, r = 5.0, 0.08
    v = np.array([0.5, 1.0])
    # A flat of depth h = s^2 H reverses its corner's fall: dv = 2 v sin(acos(1 - h / r)), twice a step's.
    h = 0.25 * FLAT_DEPTH_M
    expected = 2.0 * corner * v * np.sqrt(1.0 - (1.0 - h / r) ** 2)
    np.testing.assert_allclose(strike_impulse(_record("flat_spot", 0.5), v, corner, r), expected, rtol=1e-12)
    # A hub slammed across its play delta by the tyre's force F: J = sqrt(2 m_wheel F delta), any speed.
    delta = PLAY_M
    force = max(WHEEL_MASS * 9.81, TYRE_CORNERING * delta / HUB_SPAN)
    loose = strike_impulse(_record("loose_wheel", 1.0), v, corner, r)
    np.testing.assert_allclose(loose, np.sqrt(2 * WHEEL_MASS * force * delta), rtol=1e-12)
    # A ball over a spall of length l: its speed over the race times l / d.
    ball = v / r * BEARING_PITCH_DIAMETER / 4
    expected = corner * ball * SPALL_M / BEARING_BALL_DIAMETER
    np.testing.assert_allclose(strike_impulse(_record("bearing", 1.0), v, corner, r), expected, rtol=1e-12)
    with pytest.raises(ValueError, match="not an impulsive fault"):
        strike_impulse(_record("out_of_round", 1.0), v, corner, r)


def test_severity_scales_the_strike_linearly() -> None:
    # Severity scales the excitation: the sizes follow so that strikes grow in proportion to severity.
    for kind in ("flat_spot", "bearing", "loose_wheel"):
        j = [float(strike_impulse(_record(kind, s), np.array([0.8]), 5.0, 0.08)[0]) for s in (0.25, 0.5, 1.0)]
        assert j[1] / j[0] == pytest.approx(2.0, rel=0.03) and j[2] / j[1] == pytest.approx(2.0, rel=0.03)


def test_out_of_round_modulates_its_wheel_by_the_runout_acceleration() -> None:
    # Depth of the 1x/rev modulation = e omega^2 / g: the tyre's load and sound follow the corner's heave.
    omega = 12.0
    fault = _record("out_of_round", 1.0)
    config = AudioConfig(ambience=False, rt60_s=0.0, mic_noise_spl_db=float("-inf"), stems=True)
    tr = make_trace(2.0, omega, faults=(fault,))
    stems = render(tr, config, seed=1).stems
    healthy = render(make_trace(2.0, omega), config, seed=1).stems
    wheel = (healthy["motor"] + healthy["rolling"]).astype(np.float64)
    ratio = np.sqrt(np.mean(stems["faults"].astype(np.float64) ** 2) / np.mean(wheel**2))
    depth = fault.size * omega**2 / 9.81
    # The modulated part is one wheel's sound (a quarter of the power of four similar wheels) times
    # cos(phase): its RMS is depth x sqrt(1/2) x sqrt(1/4) of the four wheels' sound.
    assert ratio == pytest.approx(depth * np.sqrt(0.5) * 0.5, rel=0.35)


def test_the_audio_sounds_the_strikes_the_physics_recorded() -> None:
    # Two strikes of the trace's record ring at their times with amplitudes in the ratio of their impulses.
    fault = _record("flat_spot", 1.0)
    config = AudioConfig(ambience=False, rt60_s=0.0, mic_noise_spl_db=float("-inf"), stems=True)
    strikes = FaultStrikes(np.array([0.5, 1.5]), np.array([0, 0]), np.array([0.4, 1.2]))
    tr = dataclasses.replace(make_trace(2.0, 10.0, faults=(fault,)), fault_strikes=strikes)
    stem = np.abs(render(tr, config, seed=1).stems["faults"].astype(np.float64)).sum(axis=1)
    rate = 44100
    first, second = stem[int(0.5 * rate) : int(1.0 * rate)], stem[int(1.5 * rate) :]
    assert np.all(stem[: int(0.49 * rate)] == 0.0)
    assert np.all(stem[int(1.2 * rate) : int(1.49 * rate)] < 1e-3 * second.max())
    assert second.max() / first.max() == pytest.approx(3.0, rel=0.35)


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
