"""Drive motor and gearbox: shaft harmonics, torque-ripple and gear-mesh tones, PWM whine, brush noise.

Every tone is a harmonic of the motor shaft phase (wheel phase x gear ratio), so it is phase-continuous and
tracks the wheel speed; amplitudes follow the wheel speed and the motor load (torque). All tones that stay
below Nyquist are read from one wavetable of the shaft phase (cost independent of the harmonic count).

The PWM whine follows the drivers' current, which is the load, but never falls below the holding current
of a powered driver (`HOLD_LOAD` of the reference load): a stopped robot still whines faintly, the whine
envelope being `_PWM_LEVEL * max(load, HOLD_LOAD)` for the whole episode (a trace is of a powered robot).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from synth_audio import kernels
from synth_audio.drive import BLOCK, NOMINAL_SPEED, Drive
from synth_audio.dsp import TABLE_SIZE, unit_table

_SHAFT = ((1, 0.18), (2, 0.28), (3, 0.1))
"""(harmonic of the shaft, weight): mechanical unbalance and misalignment."""
_ELECTRICAL = ((2, 0.55), (4, 0.22), (6, 0.1))
"""(multiple of the electrical frequency, weight): torque ripple / cogging."""
MESH_WEIGHT = 0.45
"""Amplitude of the healthy gear-mesh tone (first harmonic) relative to the motor's tone envelope."""
_MESH = ((1, MESH_WEIGHT), (2, 0.2), (3, 0.08))
"""(multiple of the gear-mesh frequency, weight)."""
_PWM_LEVEL = 0.07
HOLD_LOAD = 0.2
"""Holding current of a powered motor driver at standstill, as a fraction of the reference load."""
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
    load = np.minimum(np.abs(drive.torque[wheel]), 4.0)
    return speed, load


def motor_wheel(
    drive: Drive,
    wheel: int,
    unit_rng: np.random.Generator,
    brush_noise: np.ndarray,
    carrier: np.ndarray | None,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Mono motor + gearbox sound of one wheel's drive, float32 (n,), added into `out` if given."""
    robot = drive.robot
    sr = drive.sample_rate
    limit = _NYQUIST_FRACTION * sr
    speed, load = load_envelope(drive, wheel)
    shaft_hz = np.abs(drive.rev_s[wheel]) * robot.gear_ratio
    top = float(np.max(shaft_hz))
    ks, amps, phases = tone_table(drive, unit_rng)
    safe = ks * top <= limit
    table = unit_table(ks[safe], amps[safe], phases[safe])
    gated = [
        ((k * shaft_hz <= limit).astype(np.float64) * a, k, p)
        for k, a, p in zip(ks[~safe], amps[~safe], phases[~safe], strict=True)
    ]
    tone_env = speed * (0.7 + 0.3 * load)
    brush_env = _BRUSH_LEVEL * speed
    pwm = carrier is not None  # the drivers switch whenever the robot is powered
    sidebands = robot.pwm_hz + 2.0 * top * robot.motor_pole_pairs < 0.48 * sr
    pwm_env = _PWM_LEVEL * np.maximum(load, HOLD_LOAD)
    modulations = _modulations(int(robot.motor_pole_pairs), bool(sidebands))
    if out is None:
        out = np.zeros(drive.n, dtype=np.float32)
    carrier_or_none = carrier if pwm and carrier is not None else _SILENT
    shaft_cycles = drive.cycles[wheel] * robot.gear_ratio
    for span in drive.spans():
        a, b = span
        if gated:
            shaft = drive.phase(wheel, robot.gear_ratio, span)
            for gate, k, ph in gated:
                tone = np.sin(np.float32(2.0 * np.pi * k) * shaft + np.float32(ph))
                drive.add_ramped(out[a:b], tone, gate * tone_env, span)
        kernels.motor_mix(
            out[a:b], drive.boundaries(shaft_cycles, span), table, modulations,
            drive.boundaries(tone_env, span), brush_noise[a:b], drive.boundaries(brush_env, span),
            carrier_or_none[a:b], drive.boundaries(pwm_env, span), BLOCK,
        )  # fmt: skip
    return out


_SILENT = np.zeros(0, dtype=np.float32)


@functools.lru_cache(maxsize=16)
def _modulations(pole_pairs: int, sidebands: bool) -> np.ndarray:
    """(P, 2) float32 (brush, PWM sideband) modulations as functions of the shaft phase, read-only, for
    `kernels.motor_mix`: brush noise pulses at the commutation rate (2 x pole pairs per shaft revolution);
    the PWM sidebands sit at carrier +- 2 x the electrical frequency (pole pairs per shaft revolution), a
    flat 1 without sidebands. Defined on the tones' TABLE_SIZE points and read with their index, they repeat
    every P = TABLE_SIZE / gcd(TABLE_SIZE, 2 x pole pairs) points, so one period is kept (the whole table
    where the float32 values do not repeat exactly): the same samples from a table that stays in cache."""
    x = np.arange(TABLE_SIZE) / TABLE_SIZE
    full = np.ones((TABLE_SIZE, 2), dtype=np.float32)
    full[:, 0] = 1.0 + 0.4 * np.cos(2.0 * np.pi * 2 * pole_pairs * x)
    if sidebands:
        full[:, 1] = 1.0 + 0.5 * np.cos(4.0 * np.pi * pole_pairs * x)
    period = TABLE_SIZE // math.gcd(TABLE_SIZE, 2 * pole_pairs)
    if not np.array_equal(
        full.reshape(-1, period, 2), np.broadcast_to(full[:period], (TABLE_SIZE // period, period, 2))
    ):
        period = TABLE_SIZE
    out = np.ascontiguousarray(full[:period])
    out.setflags(write=False)
    return out


def pwm_carrier(drive: Drive, phase: float) -> np.ndarray | None:
    """The drivers' shared PWM carrier cos(2 pi f_pwm t + phase) over the render, or None above Nyquist."""
    hz = drive.robot.pwm_hz
    if hz >= 0.46 * drive.sample_rate:
        return None
    out = np.zeros(drive.n, dtype=np.float32)
    kernels.sinusoid_into(out, phase / (2.0 * np.pi), hz / drive.sample_rate, 1.0, True)
    return out
