"""Wheel faults modelled in the physics: forces and torques applied to the faulty wheel, per step.

Each control period the rollout asks every active fault for its forces over the next `k` steps. Wheel
angles inside the period are extrapolated from the current angle and speed (the period is 40 ms, so
the error is a fraction of a degree), which keeps the work vectorised: one numpy expression per fault
and period, no per-step Python.

Models (severity s in 0..1 scales every effect; s == 0 applies nothing at all):
- flat_spot: a flat on the tyre; once per revolution the wheel drops into the flat and strikes back,
  a vertical force pulse (down, then up) over the flat's arc.
- imbalance: an eccentric mass m*e rotating with the wheel; force m*e*omega^2 rotating in the wheel plane.
- bearing: an outer-race defect; an impulse each time a rolling element passes it, at BPFO order
  (n/2)(1 - d/D cos(alpha)) per wheel revolution.
- loose_wheel: a loose hub; wobble (yaw torque and lateral force at the rotation frequency) and rattle
  (random impulses, more frequent with speed).
- motor_degradation: worn gears and a weak motor; torque loss, extra drag, torque ripple once per motor
  shaft revolution, and speed droop of the commanded wheel speed.

Calibration criterion (physical; measured on traces, never on a detector's score): on a straight cruise
at 0.8 m/s on tile, a severity-1 fault raises the IMU z-velocity amplitude at its frequency (rotation
frequency for the flat spot, BPFO x rotation for the bearing, motor shaft frequency for worn gears) at
least 4x over the healthy drive, and the loose wheel's rattle raises the z-velocity RMS at least 4x.
Vertical forces on a wheel resting on the floor reach the chassis only past the wheel's share of the
weight (~50 N), so the impulsive faults are sized to exceed it at severity 1 and mostly stay under it
at 0.3 (hard to feel). Imbalance is exempt: a realistic m e (a 375 g lump on the rim) at ~1.6 rev/s
gives ~3 N, which the floor absorbs vertically (z-velocity line ~1.1x); it shows as forward
acceleration at the rotation frequency and in the audio. Measured by `tests/synth_audio/
fault_calibration_kit.py` and held by `tests/sim/test_faults.py`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.scenario import Fault
from sim.trace import (
    BEARING_BALL_DIAMETER,
    BEARING_BALLS,
    BEARING_CONTACT_ANGLE,
    BEARING_PITCH_DIAMETER,
    IMBALANCE_ME,
    FaultRecord,
    RobotInfo,
)

FLAT_SPOT_FORCE = 200.0
"""Peak vertical force of the flat-spot strike at severity 1 and full speed, N."""
FLAT_SPOT_ARC = 0.5
"""Arc of the flat, rad."""
BEARING_IMPULSE = 1.0
"""Vertical impulse per ball pass at severity 1 and full speed, N s (a spalled race: each pass lifts the
wheel's share of the weight for one step, so the impulse reaches the chassis instead of the floor)."""
LOOSE_WOBBLE_TORQUE = 3.0
"""Wobble yaw torque amplitude at severity 1, N m."""
LOOSE_WOBBLE_FORCE = 25.0
"""Wobble lateral force amplitude at severity 1, N."""
LOOSE_RATTLE_FORCE = 360.0
"""Rattle impulse force at severity 1 (applied for one step), N: a clunk of the hub in its play, strong
enough to unload the wheel's share of the weight so the chassis feels it."""
MOTOR_TORQUE_LOSS = 0.4
"""Fraction of motor torque lost at severity 1."""
MOTOR_RIPPLE = 0.25
"""Torque ripple amplitude at severity 1, fraction of the motor torque."""
MOTOR_DRAG = 0.15
"""Extra viscous drag at severity 1, N m s/rad."""
MOTOR_DROOP = 0.25
"""Fraction of commanded speed lost at severity 1."""
FULL_SPEED = 12.0
"""Wheel speed (rad/s) at which speed-scaled effects reach full size."""

RESONANCE: dict[str, tuple[float, float]] = {
    "flat_spot": (160.0, 0.08),
    "imbalance": (28.0, 0.12),
    "bearing": (1600.0, 0.03),
    "loose_wheel": (420.0, 0.06),
    "motor_degradation": (1150.0, 0.04),
}
"""Structural resonance (Hz) and damping ratio each fault excites, before per-unit variation.

All lie below 2.2 kHz, the Nyquist frequency of the detectors' 4410 Hz audio (the paper decimates by 10):
a hub/chassis mode of a small aluminium-frame robot, not the kHz ring of an isolated bearing race."""


def bpfo_order() -> float:
    """Ball-pass frequency of the outer race, in events per wheel revolution."""
    ratio = BEARING_BALL_DIAMETER / BEARING_PITCH_DIAMETER * math.cos(BEARING_CONTACT_ANGLE)
    return BEARING_BALLS / 2.0 * (1.0 - ratio)


def defect_order(kind: str, robot: RobotInfo) -> float:
    """Defect events per wheel revolution for a fault kind."""
    if kind == "bearing":
        return bpfo_order()
    if kind == "motor_degradation":
        return float(robot.pinion_teeth * robot.gear_ratio)
    return 1.0


def fault_record(fault: Fault, robot: RobotInfo, episode: float) -> FaultRecord:
    """The trace's record of a fault, with the frequencies the audio stage needs."""
    rng = np.random.default_rng([0xFA17, robot.unit_id, fault.wheel])
    f0, zeta = RESONANCE[fault.kind]
    return FaultRecord(
        kind=fault.kind,
        wheel=fault.wheel,
        severity=float(fault.severity),
        onset=float(fault.onset),
        duration=float(min(fault.duration, episode - fault.onset)),
        defect_order=defect_order(fault.kind, robot),
        resonance_hz=float(f0 * (1.0 + rng.uniform(-0.05, 0.05))),
        damping_ratio=float(zeta),
    )


@dataclass
class FaultForcing:
    """Per-step forcing of one fault (internal state: its rattle generator)."""

    fault: Fault
    """The fault."""
    order: float
    """Defect order (events per wheel revolution)."""
    gear_ratio: float
    """Motor revolutions per wheel revolution (motor ripple)."""
    rng: np.random.Generator
    """Random draws of this fault (rattle), independent of every other stream."""

    def active(self, t: np.ndarray) -> np.ndarray:
        """(k,) 1.0 where the fault acts at times `t`, else 0.0."""
        f = self.fault
        return ((t >= f.onset) & (t < f.onset + f.duration)).astype(np.float64)

    def apply(
        self,
        t: np.ndarray,
        theta: np.ndarray,
        omega: float,
        forward: np.ndarray,
        lateral: np.ndarray,
        motor_torque: float,
        xfrc: np.ndarray,
        qfrc: np.ndarray,
        dt: float,
    ) -> None:
        """Add this fault's forcing over k steps.

        Args:
            t: (k,) step start times.
            theta: (k,) extrapolated wheel angles.
            omega: wheel speed now, rad/s.
            forward: (3,) robot forward axis in the world.
            lateral: (3,) robot left axis in the world.
            motor_torque: wheel motor torque now, N m.
            xfrc: (k, 6) Cartesian force/torque on the wheel body (world frame), added to.
            qfrc: (k,) generalised force on the wheel joint, added to.
            dt: physics step, s.
        """
        on = self.active(t)
        if not on.any():
            return
        s = self.fault.severity
        kind = self.fault.kind
        speed = min(1.0, abs(omega) / FULL_SPEED)
        if kind == "imbalance":
            f = on * s * IMBALANCE_ME * omega * omega
            xfrc[:, :3] += (f * np.cos(theta))[:, None] * forward + (f * np.sin(theta))[:, None] * _UP
        elif kind == "flat_spot":
            phase = np.mod(theta, 2 * np.pi) / FLAT_SPOT_ARC
            pulse = np.where(phase < 1.0, np.sin(np.pi * phase), 0.0)
            xfrc[:, 2] += on * s * FLAT_SPOT_FORCE * speed * pulse
        elif kind == "bearing":
            passes = np.floor(self.order * theta / (2 * np.pi))
            before = np.floor(self.order * (theta - omega * dt) / (2 * np.pi))
            hit = passes != before
            xfrc[:, 2] += on * hit * s * BEARING_IMPULSE * speed / dt
        elif kind == "loose_wheel":
            wob = on * s * np.sin(theta)
            xfrc[:, 5] += wob * LOOSE_WOBBLE_TORQUE * speed
            xfrc[:, :3] += (wob * LOOSE_WOBBLE_FORCE * speed)[:, None] * lateral
            draws = self.rng.random((len(t), 3))
            rattle = on * (draws[:, 0] < s * speed * 30.0 * dt)
            direction = 2.0 * draws[:, 1] - 1.0
            xfrc[:, 2] += rattle * s * LOOSE_RATTLE_FORCE * (0.5 + 0.5 * draws[:, 2])
            xfrc[:, :3] += (rattle * s * LOOSE_RATTLE_FORCE * 0.5 * direction)[:, None] * lateral
        else:
            ripple = np.sin(self.gear_ratio * theta)
            qfrc += (
                on
                * s
                * (
                    -MOTOR_TORQUE_LOSS * motor_torque
                    + MOTOR_RIPPLE * abs(motor_torque) * ripple
                    - MOTOR_DRAG * omega
                )
            )

    def speed_factor(self, t: float) -> float:
        """Multiplier on the wheel's commanded speed at time t (speed droop)."""
        if self.fault.kind != "motor_degradation":
            return 1.0
        f = self.fault
        if f.onset <= t < f.onset + f.duration:
            return 1.0 - MOTOR_DROOP * f.severity
        return 1.0


_UP = np.array([0.0, 0.0, 1.0])


def make_forcings(faults: tuple[Fault, ...], robot: RobotInfo, seed: int) -> list[FaultForcing]:
    """Forcing objects of the faults that act (severity > 0); zero severity adds nothing."""
    out = []
    for i, fault in enumerate(faults):
        if fault.severity <= 0.0:
            continue
        out.append(
            FaultForcing(
                fault=fault,
                order=defect_order(fault.kind, robot),
                gear_ratio=robot.gear_ratio,
                rng=np.random.default_rng([seed, 0xB0B, i]),
            )
        )
    return out
