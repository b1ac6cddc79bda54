"""The fault-aware reference detector: condition monitoring on the wheel encoders, without privileged
information.

What a vibration analyst who knows the robot's drive train computes on every 2 s window, tracking each
wheel's angle from its encoder (the odometry modality, `Windows.odometry`), for every wheel in turn (the
faulty wheel, the defect's angle and the balls' slip are unknown to it):

- the order-1 line of the chassis' smooth motion (below `condition.SPLIT_HZ`): a wheel that rides up and
  down or wobbles once per revolution;
- the time-synchronous average's strength of the IMU's motion power (0.5-100 Hz) over one revolution and
  over one ball pass, and of the audio's squared envelope over one revolution in the tyre's band and over
  one ball pass in the hub's band: a strike that repeats at the same wheel angle;
- the gear-mesh line of the audio over the lines between its sidebands, and the two motor-shaft sidebands;
- not per wheel: the audio envelope's level and crest (peak over median) in the tyre's, the hub's and the
  loose hub's bands, the IMU's vibration power (above `condition.SPLIT_HZ`) and the crest of its motion.

Each IMU indicator is the mean of its logarithm over the seven channels (z-velocity, accelerometer and
gyroscope xyz), as in the audit's oracle.

The orders come from the drive train of the robot model (`sim.faults.bpfo_order`, pinion teeth x gear
ratio); a robot team knows its own. Features are logarithms, floored where noise leaves them (a line at
1 / sqrt(n), a strength at 1); their Gaussian over nominal training windows is the reference detector's
(`benchmarks.methods.gaussian.GaussianReference`: standardised, Ledoit-Wolf covariance), and the score is the
squared Mahalanobis distance.
A window without odometry is refused.
"""

from __future__ import annotations

from typing import Any, Self

import numpy as np

from benchmarks import condition
from benchmarks.methods.gaussian import GaussianReference
from msvdd.contract import AUDIO_LEN, AUDIO_RATE, IMU_LEN, IMU_RATE, WindowError, Windows
from sim.faults import BEARING_SLIP, bpfo_order, envelope_band
from sim.robot import DRIVE_TRAINS

BANDS: tuple[str, ...] = ("flat_spot", "bearing", "loose_wheel")
"""Fault kinds whose audio band (`sim.faults.envelope_band`) the detector reads."""
_CHUNK = 64


def _log_sync(x: np.ndarray, angle: np.ndarray, order: float) -> np.ndarray:
    return np.asarray(np.log(np.maximum(condition.synchronous_strength(x, angle, order), 1.0)))


def _log_crest(x: np.ndarray) -> np.ndarray:
    """(N,) log of the peak of (N, n) powers over their median: a strike stands out of the window."""
    return np.asarray(np.log(x.max(axis=-1) + 1e-30) - np.log(np.median(x, axis=-1) + 1e-30))


def order_features(batch: Windows, model: str = "skid4") -> np.ndarray:
    """(N, F) the detector's features of a window batch (see the module); F depends on the wheel count."""
    if batch.odometry is None or batch.imu6 is None:
        raise WindowError("odometry or imu6 is None: the order reference reads wheel encoders and IMU axes")
    out = [_chunk_features(batch.subset(slice(i, i + _CHUNK)), model) for i in range(0, len(batch), _CHUNK)]
    return np.concatenate(out, axis=0)


def _chunk_features(batch: Windows, model: str) -> np.ndarray:
    drive = DRIVE_TRAINS[model]
    bpfo = bpfo_order() * (1.0 - 0.5 * sum(BEARING_SLIP))
    mesh = float(drive.pinion_teeth * drive.gear_ratio)
    assert batch.odometry is not None and batch.imu6 is not None
    imu = np.concatenate([batch.imu[:, :, None], batch.imu6], axis=2).transpose(0, 2, 1)  # (k, 7, 400)
    channels = range(imu.shape[1])
    audio = batch.audio.astype(np.float64).sum(axis=-1)  # (k, 8820)
    smooth = condition.band_pass(imu, IMU_RATE, (0.3, condition.SPLIT_HZ))
    motion = condition.band_pass(imu, IMU_RATE, (0.5, IMU_RATE / 2)) ** 2
    vibration = condition.band_pass(imu, IMU_RATE, (condition.SPLIT_HZ, IMU_RATE / 2)) ** 2
    envelopes: dict[str, np.ndarray] = {}
    for kind in BANDS:
        envelopes[kind], t_env = condition.block_envelope(audio, AUDIO_RATE, envelope_band(kind, AUDIO_RATE))
    t_imu = np.arange(IMU_LEN) / IMU_RATE
    t_audio = np.arange(AUDIO_LEN) / AUDIO_RATE
    parts: list[np.ndarray] = []
    for env in envelopes.values():
        parts += [np.log(env.mean(axis=-1) + 1e-20), _log_crest(env)]
    parts.append(np.mean([np.log(vibration[:, c].mean(axis=-1) + 1e-20) for c in channels], axis=0))
    parts.append(np.mean([_log_crest(motion[:, c]) for c in channels], axis=0))
    for w in range(batch.odometry.shape[2]):
        angle = batch.odometry[:, :, w].astype(np.float64)
        angle_env = np.stack([np.interp(t_env, t_imu, a) for a in angle])
        angle_audio = np.stack([np.interp(t_audio, t_imu, a) for a in angle])
        one = np.array([1.0])
        parts.append(np.mean([condition.log_lines(smooth[:, c], angle, one)[:, 0] for c in channels], axis=0))
        parts.append(np.mean([_log_sync(motion[:, c], angle, 1.0) for c in channels], axis=0))
        parts.append(np.mean([_log_sync(motion[:, c], angle, bpfo) for c in channels], axis=0))
        parts.append(_log_sync(envelopes["flat_spot"], angle_env, 1.0))
        parts.append(_log_sync(envelopes["bearing"], angle_env, bpfo))
        parts += list(condition.mesh_lines(audio, angle_audio, mesh, drive.gear_ratio).T)
    return np.stack(parts, axis=1)


class OrderReference(GaussianReference):
    """Order-tracked condition-monitoring features per wheel under the reference detector's Gaussian."""

    kind = "order-reference"

    def __init__(self, model: str = "skid4") -> None:
        super().__init__()
        if model not in DRIVE_TRAINS:
            raise ValueError(f"model {model!r} is unknown; allowed: {', '.join(DRIVE_TRAINS)}")
        self.model = model

    def _features(self, batch: Windows) -> np.ndarray:
        return order_features(batch, self.model)

    def _state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        return {"model": self.model}, super()._state()[1]

    @classmethod
    def _from_state(cls, header: dict[str, Any], arrays: dict[str, np.ndarray]) -> Self:
        return cls(str(header["model"]))._restored(arrays)


def register_methods() -> None:
    """Register `order-reference`."""
    from benchmarks.methods.registry import register

    register(
        "order-reference",
        lambda seed, scale, device: OrderReference(),
        cls=OrderReference,
        family="reference",
        modality="audio+imu+odometry",
        description="reference: order-tracked condition monitoring on the wheel encoders (synchronous "
        "averages, order lines, gear-mesh line) per wheel, Ledoit-Wolf Mahalanobis distance",
        label="Order tracking, wheel encoders",
        config="OrderReference(model='skid4')",
    )
