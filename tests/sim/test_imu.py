"""The IMU's noise (`sim.imu.imu_noise`) against its settings: white noise, biases, the bias random walk."""

from __future__ import annotations

import numpy as np

from sim.imu import imu_noise
from sim.scenario import Sensors

SAMPLES = 240_000
"""Twenty minutes at 200 Hz: a standard deviation is estimated to 0.3 % (one sigma)."""


def _channels(seed: int) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """Per sensor (accelerometer, gyroscope, z-velocity): its walk (SAMPLES, axes), its white noise and the
    white noise's set deviation, drawn with the default settings."""
    sensors = Sensors()
    noise = imu_noise(SAMPLES, sensors, seed=seed)
    sigmas = (sensors.acc_noise, sensors.gyro_noise, sensors.vel_noise)
    return [
        (np.asarray(walk), np.asarray(white), sigma)
        for (_, walk, white), sigma in zip((noise.acc, noise.gyro, noise.vel), sigmas, strict=True)
    ]


def test_white_noise_has_the_set_deviation_on_every_channel() -> None:
    for _, white, sigma in _channels(seed=3):
        assert white.shape[0] == SAMPLES
        np.testing.assert_allclose(white.std(axis=0), sigma, rtol=0.015)
        np.testing.assert_allclose(white.mean(axis=0), 0.0, atol=5 * sigma / np.sqrt(SAMPLES))


def test_bias_walk_is_a_random_walk_of_the_set_step() -> None:
    """The walk moves by one step per sample, of standard deviation bias_walk x the channel's noise, each step
    independent of the last (a random walk: its steps are uncorrelated)."""
    for walk, _, sigma in _channels(seed=4):
        steps = np.diff(walk, axis=0)
        np.testing.assert_allclose(steps.std(axis=0), Sensors().bias_walk * sigma, rtol=0.015)
        lag1 = np.mean(steps[1:] * steps[:-1], axis=0) / steps.var(axis=0)
        assert np.all(np.abs(lag1) < 0.01)


def test_biases_have_the_set_spread_and_the_noise_is_the_seeds() -> None:
    sensors = Sensors()
    offsets = np.array([imu_noise(10, sensors, seed=s).acc[0] for s in range(3000)])
    np.testing.assert_allclose(offsets.std(axis=0), sensors.acc_bias, rtol=0.06)
    a, b, c = (
        imu_noise(1000, sensors, seed=7),
        imu_noise(1000, sensors, seed=7),
        imu_noise(1000, sensors, seed=8),
    )
    for x, y, z in zip(a.gyro, b.gyro, c.gyro, strict=True):
        assert np.array_equal(x, y) and not np.array_equal(x, z)
