"""The trace's drive-train state resampled to audio rate: wheel phase, speed and torque per wheel.

Control values (speed, torque, cycle counts) are taken at block boundaries (every `BLOCK` samples) from the
physics-rate trace and ramped linearly within each block, which keeps every phase continuous.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.trace import RobotInfo
from synth_audio.dsp import block_ramp, frac_phase

BLOCK = 64
"""Samples per control block (1.45 ms at 44.1 kHz)."""
GRAVITY = 9.81
"""Standard gravity, m/s^2."""
NOMINAL_SPEED = 0.6
"""Rim speed at which the speed-dependent source laws have unit gain, m/s."""


@dataclass(frozen=True)
class Drive:
    """Per-wheel drive-train control signals at block boundaries, for an n-sample render."""

    n: int
    """Number of audio samples."""
    sample_rate: int
    """Audio sample rate, Hz."""
    block_time: np.ndarray
    """(nb+1,) times of the block boundaries, s."""
    cycles: np.ndarray
    """(W, nb+1) wheel revolutions (unwrapped angle / 2 pi) at the boundaries, float64."""
    rev_s: np.ndarray
    """(W, nb+1) signed wheel speed, rev/s."""
    torque: np.ndarray
    """(W, nb+1) wheel torque normalised by the unit's reference torque (dimensionless, signed)."""
    speed_mps: np.ndarray
    """(W, nb+1) wheel rim speed |omega| r, m/s."""
    robot: RobotInfo
    """The robot unit."""

    @property
    def n_wheels(self) -> int:
        """Number of wheels."""
        return int(self.cycles.shape[0])

    def ramp(self, values: np.ndarray) -> np.ndarray:
        """Per-sample linear ramp of block-boundary values (..., nb+1) -> (..., n) float32."""
        return block_ramp(values, BLOCK, self.n)

    def phase(self, wheel: int, multiple: float) -> np.ndarray:
        """Per-sample phase in cycles (wrapped near [0, 1)) of `multiple` x the wheel's rotation."""
        return frac_phase(self.cycles[wheel] * multiple, BLOCK, self.n)


def reference_torque(robot: RobotInfo) -> float:
    """Wheel torque that accelerates the unit at about 1 m/s^2 (the motor-load scale), N m."""
    radius = float(np.mean(robot.wheel_radius))
    return max(robot.mass * 1.0 * radius / max(len(robot.wheel_names), 1), 1e-6)


def rolling_torque(robot: RobotInfo) -> float:
    """Steady rolling-resistance torque per wheel on a hard floor, N m (used by the reference drive)."""
    radius = float(np.mean(robot.wheel_radius))
    return 0.03 * robot.mass * GRAVITY * radius / max(len(robot.wheel_names), 1)


def build_drive(
    robot: RobotInfo,
    time: np.ndarray,
    wheel_angle: np.ndarray,
    wheel_speed: np.ndarray,
    wheel_torque: np.ndarray,
    n: int,
    sample_rate: int,
) -> Drive:
    """Resample physics-rate wheel arrays (T, W) to block boundaries covering n audio samples."""
    nb = -(-n // BLOCK)
    tb = np.arange(nb + 1, dtype=np.float64) * (BLOCK / sample_rate)
    t = np.asarray(time, dtype=np.float64)

    def interp(a: np.ndarray) -> np.ndarray:
        a = np.asarray(a, dtype=np.float64)
        return np.stack([np.interp(tb, t, a[:, w]) for w in range(a.shape[1])])

    angle = interp(wheel_angle)
    speed = interp(wheel_speed)
    torque = interp(wheel_torque) / reference_torque(robot)
    radius = np.asarray(robot.wheel_radius, dtype=np.float64)[:, None]
    return Drive(
        n=n,
        sample_rate=sample_rate,
        block_time=tb,
        cycles=angle / (2.0 * np.pi),
        rev_s=speed / (2.0 * np.pi),
        torque=torque,
        speed_mps=np.abs(speed) * radius,
        robot=robot,
    )
