"""The IMU: physics-rate MuJoCo sensors decimated to 200 Hz, with noise and bias that we add.

MuJoCo's sensor `noise` attribute does nothing, so noise is added here from a generator seeded by the
scenario seed: white noise per sample, a constant bias per axis and a slow bias random walk.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

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
    """Block mean over `factor` physics steps (the IMU's own anti-alias averaging); axis 0.

    Two steps (the simulator's) are averaged as (a + b + 0.0) / 2: the bits of numpy's `mean` (whose sum
    starts from +0.0, so that two -0.0 average to +0.0) without its reduction machinery, in one compiled pass
    over the (strided) columns."""
    n = (x.shape[0] // factor) * factor
    if factor == 2 and x.ndim <= 2:
        columns = x.reshape(x.shape[0], -1)
        return _pair_means(columns, np.empty((n // 2, columns.shape[1]))).reshape(n // 2, *x.shape[1:])
    return x[:n].reshape(n // factor, factor, *x.shape[1:]).mean(axis=1)


@njit(cache=True, nogil=True)
def _pair_means(x: np.ndarray, out: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """out[i] = (x[2 i] + x[2 i + 1] + 0.0) / 2, row by row, in one pass over a (strided) 2-D view."""
    for i in range(out.shape[0]):
        for j in range(out.shape[1]):
            out[i, j] = (x[2 * i, j] + x[2 * i + 1, j] + 0.0) / 2.0
    return out


@dataclass(frozen=True)
class ImuNoise:
    """The noise of every IMU sample of an episode, drawn once: a bias per axis, a bias random walk and white
    noise. `simulate` and the Gymnasium environment both take their IMU noise from here."""

    acc: tuple[np.ndarray, np.ndarray, np.ndarray]
    """Accelerometer (bias (3,), walk (m, 3), white (m, 3)), m/s^2."""
    gyro: tuple[np.ndarray, np.ndarray, np.ndarray]
    """Gyroscope (bias (3,), walk (m, 3), white (m, 3)), rad/s."""
    vel: tuple[np.ndarray, np.ndarray, np.ndarray]
    """Z-velocity (bias (1,), walk (m, 1), white (m, 1)), m/s."""

    def __len__(self) -> int:
        return int(self.acc[1].shape[0])

    @staticmethod
    def _add(x: np.ndarray, parts: tuple[np.ndarray, np.ndarray, np.ndarray], index: slice) -> np.ndarray:
        bias, walk, white = parts
        return x + bias + walk[index] + white[index]

    def apply(
        self, acc: np.ndarray, gyro: np.ndarray, vel_z: np.ndarray, index: slice
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Noisy (acc (k, 3), gyro (k, 3), vel_z (k,)) of the noise-free samples at `index` of the episode."""
        v = self._add(vel_z[:, None], self.vel, index)[:, 0]
        return self._add(acc, self.acc, index), self._add(gyro, self.gyro, index), v


def imu_noise(m: int, sensors: Sensors, seed: int) -> ImuNoise:
    """The noise of an episode of `m` IMU samples, from a generator seeded by `seed` (the scenario's)."""
    rng = np.random.default_rng([seed, 0x1A0])

    def draw(axes: int, white: float, bias: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        offset = rng.normal(0.0, bias, size=(axes,))
        walk = np.cumsum(rng.normal(0.0, sensors.bias_walk * white, size=(m, axes)), axis=0)
        return offset, walk, rng.normal(0.0, white, size=(m, axes))

    return ImuNoise(
        acc=draw(3, sensors.acc_noise, sensors.acc_bias),
        gyro=draw(3, sensors.gyro_noise, sensors.gyro_bias),
        vel=draw(1, sensors.vel_noise, sensors.vel_bias),
    )


def decimation_factor(sensors: Sensors, dt: float) -> int:
    """Physics steps per IMU sample."""
    return max(1, round(1.0 / (sensors.imu_rate * dt)))


def imu_samples(
    time: np.ndarray, acc: np.ndarray, gyro: np.ndarray, vel: np.ndarray, sensors: Sensors, seed: int
) -> ImuSamples:
    """Decimate physics-rate IMU signals and add noise, bias and bias drift (`imu_noise(m, sensors, seed)`).

    Args:
        time: (n,) physics-rate times (n a multiple of the decimation factor).
        acc: (n, 3) accelerometer without noise.
        gyro: (n, 3) gyroscope without noise.
        vel: (n, 3) velocimeter (sensor frame) without noise.
        sensors: noise settings.
        seed: scenario seed.
    """
    dt = float(time[1] - time[0]) if len(time) > 1 else float(time[0])
    factor = decimation_factor(sensors, dt)
    t = time[factor - 1 :: factor][: len(time) // factor]
    m = len(t)
    noise = imu_noise(m, sensors, seed)
    a, g, v = noise.apply(
        decimate(acc, factor)[:m], decimate(gyro, factor)[:m], decimate(vel[:, 2], factor)[:m], slice(0, m)
    )
    return ImuSamples(time=t, acc=a, gyro=g, vel_z=v)
