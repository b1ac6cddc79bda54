"""Wheel encoders: the IMU-rate wheel positions a robot publishes, one encoder count of resolution."""

from __future__ import annotations

import numpy as np
from sim_kit import straight

from sim import simulate
from sim.odometry import COUNTS_PER_WHEEL_REV, ENCODER_LINES, NOMINAL_GEAR_RATIO, wheel_encoders


def test_encoders_are_whole_counts_within_one_count_of_the_wheel_angle() -> None:
    trace = simulate(straight(duration=3.0, speed=0.8))
    pos = wheel_encoders(trace)
    assert pos.shape == (trace.imu_time.size, trace.n_wheels)
    count = 2 * np.pi / (4 * ENCODER_LINES) / NOMINAL_GEAR_RATIO  # one count, as the firmware converts it
    counts = pos / count
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-6)
    truth = np.stack(
        [np.interp(trace.imu_time, trace.time, trace.wheel_angle[:, w]) for w in range(4)], axis=1
    )
    shaft_truth = truth * trace.robot.gear_ratio / NOMINAL_GEAR_RATIO  # what the count measures
    assert np.all(np.abs(pos - shaft_truth) <= count * (1 + 1e-9))
    assert COUNTS_PER_WHEEL_REV == 4 * ENCODER_LINES * NOMINAL_GEAR_RATIO
    assert pos[-1, 0] > 2 * np.pi  # the robot drove: more than a revolution in 3 s at 0.8 m/s
