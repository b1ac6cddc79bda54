"""A tiny synthetic audio-IMU task for tests and smoke runs (not the benchmark's data).

Nominal windows: a few motor-like tones whose frequency follows a random speed, broadband noise, a smooth
IMU z-velocity, six IMU axes and four wheel encoders. Anomalous windows add what collisions and faults add
in the real data: a decaying broadband impact in both audio channels with a matching IMU spike, or a
periodic click train with IMU ripple. Anomalies are of similar RMS to the nominal windows, so energy alone
does not separate them.
"""

from __future__ import annotations

import numpy as np

from msvdd.contract import AUDIO_LEN, AUDIO_RATE, IMU_LEN, IMU_RATE, Windows


def toy_windows(n_normal: int, n_anomalous: int, seed: int) -> tuple[Windows, np.ndarray]:
    """Windows and (N,) int labels (0 nominal, 1 anomalous), nominal first.

    Args:
        n_normal: number of nominal windows.
        n_anomalous: number of anomalous windows (half impacts, half click trains).
        seed: seed of every random draw.
    """
    if n_normal < 0 or n_anomalous < 0:
        raise ValueError(f"window counts must be >= 0, got n_normal={n_normal}, n_anomalous={n_anomalous}")
    rng = np.random.default_rng(seed)
    n = n_normal + n_anomalous
    t_a = np.arange(AUDIO_LEN) / AUDIO_RATE
    t_i = np.arange(IMU_LEN) / IMU_RATE
    speed = rng.uniform(0.3, 1.2, size=(n, 1))
    f0 = 60.0 * speed
    phase = rng.uniform(0, 2 * np.pi, size=(n, 1))
    tones = sum(np.sin(2 * np.pi * k * f0 * t_a + k * phase) / k for k in (1, 2, 3))
    audio = 0.3 * tones + 0.05 * rng.standard_normal((n, AUDIO_LEN))
    imu = 0.02 * np.sin(2 * np.pi * rng.uniform(0.5, 2.0, size=(n, 1)) * t_i + phase)
    imu = imu + 0.005 * rng.standard_normal((n, IMU_LEN))
    labels = np.zeros(n, dtype=np.int64)
    labels[n_normal:] = 1
    for j, idx in enumerate(range(n_normal, n)):
        if j % 2 == 0:
            onset = rng.uniform(0.2, 1.6)
            env = np.where(t_a >= onset, np.exp(-(t_a - onset) / 0.03), 0.0)
            audio[idx] = 0.6 * audio[idx] + 1.2 * env * rng.standard_normal(AUDIO_LEN)
            imu[idx] += 0.15 * np.exp(-(((t_i - onset) / 0.02) ** 2))
        else:
            rate = rng.uniform(8.0, 15.0)
            clicks = (np.sin(2 * np.pi * rate * t_a) > 0.995).astype(float)
            audio[idx] = 0.8 * audio[idx] + 0.9 * clicks * rng.standard_normal(AUDIO_LEN)
            imu[idx] += 0.03 * np.sin(2 * np.pi * rate * t_i)
    stereo = np.stack([audio, 0.8 * audio + 0.01 * rng.standard_normal((n, AUDIO_LEN))], axis=-1)
    # Six IMU axes from their own generator (the draws above stay as they were): gravity on acc z, small
    # noise everywhere, and the z-velocity's anomalies felt as vertical acceleration.
    rng6 = np.random.default_rng([seed, 6])
    imu6 = 0.03 * rng6.standard_normal((n, IMU_LEN, 6))
    imu6[:, :, 2] += 9.81
    imu6[:, :, 2] += np.gradient(imu, 1.0 / IMU_RATE, axis=1)
    # Four wheel encoders from their own generator: the wheels turn at the speed the motor tones follow
    # (0.08 m wheels), each with its own small slip.
    rng_w = np.random.default_rng([seed, 7])
    omega = speed[:, :, None] / 0.08 * (1.0 + 0.02 * rng_w.standard_normal((n, 1, 4)))
    odometry = omega * t_i[None, :, None]
    windows = Windows(
        audio=stereo.astype(np.float32),
        imu=imu.astype(np.float32),
        imu6=imu6.astype(np.float32),
        odometry=odometry.astype(np.float32),
    )
    return windows, labels
