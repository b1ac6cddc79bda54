"""Drive motor and gearbox: shaft harmonics, torque-ripple and gear-mesh tones, PWM whine, brush noise.

Every tone is a harmonic of the motor shaft phase (wheel phase x gear ratio), so it is phase-continuous and
tracks the wheel speed; amplitudes follow the wheel speed and the motor load (torque). All tones that stay
below Nyquist are read from one wavetable of the shaft phase (cost independent of the harmonic count).
"""

from __future__ import annotations

import numpy as np

from synth_audio.drive import BLOCK, NOMINAL_SPEED, Drive
from synth_audio.dsp import frac_phase, harmonic_table, wavetable

_SHAFT = ((1, 0.18), (2, 0.28), (3, 0.1))
"""(harmonic of the shaft, weight): mechanical unbalance and misalignment."""
_ELECTRICAL = ((2, 0.55), (4, 0.22), (6, 0.1))
"""(multiple of the electrical frequency, weight): torque ripple / cogging."""
_MESH = ((1, 0.45), (2, 0.2), (3, 0.08))
"""(multiple of the gear-mesh frequency, weight)."""
_PWM_LEVEL = 0.07
_BRUSH_LEVEL = 0.12
_NYQUIST_FRACTION = 0.45


def tone_table(drive: Drive, unit_rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(shaft harmonic numbers, amplitudes, phases) of the motor tones, with the unit's own weighting."""
    robot = drive.robot
    ks = [float(k) for k, _ in _SHAFT]
    ks += [float(k * robot.motor_pole_pairs) for k, _ in _ELECTRICAL]
    ks += [float(k * robot.pinion_teeth) for k, _ in _MESH]
    weights = [w for _, w in _SHAFT + _ELECTRICAL + _MESH]
    jitter = 10.0 ** (unit_rng.normal(0.0, 2.0, len(ks)) / 20.0)
    phases = unit_rng.uniform(0.0, 2.0 * np.pi, len(ks))
    merged: dict[float, tuple[float, float]] = {}
    for k, w, j, p in zip(ks, weights, jitter, phases, strict=True):
        a, ph = merged.get(k, (0.0, float(p)))
        merged[k] = (a + w * float(j), ph)
    order = sorted(merged)
    return (
        np.array(order),
        np.array([merged[k][0] for k in order]),
        np.array([merged[k][1] for k in order]),
    )


def load_envelope(drive: Drive, wheel: int) -> tuple[np.ndarray, np.ndarray]:
    """(speed factor, load factor) at block boundaries for one wheel."""
    speed = np.minimum(drive.speed_mps[wheel] / NOMINAL_SPEED, 3.0) ** 0.8
    load = np.minimum(np.abs(drive.torque[wheel]) / 0.3, 4.0)
    return speed, load


def motor_wheel(
    drive: Drive,
    wheel: int,
    unit_rng: np.random.Generator,
    brush_noise: np.ndarray,
    pwm_offset: float,
) -> np.ndarray:
    """Mono motor + gearbox sound of one wheel's drive, float32 (n,)."""
    robot = drive.robot
    sr = drive.sample_rate
    limit = _NYQUIST_FRACTION * sr
    speed, load = load_envelope(drive, wheel)
    shaft_hz = np.abs(drive.rev_s[wheel]) * robot.gear_ratio
    top = float(np.max(shaft_hz))
    shaft = drive.phase(wheel, robot.gear_ratio)
    ks, amps, phases = tone_table(drive, unit_rng)
    safe = ks * top <= limit
    tonal = wavetable(shaft, harmonic_table(ks[safe], amps[safe], phases[safe]))
    for k, amp, ph in zip(ks[~safe], amps[~safe], phases[~safe], strict=True):
        gate = drive.ramp((k * shaft_hz <= limit).astype(np.float32) * amp)
        tone = np.sin(np.float32(2.0 * np.pi * k) * shaft + np.float32(ph))
        tone *= gate
        tonal += tone
    tonal *= drive.ramp(speed * (0.6 + 0.4 * load))
    # Brush noise, modulated at the commutation rate (2 x pole pairs per shaft revolution).
    comm = drive.phase(wheel, robot.gear_ratio * 2 * robot.motor_pole_pairs)
    tmp = np.cos(np.float32(2.0 * np.pi) * comm)
    tmp *= np.float32(0.4)
    tmp += np.float32(1.0)
    tmp *= brush_noise
    tmp *= drive.ramp(_BRUSH_LEVEL * speed)
    tonal += tmp
    # PWM carrier with sidebands at carrier +- 2 x electrical frequency.
    carrier_hz = robot.pwm_hz * (1.0 + 0.002 * unit_rng.normal())
    if carrier_hz < 0.46 * sr and np.any(drive.torque[wheel] != 0):
        carrier = frac_phase((carrier_hz * drive.block_time + pwm_offset)[None, :], BLOCK, drive.n)[0]
        tmp = np.cos(np.float32(2.0 * np.pi) * carrier)
        if carrier_hz + 2.0 * top * robot.motor_pole_pairs < 0.48 * sr:
            elec = drive.phase(wheel, robot.gear_ratio * robot.motor_pole_pairs)
            side = np.cos(np.float32(4.0 * np.pi) * elec)
            side *= np.float32(0.5)
            side += np.float32(1.0)
            tmp *= side
        tmp *= drive.ramp(_PWM_LEVEL * np.minimum(np.abs(drive.torque[wheel]) / 0.3, 4.0))
        tonal += tmp
    return tonal
