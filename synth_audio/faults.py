"""Wheel-fault sounds, each driven by the faulty wheel's phase and speed and scaled by severity.

- flat_spot: a thump once per wheel revolution (tyre thud + structural resonance).
- imbalance: the wheel's own sound amplitude-modulated at the rotation frequency, plus a structural buzz.
- bearing: an impulse train at defect_order x rotation frequency with slip jitter, exciting resonance_hz.
- loose_wheel: rattle whose rate peaks once per revolution as the hub wobbles.
- motor_degradation: gear-wear sidebands around the mesh tone at +- the wheel and shaft rotation rates.

Calibration criterion (physical; measured on stems, never on a detector's score): on a straight cruise
at 0.8 m/s on tile, the fault stem's power in its characteristic band (`fault_band`, below the
detectors' 2205 Hz Nyquist) over the healthy robot's drive sound (motor + rolling stems of the same
drive without the fault) in that band is L(s) = +16 dB + 30 log10(s): loud at severity 1 (+16 dB, a
fault that gets a robot taken out of service), clearly audible at 0.6 (+9.3 dB), level with the drive
at 0.3 (+0.3 dB: the band's power doubles, hard to hear under the environment), and under it below
that (the `hard` preset's 0.05..0.35). The law is `severity_gain` (amplitude s^1.5); `KIND_GAIN_DB`
sets the +16 dB per kind. Other speeds follow each model's own speed law. Measured by
`tests/synth_audio/fault_calibration_kit.py` and held (within +-1.5 dB at severity 1, +-2 dB at 0.3) by
`tests/synth_audio/test_fault_calibration.py`.
"""

from __future__ import annotations

import numpy as np

from sim.trace import FaultRecord
from synth_audio.drive import BLOCK, NOMINAL_SPEED, Drive
from synth_audio.dsp import damped_modes, overlap_add, resonate, white
from synth_audio.rolling import poisson_events

FAULT_SCALE = 3.0
"""Common fault sound scale at severity 1 and the nominal speed (each kind trimmed by KIND_GAIN_DB)."""
IMBALANCE_DEPTH = 0.8
"""Depth of the imbalance's amplitude modulation of its wheel's sound at severity 1 and the nominal speed."""
KIND_GAIN_DB: dict[str, float] = {
    "flat_spot": 20.3,
    "imbalance": -12.4,
    "bearing": 19.2,
    "loose_wheel": 16.8,
    "motor_degradation": 12.5,
}
"""Per-kind trim of the fault level, dB, calibrated to the criterion in the module docstring."""
REFERENCE_LEVEL_DB = 16.0
"""L(1): the fault's in-band level over the healthy drive sound at severity 1, dB (the criterion above)."""
_EDGE_S = 0.02
DETECTOR_NYQUIST_HZ = 2205.0
"""Nyquist frequency of the detectors' audio (44.1 kHz decimated by 10): calibration bands stay below it."""


def fault_band(fault: FaultRecord, rotation_hz: float, sample_rate: int) -> tuple[float, float]:
    """Characteristic band of a fault's sound, Hz, where its calibrated level is measured.

    One octave centred on the structural resonance the fault excites (`fault.resonance_hz`), or +-20 %
    around the gear-mesh tone (`defect_order` x `rotation_hz`) for motor degradation; clipped to
    [20 Hz, DETECTOR_NYQUIST_HZ] and to the sample rate's Nyquist.
    """
    top = min(DETECTOR_NYQUIST_HZ, 0.5 * sample_rate)
    if fault.kind == "motor_degradation":
        centre, half = float(fault.defect_order) * abs(rotation_hz), 1.2
    else:
        centre, half = float(fault.resonance_hz), float(np.sqrt(2.0))
    lo = float(np.clip(centre / half, 20.0, top))
    hi = float(np.clip(centre * half, 20.0, top))
    if hi <= lo:
        raise ValueError(f"fault band of {fault.kind!r} is empty: centre {centre:.1f} Hz, limit {top:.0f} Hz")
    return lo, hi


def severity_gain(severity: float) -> float:
    """Amplitude factor of a fault: severity^1.5, i.e. 30 log10(severity) dB (0.3: -15.7 dB, 0.1: -30 dB)."""
    return float(np.clip(severity, 0.0, 1.0)) ** 1.5


def window(drive: Drive, fault: FaultRecord) -> np.ndarray:
    """Gate at block boundaries: 1 inside [onset, onset + duration], with 20 ms ramps, else 0."""
    t = drive.block_time
    start, end = fault.onset, fault.onset + fault.duration
    rise = np.clip((t - start) / _EDGE_S + 1.0, 0.0, 1.0)
    fall = np.clip((end - t) / _EDGE_S + 1.0, 0.0, 1.0)
    return rise * fall


def _crossings(cycles: np.ndarray, offset: float) -> tuple[np.ndarray, np.ndarray]:
    """Fractional sample positions where `cycles - offset` (block-boundary values) crosses an integer.

    Returns (positions in samples, block index of each crossing); every crossing is found, in either
    direction of rotation.
    """
    c = cycles - offset
    c0, c1 = c[:-1], c[1:]
    k0, k1 = np.floor(c0), np.floor(c1)
    count = np.abs(k1 - k0).astype(np.int64)
    blocks = np.repeat(np.arange(c0.size), count)
    if blocks.size == 0:
        return np.zeros(0), blocks
    first = np.cumsum(count) - count
    rank = np.arange(blocks.size) - np.repeat(first, count)
    up = c1[blocks] > c0[blocks]
    target = np.where(up, k0[blocks] + 1 + rank, k0[blocks] - rank)
    frac = (target - c0[blocks]) / (c1[blocks] - c0[blocks])
    return (blocks + np.clip(frac, 0.0, 1.0)) * BLOCK, blocks


def _resonance(fault: FaultRecord, sample_rate: int, rng: np.random.Generator) -> np.ndarray:
    """Impulse response of the structural resonance the defect excites (unit peak)."""
    f = float(np.clip(fault.resonance_hz, 20.0, 0.45 * sample_rate))
    zeta = float(np.clip(fault.damping_ratio, 0.002, 0.5))
    t60 = 6.907755 / (2.0 * np.pi * f * zeta)
    length = int(min(t60, 0.25) * sample_rate) + 8
    return damped_modes(
        np.array([f]), np.array([t60]), np.ones(1), rng.uniform(0, 6.28, 1), sample_rate, length
    )


def fault_sound(
    drive: Drive, fault: FaultRecord, wheel_sound: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """Mono sound of one fault at its wheel, float32 (n,). `wheel_sound` is that wheel's nominal sound."""
    sr, n, w = drive.sample_rate, drive.n, fault.wheel
    gate = window(drive, fault)
    if fault.kind not in KIND_GAIN_DB:
        raise ValueError(f"unknown fault kind {fault.kind!r}; allowed: {', '.join(KIND_GAIN_DB)}")
    level = FAULT_SCALE * severity_gain(fault.severity) * 10.0 ** (KIND_GAIN_DB[fault.kind] / 20.0)
    if level == 0.0 or not np.any(gate > 0):
        return np.zeros(n, dtype=np.float32)
    speed = np.minimum(drive.speed_mps[w] / NOMINAL_SPEED, 3.0)
    kind = fault.kind
    if kind in ("flat_spot", "bearing"):
        order = 1.0 if kind == "flat_spot" else max(float(fault.defect_order), 0.1)
        pos, blocks = _crossings(drive.cycles[w] * order, float(rng.uniform()))
        amp = gate[blocks] * speed[blocks] ** (1.0 if kind == "flat_spot" else 0.6)
        if kind == "bearing":
            # Slip: rolling elements do not roll perfectly, so impacts jitter by ~1.5 % of the period.
            period = sr / np.maximum(order * np.abs(drive.rev_s[w][blocks]), 1e-3)
            pos = pos + rng.normal(0.0, 0.015, pos.size) * period
            amp = amp * rng.uniform(0.7, 1.3, pos.size)
            kernel = _resonance(fault, sr, rng)
        else:
            kernel = _resonance(fault, sr, rng)
            thud_len = int(0.08 * sr)
            kernel = np.pad(kernel, (0, max(thud_len - kernel.size, 0)))
            modes = (np.array([85.0, 190.0]), np.array([0.06, 0.04]), np.array([1.0, 0.5]), np.zeros(2))
            kernel[:thud_len] += 2.0 * damped_modes(*modes, sr, thud_len)
        return overlap_add(n, np.round(pos), amp * level * 1.5, kernel)
    if kind == "imbalance":
        phase = drive.phase(w, 1.0)
        mod = np.cos(np.float32(2 * np.pi) * phase + np.float32(rng.uniform(0, 6.28)))
        noise = resonate(white(rng, n), fault.resonance_hz, max(fault.damping_ratio, 0.01), sr)
        noise *= np.float32(0.3)
        # The wheel's own sound, modulated with depth IMBALANCE_DEPTH x severity gain (not over-modulated),
        # plus the structural buzz, trimmed to the calibration.
        depth = IMBALANCE_DEPTH * severity_gain(fault.severity)
        out = wheel_sound * mod * drive.ramp(depth * gate * np.minimum(speed, 1.5))
        out += noise * (1.0 + mod) * drive.ramp(level * gate * speed**2)
        return out
    if kind == "loose_wheel":
        wobble = 1.0 + np.cos(2 * np.pi * (drive.cycles[w][:-1] - rng.uniform()))
        expected = 35.0 * np.diff(drive.block_time) * speed[:-1] * wobble * gate[:-1]
        pos, amp = poisson_events(rng, expected, n)
        length = int(0.05 * sr)
        kernel = damped_modes(
            np.array([float(fault.resonance_hz), 1100.0, 2300.0, 3900.0, 160.0]),
            np.array([0.04, 0.04, 0.03, 0.02, 0.03]), np.array([1.0, 0.8, 1.0, 0.6, 0.7]),
            rng.uniform(0, 6.28, 5), sr, length,
        )  # fmt: skip
        return overlap_add(n, pos, amp * level * 0.5, kernel)
    # motor_degradation
    robot = drive.robot
    order = float(fault.defect_order) if fault.defect_order > 0 else robot.pinion_teeth * robot.gear_ratio
    mesh = np.sin(np.float32(2 * np.pi) * drive.phase(w, order))
    wheel_mod = np.cos(np.float32(2 * np.pi) * drive.phase(w, 1.0))
    shaft_mod = np.cos(np.float32(2 * np.pi) * drive.phase(w, robot.gear_ratio))
    mesh *= np.float32(0.6) + np.float32(0.5) * wheel_mod + np.float32(0.3) * shaft_mod
    return mesh * drive.ramp(level * 0.5 * gate * speed**0.8)
