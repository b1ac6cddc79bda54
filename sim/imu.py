"""The IMU: physics-rate MuJoCo sensors decimated to 200 Hz, with noise and bias that we add.

MuJoCo's sensor `noise` attribute does nothing, so noise is added here from a generator seeded by the
scenario seed: white noise per sample, a constant bias per axis and a slow bias random walk.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.scenario import Sensors


@dataclass(frozen=True)
class ImuSamples:
    """IMU output at the IMU rate."""

    time: np.ndarray
    """(m,) sample times, s."""
    acc: np.ndarray
    """(m, 3) accelerometer, m/s^2."""
    gyro: np.ndarray
    """(m, 3) gyroscope, rad/s."""
    vel_z: np.ndarray
    """(m,) z-axis velocity in the sensor frame, m/s."""


def decimate(x: np.ndarray, factor: int) -> np.ndarray:
    """Block mean over `factor` physics steps (the IMU's own anti-alias averaging); axis 0."""
    n = (x.shape[0] // factor) * factor
    return x[:n].reshape(n // factor, factor, *x.shape[1:]).mean(axis=1)


def imu_samples(
    time: np.ndarray, acc: np.ndarray, gyro: np.ndarray, vel: np.ndarray, sensors: Sensors, seed: int
) -> ImuSamples:
    """Decimate physics-rate IMU signals and add noise, bias and bias drift (seeded by `seed`).

    Args:
        time: (n,) physics-rate times (n a multiple of the decimation factor).
        acc: (n, 3) accelerometer without noise.
        gyro: (n, 3) gyroscope without noise.
        vel: (n, 3) velocimeter (sensor frame) without noise.
        sensors: noise settings.
        seed: scenario seed.
    """
    dt = float(time[1] - time[0]) if len(time) > 1 else float(time[0])
    factor = max(1, round(1.0 / (sensors.imu_rate * dt)))
    t = time[factor - 1 :: factor][: len(time) // factor]
    m = len(t)
    rng = np.random.default_rng([seed, 0x1A0])

    def noisy(x: np.ndarray, white: float, bias: float) -> np.ndarray:
        shape = x.shape
        offset = rng.normal(0.0, bias, size=shape[1:])
        walk = np.cumsum(rng.normal(0.0, sensors.bias_walk * white, size=shape), axis=0)
        return x + offset + walk + rng.normal(0.0, white, size=shape)

    a = noisy(decimate(acc, factor)[:m], sensors.acc_noise, sensors.acc_bias)
    g = noisy(decimate(gyro, factor)[:m], sensors.gyro_noise, sensors.gyro_bias)
    v = noisy(decimate(vel[:, 2:3], factor)[:m], sensors.vel_noise, sensors.vel_bias)[:, 0]
    return ImuSamples(time=t, acc=a, gyro=g, vel_z=v)
