"""Impacts (energy vs impulse, sample-accurate onset) and wheel faults (envelope-spectrum oracles)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from audio_trace_kit import contacts, make_trace
from signal_oracles import envelope_spectrum

from sim.trace import FaultRecord
from synth_audio import AudioConfig, render

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


def _fault_audio(
    kind: str, order: float, omega: float, quiet: AudioConfig, severity: float = 1.0
) -> np.ndarray:
    fault = FaultRecord(kind, 1, 1.0, 0.0, 10.0, order, 2500.0, 0.03)
    trace = make_trace(3.0, omega, faults=(fault,), surface="carpet")
    return render(trace, quiet, seed=5).samples[:, 1].astype(np.float64)


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


@pytest.mark.parametrize("kind", ["flat_spot", "imbalance", "bearing", "loose_wheel", "motor_degradation"])
def test_fault_sound_scales_with_severity(kind: str, quiet: AudioConfig) -> None:
    def level(severity: float) -> float:
        fault = FaultRecord(kind, 0, severity, 0.2, 1.0, 3.0, 2000.0, 0.05)
        stem = render(make_trace(1.5, 12.0, faults=(fault,)), quiet, seed=1).stems["faults"]
        return float(np.sqrt(np.mean(stem.astype(np.float64) ** 2)))

    quiet_level, mid, loud = level(0.0), level(0.3), level(1.0)
    assert quiet_level == 0.0
    assert 0.0 < mid < loud
    assert 20 * np.log10(loud / mid) > 6.0


def test_a_soft_slow_contact_longer_than_the_modal_ring_renders() -> None:
    # A pedestrian met at walking pace: the contact click (4 tau) outlasts the soft body's short ring.
    from synth_audio.impacts import MATERIALS, contact_time, impact

    tau = contact_time(MATERIALS["soft_body"], 0.01)
    sound = impact("soft_body", 5.0, 0.01, 44100, np.random.default_rng(0))
    assert sound.size >= int(4 * tau * 44100)
    assert np.all(np.isfinite(sound)) and float(np.abs(sound).max()) > 0
