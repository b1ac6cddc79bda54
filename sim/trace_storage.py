"""How a Trace is kept in its `.npz` file: which arrays are float32, which are derived, not stored.

Format 1 kept every array as the simulator made it (float64). Format 2 keeps the same names, and per field:

- exact: the scalars, the robot, the events, faults and obstacles, the arena, the labels;
- float32 (`FLOAT32_FIELDS`): the sampled physics- and IMU-rate signals, within 2^-24 of each value
  (relative 6e-8: a wheel speed to 1 micro-rad/s, a position to 1 micrometre, far below what the audio or a
  viewer resolves and below the IMU's own noise); read back as float64;
- derived when the simulator's values follow the law, so not stored:
  `time` = physics_dt x (1, 2, ..., n) and `imu_time` = every f-th `time` (exact: the simulator's own
  formulas); `wheel_angle` = its first row (float64, kept as `wheel_angle_start`) plus the running sum of the
  stored `wheel_speed` x physics_dt, which is how the simulator's integrator advances it (within
  `ANGLE_TOLERANCE_RAD`, checked on every save); `mic_pos` = `base_pos` plus `base_quat` rotating
  `robot.mic_pos_body` (within `MIC_TOLERANCE_M`, checked likewise).
  A trace whose values do not follow a law (a hand-made one) keeps that field: `time`, `imu_time` and
  `wheel_angle` as float64, `mic_pos` as float32.

`encode` and `decode` map the flat {dotted name: array} dict of `sim.trace` between the two; every step is
an element-wise IEEE operation or a sequential running sum, so the same trace gives the same bytes on any
machine.
"""

from __future__ import annotations

import zipfile
import zlib
from collections.abc import Mapping
from typing import BinaryIO

import numpy as np

from sim.vocab import TRANSIENT_HEIGHT

FLOAT32_FIELDS: tuple[str, ...] = (
    "wheel_speed",
    "wheel_torque",
    "base_pos",
    "base_quat",
    "base_linvel",
    "base_angvel",
    "imu_vel_z",
    "imu_acc",
    "imu_gyro",
    "obstacle_pos",
)
"""Sampled signals stored as float32 (format 2)."""

ANGLE_START = "wheel_angle_start"
"""Key of the (W,) float64 first row of `wheel_angle` when the rest is derived."""

ANGLE_TOLERANCE_RAD = 1e-5
"""Largest deviation of a derived wheel angle from the simulator's, rad (gear-mesh phase under 4 mrad)."""

MIC_TOLERANCE_M = 1e-5
"""Largest deviation of a derived microphone position from the simulator's, m (30 ns of sound)."""


def encode(arrays: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Format-1 arrays (every field as simulated) -> the format-2 arrays to store."""
    out = dict(arrays)
    for name in FLOAT32_FIELDS:
        out[name] = np.asarray(arrays[name], dtype=np.float32)
    stored = decode_floats(out)  # what a reader will see of the float32 signals
    n, m = stored["wheel_speed"].shape[0], stored["label"].shape[0]
    time = np.asarray(arrays["time"])
    if time.shape == (n,) and np.array_equal(time, _time(stored["physics_dt"], n)):
        del out["time"]
    imu_time = np.asarray(arrays["imu_time"])
    if m > 0 and imu_time.shape == (m,) and np.array_equal(imu_time, _imu_time(time, m)):
        del out["imu_time"]
    angle = np.asarray(arrays["wheel_angle"], dtype=np.float64)
    if n > 0 and angle.shape == stored["wheel_speed"].shape:
        derived = _wheel_angle(angle[0], stored["wheel_speed"], stored["physics_dt"])
        if _within(derived, angle, ANGLE_TOLERANCE_RAD):
            del out["wheel_angle"]
            out[ANGLE_START] = np.ascontiguousarray(angle[0])
    mic = np.asarray(arrays["mic_pos"], dtype=np.float64)
    body = np.asarray(arrays["robot.mic_pos_body"], dtype=np.float64)
    if _rigid_shapes(stored, body, mic) and _within(_mic_pos(stored, body), mic, MIC_TOLERANCE_M):
        del out["mic_pos"]
    else:
        out["mic_pos"] = mic.astype(np.float32)
    return out


def decode(arrays: dict[str, np.ndarray], version: int) -> dict[str, np.ndarray]:
    """Stored arrays of format `version` (1 or 2) -> every field, float64 signals, as `sim.trace` expects.

    Raises:
        KeyError: a stored array is missing (named).
    """
    if version == 1:
        return _with_fault_defects(_with_transient_heights(dict(arrays)))
    out = _with_fault_defects(_with_transient_heights(decode_floats(arrays)))
    n, m = out["wheel_speed"].shape[0], out["label"].shape[0]
    if "time" not in out:
        out["time"] = _time(out["physics_dt"], n)
    if "imu_time" not in out:
        out["imu_time"] = _imu_time(out["time"], m)
    if "wheel_angle" not in out:
        start = np.asarray(out.pop(ANGLE_START), dtype=np.float64)
        out["wheel_angle"] = _wheel_angle(start, out["wheel_speed"], out["physics_dt"])
    if "mic_pos" not in out:
        out["mic_pos"] = _mic_pos(out, np.asarray(out["robot.mic_pos_body"], dtype=np.float64))
    else:
        out["mic_pos"] = np.asarray(out["mic_pos"], dtype=np.float64)
    return out


def _with_transient_heights(out: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Traces written before the transient events carried their feature heights get them from the
    scenario's table (`sim.vocab.TRANSIENT_HEIGHT`), the values the simulator built the features with."""
    if "transients.height" not in out and "transients.kind" in out:
        kinds = [str(k) for k in np.asarray(out["transients.kind"]).ravel()]
        out["transients.height"] = np.array([TRANSIENT_HEIGHT[k] for k in kinds], dtype=np.float64)
    return out


def _with_fault_defects(out: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Traces written before the faults' defect model (formats 1 and 2) read with zero defect sizes and
    phases and no strikes."""
    if "fault_strikes.time" not in out:
        n = int(out.get("faults.__len__", 0))
        out.setdefault("faults.size", np.zeros(n))
        out.setdefault("faults.phase", np.zeros(n))
        out["fault_strikes.time"] = np.zeros(0)
        out["fault_strikes.wheel"] = np.zeros(0, dtype=np.int64)
        out["fault_strikes.impulse"] = np.zeros(0)
    return out


def decode_floats(arrays: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """A copy of `arrays` with every `FLOAT32_FIELDS` array as float64 (the values it holds)."""
    out = dict(arrays)
    for name in FLOAT32_FIELDS:
        out[name] = np.asarray(arrays[name], dtype=np.float64)
    return out


def _within(a: np.ndarray, b: np.ndarray, tolerance: float) -> bool:
    return a.shape == b.shape and bool(np.all(np.abs(a - b) <= tolerance))


def _time(physics_dt: np.ndarray, n: int) -> np.ndarray:
    """The simulator's physics time stamps: one step after another, the first at dt."""
    return float(physics_dt) * np.arange(1, n + 1)


def _imu_time(time: np.ndarray, m: int) -> np.ndarray:
    """The IMU's time stamps: every f-th physics time stamp, f = n // m."""
    factor = max(time.shape[0] // max(m, 1), 1)
    return np.ascontiguousarray(time[factor - 1 :: factor][:m])


def _wheel_angle(start: np.ndarray, speed: np.ndarray, physics_dt: np.ndarray) -> np.ndarray:
    """(n, W) angles: `start`, then each step adds speed x dt (a sequential sum, as the integrator does)."""
    steps = np.concatenate([start.reshape(1, -1), speed[1:] * float(physics_dt)])
    return np.cumsum(steps, axis=0)


def _rigid_shapes(arrays: dict[str, np.ndarray], body: np.ndarray, mic: np.ndarray) -> bool:
    n = arrays["base_pos"].shape[0]
    return (
        body.ndim == 2
        and body.shape[1] == 3
        and mic.shape == (n, body.shape[0], 3)
        and arrays["base_pos"].shape == (n, 3)
        and arrays["base_quat"].shape == (n, 4)
    )


def _mic_pos(arrays: dict[str, np.ndarray], body: np.ndarray) -> np.ndarray:
    """(n, k, 3) world positions of the body points `body` (k, 3) carried by the base pose."""
    pos, quat = arrays["base_pos"], arrays["base_quat"]
    w, x, y, z = (quat[:, i : i + 1] for i in range(4))
    rows = (
        (1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)),
        (2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)),
        (2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)),
    )
    bx, by, bz = body[:, 0], body[:, 1], body[:, 2]
    axes = [pos[:, i : i + 1] + r0 * bx + r1 * by + r2 * bz for i, (r0, r1, r2) in enumerate(rows)]
    return np.stack(axes, axis=-1)


NPZ_LEVEL = 1
"""zlib level of the `.npz` members `write_npz` compresses. The stored signals are float32 samples whose low
mantissa bits are noise to zlib, which the higher levels search in vain: level 1 makes files nearly as small
as numpy's default level 6, in less time."""

STORE_RATIO = 0.9
"""A member whose first `PROBE_BYTES` compress to more than this fraction of their size is stored
uncompressed: the signals of accelerations, rates and torques are noise to zlib in all but their exponent
bits, so compressing them costs most of an episode's `.npz` time and saves few bytes."""

PROBE_BYTES = 1 << 14
"""Bytes of a member's data that `write_npz` compresses to decide how to store it."""


def _deflates(value: np.ndarray) -> bool:
    """Whether the array's first `PROBE_BYTES` compress (zlib, `NPZ_LEVEL`) to at most `STORE_RATIO` of
    their size; decided by the array's bytes alone, so the same arrays give the same files."""
    raw = np.ascontiguousarray(value).reshape(-1).view(np.uint8)[:PROBE_BYTES]
    if raw.size == 0:
        return True
    return len(zlib.compress(raw.tobytes(), NPZ_LEVEL)) <= STORE_RATIO * raw.size


def write_npz(handle: BinaryIO, arrays: Mapping[str, np.ndarray]) -> None:
    """Write `arrays` to an open binary file as an `.npz` that `numpy.load` reads: numpy's `savez_compressed`
    layout (one `<name>.npy` member per array, zip64, the members' fixed 1980 date, so the same arrays give
    the same bytes), each member deflated at zlib level `NPZ_LEVEL` or, where its data barely compresses
    (`_deflates`), stored."""
    with zipfile.ZipFile(handle, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=NPZ_LEVEL) as archive:
        for name, value in arrays.items():
            array = np.asanyarray(value)
            # a member takes the archive's compression when it is opened
            archive.compression = zipfile.ZIP_DEFLATED if _deflates(array) else zipfile.ZIP_STORED
            with archive.open(name + ".npy", "w", force_zip64=True) as member:
                np.lib.format.write_array(member, array, allow_pickle=False)
