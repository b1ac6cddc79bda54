"""Wheel-fault sounds from the defect's physical size, on the common impact scale.

Each fault's sound follows a level law from its physical parameters (severity s in 0..1 scales the defect;
m is the robot's mass, W its wheel count, r the wheel radius, v the faulty wheel's rim speed, omega = v / r):

- flat_spot: a flat of depth h = s `FLAT_DEPTH_M` on the tyre. Once per revolution the wheel drops into it
  and strikes its far edge like a step of height h: the wheel's corner of the robot exchanges
  J = (m / W) v sin(acos(1 - h / r)) (the same law as a benign bump, `transients.strike_impulse`).
- loose_wheel: a hub with play delta = s `PLAY_M`. The wheel falls through its play and clunks: each clunk
  exchanges J = `WHEEL_MASS` sqrt(2 g delta); clunks come `RATTLE_RATE` per second at the nominal speed, in
  proportion to speed, most when the wobble peaks once per revolution.
- bearing: an outer-race spall of length l = s `SPALL_M`. Each rolling element crossing it strikes the
  spall's edge at angle asin(l / d) (d the ball diameter): J = (m / W) v_c l / d, with v_c = omega
  D_pitch / 4 the balls' speed over the race; at the ball-pass order (BPFO) with 1-2 % slip and jitter.
- imbalance: an eccentric mass m e = s `sim.trace.IMBALANCE_ME` loads and unloads its wheel once per
  revolution with F = m e omega^2: the wheel's rolling and motor sound is amplitude-modulated at the
  rotation rate with depth F / (m g / W) (the tyre's noise follows its load); the IMU feels F as forward
  and vertical vibration at the rotation rate (`sim.faults`).
- motor_degradation: worn gears raise the gear-mesh transmission error to (1 + s `WEAR_GAIN`) times a
  healthy pair's: the mesh tone grows by s `WEAR_GAIN` times the healthy mesh tone (`motor._MESH`),
  modulated at the wheel and motor shaft rates (eccentric worn gears).

The impulsive faults ring through a kernel of unit impulse on `impacts.IMPACT_SCALE`, like collisions and
bumps. `tests/synth_audio/fault_calibration_kit.py` prints each fault's level in its characteristic band
(`fault_band`) over the healthy drive at 0.8 m/s; severity 1 of every kind is detectable in principle, at
least 6 dB over the healthy drive in its band in the audio or in the IMU (the IMU criteria are those of
`sim.faults`); `tests/synth_audio/test_fault_calibration.py` holds it.
"""

from __future__ import annotations

import numpy as np

from sim.trace import BEARING_BALL_DIAMETER, BEARING_PITCH_DIAMETER, IMBALANCE_ME, FaultRecord
from synth_audio.drive import BLOCK, GRAVITY, NOMINAL_SPEED, Drive
from synth_audio.dsp import overlap_add
from synth_audio.impacts import IMPACT_SCALE, Material, struck_response
from synth_audio.motor import MESH_WEIGHT, load_envelope
from synth_audio.rolling import poisson_events

FLAT_DEPTH_M = 0.003
"""Depth of the flat at severity 1, m (a 44 mm-long flat on an 80 mm wheel: a tyre that skidded locked)."""
PLAY_M = 0.0025
"""Play of the loose hub at severity 1, m (a wheel that visibly wobbles)."""
WHEEL_MASS = 1.1
"""Mass of a wheel and hub, kg (the robot model's wheel): what clunks in a loose hub's play."""
SPALL_M = 0.003
"""Length of the outer-race spall at severity 1, m (half the ball diameter: a bearing to replace)."""
WEAR_GAIN = 3.0
"""Growth of the gear-mesh transmission error at severity 1, in units of a healthy pair's (+12 dB)."""
RATTLE_RATE = 35.0
"""Clunks per second of a loose hub at the nominal speed (proportional to speed)."""
BEARING_SLIP = (0.01, 0.02)
"""Range of the rolling elements' slip: the ball-pass rate is this fraction below the kinematic BPFO."""
BEARING_JITTER = 0.015
"""Standard deviation of each ball pass's timing, in ball-pass periods."""
DETECTOR_NYQUIST_HZ = 2205.0
"""Nyquist frequency of the detectors' audio (44.1 kHz decimated by 10): characteristic bands stay below."""
_EDGE_S = 0.02
_REFERENCE_SPEED = 0.8
"""Approach speed of the kernels' contact time, m/s (the strike speed changes only the impulse)."""


def band_power(x: np.ndarray, rate: float, band: tuple[float, float]) -> float:
    """Energy of (n,) or (n, C) samples between band[0] (included) and band[1] (excluded) Hz, summed over the
    channels: the sum of |rfft|^2 over the band's bins (Parseval up to the factor 2 / n of one-sided bins).
    The measure of a fault's level in its `fault_band` (the calibration kit's and the audit's)."""
    spectrum = np.abs(np.fft.rfft(np.asarray(x, dtype=np.float64), axis=0)) ** 2
    freqs = np.fft.rfftfreq(np.asarray(x).shape[0], 1.0 / rate)
    keep = (freqs >= band[0]) & (freqs < band[1])
    return float(spectrum[keep].sum())


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


def _kernel(fault: FaultRecord, sample_rate: int, rng: np.random.Generator) -> np.ndarray:
    """Sound of one strike of 1 N s for an impulsive fault: what its defect rings, on `IMPACT_SCALE`."""
    f = float(np.clip(fault.resonance_hz, 20.0, 0.45 * sample_rate))
    t60 = float(min(6.907755 / (2.0 * np.pi * f * float(np.clip(fault.damping_ratio, 0.002, 0.5))), 0.25))
    if fault.kind == "flat_spot":  # tyre thud and the hub's resonance; the chassis rings too
        material = Material((85.0, 190.0, f), (0.06, 0.04, t60), (1.0, 0.5, 0.6), 0.003, 0.3, 1.0)
        body = 1.0
    elif fault.kind == "bearing":  # steel on steel: a short click through the hub's resonance
        material = Material((f, 1.5 * f), (t60, 0.5 * t60), (1.0, 0.4), 0.0002, 0.6, 1.0)
        body = 0.3
    else:  # loose_wheel: metal clunk of the hub in its seat
        material = Material((f, 1100.0, 2300.0, 3900.0, 160.0), (0.04, 0.04, 0.03, 0.02, 0.03),
                            (1.0, 0.8, 1.0, 0.6, 0.7), 0.0005, 0.6, 1.0)  # fmt: skip
        body = 0.5
    return struck_response(material, 1.0, _REFERENCE_SPEED, sample_rate, rng, IMPACT_SCALE, body)


def strike_impulses(drive: Drive, fault: FaultRecord, speed_mps: np.ndarray) -> np.ndarray:
    """Impulse of each strike of an impulsive fault (the level laws above) at rim speeds `speed_mps`, N s."""
    robot = drive.robot
    corner = float(robot.mass) / max(len(robot.wheel_names), 1)
    radius = float(robot.wheel_radius[fault.wheel])
    s = float(np.clip(fault.severity, 0.0, 1.0))
    v = np.abs(np.asarray(speed_mps, dtype=np.float64))
    if fault.kind == "flat_spot":
        h = s * FLAT_DEPTH_M
        return corner * v * np.sin(np.arccos(max(1.0 - h / radius, -1.0)))
    if fault.kind == "bearing":
        ball_speed = v / radius * BEARING_PITCH_DIAMETER / 4.0
        return corner * ball_speed * min(s * SPALL_M / BEARING_BALL_DIAMETER, 1.0)
    if fault.kind == "loose_wheel":
        return np.full(v.shape, WHEEL_MASS * np.sqrt(2.0 * GRAVITY * s * PLAY_M))
    raise ValueError(f"{fault.kind!r} is not an impulsive fault; allowed: flat_spot, bearing, loose_wheel")


def fault_sound(
    drive: Drive, fault: FaultRecord, wheel_sound: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """Mono sound of one fault at its wheel, float32 (n,). `wheel_sound` is that wheel's nominal sound."""
    sr, n, w = drive.sample_rate, drive.n, fault.wheel
    kinds = ("flat_spot", "imbalance", "bearing", "loose_wheel", "motor_degradation")
    if fault.kind not in kinds:
        raise ValueError(f"unknown fault kind {fault.kind!r}; allowed: {', '.join(kinds)}")
    gate = window(drive, fault)
    if fault.severity <= 0.0 or not np.any(gate > 0):
        return np.zeros(n, dtype=np.float32)
    kind = fault.kind
    rim = drive.speed_mps[w]
    if kind in ("flat_spot", "bearing"):
        order = 1.0 if kind == "flat_spot" else max(float(fault.defect_order), 0.1)
        if kind == "bearing":
            order *= 1.0 - float(rng.uniform(*BEARING_SLIP))
        pos, blocks = _crossings(drive.cycles[w] * order, float(rng.uniform()))
        if kind == "bearing":
            period = sr / np.maximum(order * np.abs(drive.rev_s[w][blocks]), 1e-3)
            pos = pos + rng.normal(0.0, BEARING_JITTER, pos.size) * period
        amp = gate[blocks] * strike_impulses(drive, fault, rim[blocks])
        return overlap_add(n, np.round(pos), amp, _kernel(fault, sr, rng))
    if kind == "loose_wheel":
        speed = np.minimum(rim / NOMINAL_SPEED, 3.0)
        wobble = 1.0 + np.cos(2 * np.pi * (drive.cycles[w][:-1] - rng.uniform()))
        expected = RATTLE_RATE * np.diff(drive.block_time) * speed[:-1] * wobble * gate[:-1]
        pos, amp = poisson_events(rng, expected, n)
        amp = amp * strike_impulses(drive, fault, np.zeros(pos.size))
        return overlap_add(n, pos, amp, _kernel(fault, sr, rng))
    if kind == "imbalance":
        robot = drive.robot
        omega = np.abs(drive.rev_s[w]) * 2.0 * np.pi
        load = float(robot.mass) * GRAVITY / max(len(robot.wheel_names), 1)
        depth = np.minimum(fault.severity * IMBALANCE_ME * omega**2 / load, 1.0)
        mod = np.cos(np.float32(2 * np.pi) * drive.phase(w, 1.0) + np.float32(rng.uniform(0, 6.28)))
        return wheel_sound * mod * drive.ramp(depth * gate)
    # motor_degradation
    robot = drive.robot
    order = float(fault.defect_order) if fault.defect_order > 0 else robot.pinion_teeth * robot.gear_ratio
    mesh = np.sin(np.float32(2 * np.pi) * drive.phase(w, order) + np.float32(rng.uniform(0, 6.28)))
    wheel_mod = np.cos(np.float32(2 * np.pi) * drive.phase(w, 1.0))
    shaft_mod = np.cos(np.float32(2 * np.pi) * drive.phase(w, robot.gear_ratio))
    mesh *= np.float32(1.0) + np.float32(0.4) * wheel_mod + np.float32(0.25) * shaft_mod
    speed, load_factor = load_envelope(drive, w)
    tone_env = speed * (0.7 + 0.3 * load_factor)
    return mesh * drive.ramp(MESH_WEIGHT * fault.severity * WEAR_GAIN * tone_env * gate)
