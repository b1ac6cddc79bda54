"""The trace's drive-train state resampled to audio rate: wheel phase, speed and torque per wheel.

Control values (speed, torque, cycle counts) are taken at block boundaries (every `BLOCK` samples) from the
physics-rate trace and ramped linearly within each block, which keeps every phase continuous.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from sim.trace import RobotInfo
from synth_audio import kernels
from synth_audio.dsp import block_ramp, frac_phase

BLOCK = 64
"""Samples per control block (1.45 ms at 44.1 kHz)."""
CHUNK = 2**16
"""Samples per processing span of the dense sources (a multiple of BLOCK)."""
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

    def spans(self) -> Iterator[tuple[int, int]]:
        """Consecutive [start, stop) sample ranges of at most CHUNK samples covering the render.

        Dense sources are computed span by span so that temporaries stay in cache; spans start on block
        boundaries, so the result is identical to a whole-signal computation.
        """
        for start in range(0, self.n, CHUNK):
            yield start, min(start + CHUNK, self.n)

    def ramp(self, values: np.ndarray, span: tuple[int, int] | None = None) -> np.ndarray:
        """Per-sample linear ramp of block-boundary values (..., nb+1) over the render or one span."""
        if span is None:
            return block_ramp(values, BLOCK, self.n)
        b0, b1 = span[0] // BLOCK, -(-span[1] // BLOCK)
        return block_ramp(values[..., b0 : b1 + 1], BLOCK, span[1] - span[0])

    def boundaries(self, values: np.ndarray, span: tuple[int, int]) -> np.ndarray:
        """The block-boundary values (..., nb+1) that cover one span (its first block's start to its last
        block's end)."""
        b0, b1 = span[0] // BLOCK, -(-span[1] // BLOCK)
        return values[..., b0 : b1 + 1]

    def add_ramped(
        self, out: np.ndarray, signal: np.ndarray, values: np.ndarray, span: tuple[int, int]
    ) -> None:
        """out += signal x the block-boundary `values` ramped per sample, over one span (`out` and `signal`
        are the span's samples; `kernels.add_ramped`)."""
        kernels.add_ramped(out, signal, self.boundaries(values, span), BLOCK)

    def phase(self, wheel: int, multiple: float, span: tuple[int, int] | None = None) -> np.ndarray:
        """Per-sample phase in cycles (wrapped near [0, 1)) of `multiple` x the wheel's rotation."""
        if span is None:
            return frac_phase(self.cycles[wheel] * multiple, BLOCK, self.n)
        b0, b1 = span[0] // BLOCK, -(-span[1] // BLOCK)
        return frac_phase(self.cycles[wheel][b0 : b1 + 1] * multiple, BLOCK, span[1] - span[0])


def reference_torque(robot: RobotInfo) -> float:
    """Typical wheel torque while driving and turning, 0.25 m g r / W (the motor-load scale), N m.

    The unit's reference drive runs at this torque; the motor gets louder above it (acceleration,
    skid-steer scrubbing, pushing against an obstacle) and quieter below it (coasting).
    """
    radius = float(np.mean(robot.wheel_radius))
    return max(0.25 * robot.mass * GRAVITY * radius / max(len(robot.wheel_names), 1), 1e-6)


def unstrained_torque(
    time: np.ndarray, torque: np.ndarray, start: np.ndarray, duration: np.ndarray
) -> np.ndarray:
    """(T, W) wheel torques without the strain of the robot's contacts with obstacles: over each contact
    [start, start + duration] every wheel's torque is held at its value of the step before the contact, the
    load the drive had before the obstacle pushed back (the motors' sound then follows the driving alone)."""
    out = np.array(torque, dtype=np.float64)
    ends = np.asarray(start, dtype=np.float64) + np.asarray(duration, dtype=np.float64)
    for t0, t1 in zip(np.asarray(start, dtype=np.float64), ends, strict=True):
        a, b = np.searchsorted(time, [t0, t1], side="left")
        out[a : b + 1] = out[max(a - 1, 0)]
    return out


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
