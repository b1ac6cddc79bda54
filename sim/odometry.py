"""Wheel odometry: each wheel's encoder position at the IMU rate, as a robot publishes its joint states.

A drive motor of this class carries an incremental encoder on its shaft: `ENCODER_LINES` lines read in
quadrature give 4 x `ENCODER_LINES` counts per motor revolution, so `ENCODER_LINES` x 4 x gear ratio counts
per wheel revolution (`COUNTS_PER_WHEEL_REV` at the models' nominal 18:1 gear, 85 micro-rad a count). The
controller publishes the count with every IMU sample; the position is the count times the wheel angle of one
count at the nominal gear ratio (the firmware does not know a unit's gear tolerance).
"""

from __future__ import annotations

import math

import numpy as np

from sim.trace import Trace

ENCODER_LINES = 1024
"""Lines of the motor shaft encoder (quadrature: 4 counts a line)."""
NOMINAL_GEAR_RATIO = 18.0
"""Motor revolutions per wheel revolution the firmware converts counts with."""
COUNTS_PER_WHEEL_REV = 4 * ENCODER_LINES * NOMINAL_GEAR_RATIO
"""Encoder counts per wheel revolution at the nominal gear ratio."""


def wheel_encoders(trace: Trace) -> np.ndarray:
    """(m, W) wheel positions at the trace's IMU samples, rad, quantised to one encoder count.

    The motor shaft turns gear_ratio times the wheel; the count is floor(shaft angle / count angle), and the
    published position converts it back with the nominal gear ratio.
    """
    count = 2 * math.pi / (4 * ENCODER_LINES)
    angle = [np.interp(trace.imu_time, trace.time, trace.wheel_angle[:, w]) for w in range(trace.n_wheels)]
    shaft = np.stack(angle, axis=1) * float(trace.robot.gear_ratio)
    return np.asarray(np.floor(shaft / count) * count / NOMINAL_GEAR_RATIO)
