"""Impacts (energy vs impulse, sample-accurate onset) and wheel faults (envelope-spectrum oracles)."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest
from audio_trace_kit import contacts, make_trace, transients
from signal_oracles import envelope_spectrum

from sim import faults
from sim.faults import IMPULSIVE_KINDS, defect_size
from sim.trace import FaultRecord, FaultStrikes, Trace
from sim.vocab import TRANSIENT_HEIGHT
from synth_audio import AudioConfig, render
from synth_audio.impacts import impact_impulse
from synth_audio.transients import strike_impulse

SR = 44100
CONTACT = (0.25, 0.08, 0.12)


@pytest.mark.parametrize("material", ["plaster", "metal", "cardboard", "soft_body"])
def test_impact_energy_grows_monotonically_with_impulse(material: str, quiet: AudioConfig) -> None:
    energies = []
    for impulse in (0.25, 0.5, 1.0, 2.0, 4.0, 8.0):
        trace = make_trace(1.0, 0.0, contact_events=contacts([0.3], [impulse], [CONTACT], [material]))
        energies.append(float(np.sum(render(trace, quiet, seed=4).stems["impacts"].astype(np.float64) ** 2)))
    assert all(b > a for a, b in itertools.pairwise(energies)), energies


@pytest.mark.parametrize("material", ["plaster", "concrete", "metal", "wood"])
@pytest.mark.parametrize("t_contact", [0.2, 0.41237])
def test_impact_onset_within_1ms_of_contact(material: str, t_contact: float, quiet: AudioConfig) -> None:
    trace = make_trace(0.8, 0.0, contact_events=contacts([t_contact], [3.0], [CONTACT], [material]))
    left = render(trace, quiet, seed=0).stems["impacts"][:, 0]
    onset = np.argmax(np.abs(left) > 0.05 * np.max(np.abs(left))) / SR
    travel = np.linalg.norm(np.asarray(CONTACT) - trace.robot.mic_pos_body[0]) / 343.0
    assert abs(onset - t_contact) < 1e-3
    assert abs(onset - (t_contact + travel)) < 1e-3
    assert not np.any(left[: int(t_contact * SR)])


def _faulty_trace(fault: FaultRecord, duration: float, omega: float, surface: str = "tile") -> Trace:
    """`make_trace` at constant `omega` with the fault and, for an impulsive one, the strikes its physics
    makes there: one each time the wheel passes the defect's angle (`defect_order` a revolution)."""
    trace = make_trace(duration, omega, faults=(fault,), surface=surface)
    if fault.kind not in IMPULSIVE_KINDS:
        return trace
    step = 2 * np.pi / fault.defect_order / omega
    times = np.arange(fault.onset + step, min(duration, fault.onset + fault.duration), step)
    r = float(trace.robot.wheel_radius[fault.wheel])
    impulse = faults.strike_impulse(fault, np.full(times.size, omega * r), trace.robot.mass / 4, r)
    strikes = FaultStrikes(times, np.full(times.size, fault.wheel), impulse)
    return dataclasses.replace(trace, fault_strikes=strikes)


def _record(kind: str, severity: float, onset: float, span: float, order: float, hz: float) -> FaultRecord:
    return FaultRecord(kind, 1, severity, onset, span, order, hz, 0.03, size=defect_size(kind, severity))


def _fault_audio(kind: str, order: float, omega: float, quiet: AudioConfig) -> np.ndarray:
    trace = _faulty_trace(_record(kind, 1.0, 0.0, 10.0, order, 2500.0), 3.0, omega, surface="carpet")
    return render(trace, quiet, seed=5).stems["faults"][:, 1].astype(np.float64)


def test_bearing_envelope_spectrum_peaks_at_the_defect_frequency(quiet: AudioConfig) -> None:
    omega, order = 20.0, 3.57
    defect = order * omega / (2 * np.pi)
    freqs, mag = envelope_spectrum(_fault_audio("bearing", order, omega, quiet), SR, (2000.0, 3000.0))
    band = (freqs > 2.0) & (freqs < 1.6 * defect)
    assert abs(freqs[band][np.argmax(mag[band])] - defect) < 0.4


def test_flat_spot_envelope_spectrum_peaks_at_the_rotation_frequency(quiet: AudioConfig) -> None:
    omega = 20.0
    rotation = omega / (2 * np.pi)
    freqs, mag = envelope_spectrum(_fault_audio("flat_spot", 1.0, omega, quiet), SR, (40.0, 400.0))
    band = (freqs > 1.0) & (freqs < 1.6 * rotation)
    assert abs(freqs[band][np.argmax(mag[band])] - rotation) < 0.4


@pytest.mark.parametrize("kind", ["flat_spot", "out_of_round", "bearing", "loose_wheel", "motor_degradation"])
def test_fault_sound_scales_with_severity(kind: str, quiet: AudioConfig) -> None:
    def level(severity: float) -> float:
        fault = _record(kind, severity, 0.2, 1.0, 3.0, 2000.0)
        stem = render(_faulty_trace(fault, 1.5, 12.0), quiet, seed=1).stems["faults"]
        return float(np.sqrt(np.mean(stem.astype(np.float64) ** 2)))

    quiet_level, mid, loud = level(0.0), level(0.3), level(1.0)
    assert quiet_level == 0.0
    assert 0.0 < mid < loud
    assert 20 * np.log10(loud / mid) > 8.0  # severity scales the excitation linearly: 10.5 dB


def test_a_soft_slow_contact_longer_than_the_modal_ring_renders() -> None:
    # A pedestrian met at walking pace: the contact click (4 tau) outlasts the soft body's short ring.
    from synth_audio.impacts import MATERIALS, contact_time, impact

    tau = contact_time(MATERIALS["soft_body"], 0.01)
    sound = impact("soft_body", 5.0, 0.01, 44100, np.random.default_rng(0))
    assert sound.size >= int(4 * tau * 44100)
    assert np.all(np.isfinite(sound)) and float(np.abs(sound).max()) > 0


@pytest.mark.parametrize("kind", ["seam", "threshold", "cable", "debris"])
def test_strike_impulse_is_the_corner_mass_turning_over_the_step(kind: str) -> None:
    # A wheel of radius r meets a step of height h at angle acos(1 - h/r): its centre's velocity turns by
    # that angle, so the corner of the robot gains dv_z = v sin(theta).
    h, r, v, m = TRANSIENT_HEIGHT[kind], 0.08, 1.2, 5.0
    expected = m * v * np.sqrt(1.0 - (1.0 - h / r) ** 2)
    assert strike_impulse(kind, h, v, r, m) == pytest.approx(expected, rel=1e-12)
    assert strike_impulse(kind, h, -v, r, m) == pytest.approx(expected, rel=1e-12)
    assert strike_impulse(kind, h, 0.0, r, m) == 0.0


def test_kerb_ramp_strike_is_the_drop_off_its_far_edge() -> None:
    h = TRANSIENT_HEIGHT["kerb_ramp"]
    assert strike_impulse("kerb_ramp", h, 0.5, 0.08, 5.0) == pytest.approx(5.0 * np.sqrt(2 * 9.81 * h))


def test_impact_impulse_keeps_a_bounce_and_drops_the_push() -> None:
    # A 20 kg robot at 0.7 m/s into a wall: a bounce exchanges up to 2 m v; a long push adds no bang.
    assert impact_impulse(20.0, 0.7, 20.0, None) == pytest.approx(20.0)
    assert impact_impulse(300.0, 0.7, 20.0, None) == pytest.approx(2 * 20.0 * 0.7)
    # A free 4 kg box: the reduced mass 20 * 4 / 24 limits what the hit can exchange.
    assert impact_impulse(300.0, 0.7, 20.0, 4.0) == pytest.approx(2 * (20 * 4 / 24) * 0.7)


def test_a_wall_hit_is_louder_than_a_cable_crossed_faster(quiet: AudioConfig) -> None:
    # Same robot, same microphones: a 0.7 m/s wall hit against a wheel crossing a cable at 1.2 m/s.
    radius = 0.06
    omega = 1.2 / radius
    corner = 12.0 / 4
    cable = make_trace(
        1.0, omega, transient_events=transients([0.3], [0], [7.0], ["cable"])
    )  # MuJoCo's 7 N s holds the carried weight: it must not set the loudness
    hit = impact_impulse(14.0, 0.7, 12.0, None)
    wall = make_trace(
        1.0, omega, contact_events=contacts([0.3], [hit], [CONTACT], ["plaster"], normal_speed=0.7)
    )
    e_cable = float(np.sum(render(cable, quiet, seed=1).stems["transients"].astype(np.float64) ** 2))
    e_wall = float(np.sum(render(wall, quiet, seed=1).stems["impacts"].astype(np.float64) ** 2))
    strike = strike_impulse("cable", TRANSIENT_HEIGHT["cable"], 1.2, radius, corner)
    assert strike < 0.2 * hit
    assert 10 * np.log10(e_wall / e_cable) > 10.0


@pytest.mark.parametrize("phase", [0.0, 1.3, 4.0])
def test_a_spalled_bearing_grinds_loudest_where_its_balls_strike(phase: float, quiet: AudioConfig) -> None:
    # The physics strikes where order x (angle - phase) is a multiple of 2 pi (`sim.faults`); the grinding
    # swells at those same angles whatever the spall's angular position.
    omega, order = 20.0, 3.57
    fault = dataclasses.replace(_record("bearing", 1.0, 0.0, 10.0, order, 1600.0), phase=phase)
    trace = make_trace(3.0, omega, faults=(fault,), surface="carpet")  # no strikes: the grinding alone
    growl = render(trace, quiet, seed=5).stems["faults"][:, 1].astype(np.float64)
    t = np.arange(growl.size) / SR
    keep = t > 0.5
    at_defect = np.mod(order * (omega * t[keep] - phase), 2 * np.pi)  # 0 at each strike
    power = growl[keep] ** 2
    bins = np.minimum((at_defect / (2 * np.pi) * 8).astype(int), 7)
    mean = np.bincount(bins, power, 8) / np.bincount(bins, minlength=8)
    loudest = (np.argmax(mean) + 0.5) / 8  # of a defect period
    assert min(loudest, 1.0 - loudest) < 0.13, mean


def test_a_bearing_growls_over_its_gate_as_the_whole_episode_filtered_would() -> None:
    # The growl is filtered over the gate's span only, from `_GROWL_SETTLE_S` before it
    # (`synth_audio.faults`): against the same band-pass run from the episode's first sample, it is equal to
    # float32 precision.
    from synth_audio import faults as fault_sounds
    from synth_audio.drive import build_drive

    fault = _record("bearing", 1.0, 1.2, 0.6, 3.57, 1600.0)
    trace = make_trace(2.5, 20.0, faults=(fault,), surface="carpet")
    n = round(trace.duration * SR)
    drive = build_drive(
        trace.robot, trace.time, trace.wheel_angle, trace.wheel_speed, trace.wheel_torque, n, SR
    )  # fmt: skip
    wheel_sound = np.random.default_rng(3).standard_normal(n).astype(np.float32)
    gate = fault_sounds.window(drive, fault)
    a, b = fault_sounds._gated_span(drive, gate)
    assert 0 < a < 1.2 * SR - 0.02 * SR and 1.8 * SR + 0.02 * SR < b < n  # the gate, its ramps and a block
    settled = fault_sounds._growl(drive, fault, wheel_sound, gate, (a, b))
    whole = fault_sounds._growl(drive, fault, wheel_sound, gate, (0, n))
    assert not np.any(whole[:a]) and not np.any(whole[b:])
    assert np.allclose(settled, whole[a:b], rtol=0.0, atol=1e-6 * float(np.max(np.abs(whole))))
