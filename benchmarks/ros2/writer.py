"""An episode as a ROS 2 bag in MCAP: what `msvdd-bench export-bag` writes, and `import --layout ros2` reads
back to the same windows.

Topics (`benchmarks.ros2.topics.Topics`), every schema embedded (`benchmarks.ros2.msgs`):

- IMU, `sensor_msgs/msg/Imu` at 200 Hz in frame `imu_link`: accelerometer and gyroscope; no orientation
  (`orientation_covariance[0] = -1`, the ROS convention for "not provided"), covariances 0 ("unknown");
- velocity, `geometry_msgs/msg/TwistStamped` at 200 Hz: the IMU's z-axis velocity in `twist.linear.z`;
- audio, `audio_common_msgs/msg/AudioDataStamped`: the binaural 44.1 kHz audio, interleaved, in chunks of
  `AUDIO_CHUNK` frames; `S16LE` when every sample is a 16-bit value (a simulated episode), else `S32LE`
  (an imported one's 24 bits); its `AudioInfo` once, at the start;
- joint states, `sensor_msgs/msg/JointState` at 200 Hz: each wheel's encoder position (the odometry
  modality) and, as velocity, the positions' central difference;
- `tf2_msgs/msg/TFMessage`: `odom` -> `base_link` at `POSE_RATE` on `/tf`, and `base_link` -> `imu_link`,
  `mic_left`, `mic_right` once on `/tf_static` (simulated episodes: an import has no pose);
- ground truth: `msvdd_bench_msgs/msg/Contact` for each contact of a simulated episode, and an
  `msvdd_bench_msgs/msg/AnomalyInterval` for each stretch of the label timeline that is not normal (its
  kind, sub-kind and wheel), published at its start;
- a metadata record `msvdd-bench`: the episode's id, category and split, and the dataset's fingerprint.

An episode writes the streams it carries: an import without IMU (MIMII) has no IMU topics, one without
wheel odometry no joint states. The bag's clock is the episode's, from 0 (a bag that starts at the Unix
epoch): sample i of the 200 Hz streams is stamped i / 200 s and audio sample j j / 44100 s, the pairing of
audio and IMU the dataset's windows use; the pose and the contacts keep the simulator's times. A message's
log time is its stamp (a recorder without delay), so the file is in time order. Writing an episode twice
gives the same bytes.
"""

from __future__ import annotations

import heapq
import itertools
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from mcap_ros2.writer import Writer

from benchmarks.episode import IMPORTED, SIMULATED, Episode, read_episode
from benchmarks.importers.writer import UNSPECIFIED
from benchmarks.ros2 import msgs
from benchmarks.ros2.topics import Topics
from msvdd.atomic import atomic_file
from msvdd.contract import IMU_RATE
from sim.vocab import LABELS, NORMAL, SUB_KINDS

AUDIO_CHUNK = 4410
"""Audio frames per message (0.1 s at 44.1 kHz)."""
POSE_RATE = 50.0
"""Rate of the `odom` -> `base_link` transforms, Hz."""
FRAMES: dict[str, str] = {"world": "odom", "base": "base_link", "imu": "imu_link"}
"""Frame ids: the world (odometry origin), the robot's base, the IMU."""
MIC_FRAMES: tuple[str, str] = ("mic_left", "mic_right")
"""Frame ids of the two microphones."""
METADATA_NAME = "msvdd-bench"
"""Name of the bag's metadata record."""

Item = tuple[int, int, str, str, dict[str, Any]]
"""(log time ns, topic rank, topic, message type, message) of one message to write."""


@dataclass(frozen=True)
class BagSummary:
    """What was written."""

    path: Path
    """The bag file."""
    messages: dict[str, int]
    """Messages per topic."""
    duration_s: float
    """Time from the first message to the last, s."""


def _ns(index: int, rate: int) -> int:
    """Nanoseconds of sample `index` at an integer `rate`, rounded to the nearest one."""
    return (index * msgs.NS * 2 + rate) // (2 * rate)


def _header(ns: int, frame: str = "") -> dict[str, Any]:
    return {"stamp": msgs.time_msg(ns), "frame_id": frame}


def _imu(episode: Episode, topics: Topics) -> Iterator[Item]:
    rate = int(IMU_RATE)
    covariance_unknown = [0.0] * 9
    for i, row in enumerate(np.asarray(episode.imu6, dtype=np.float64).tolist()):
        ns = _ns(i, rate)
        yield (
            ns,
            0,
            topics.imu,
            msgs.IMU,
            {
                "header": _header(ns, FRAMES["imu"]),
                "orientation_covariance": [-1.0] + [0.0] * 8,
                "angular_velocity": {"x": row[3], "y": row[4], "z": row[5]},
                "angular_velocity_covariance": covariance_unknown,
                "linear_acceleration": {"x": row[0], "y": row[1], "z": row[2]},
                "linear_acceleration_covariance": covariance_unknown,
            },
        )


def _velocity(episode: Episode, topics: Topics) -> Iterator[Item]:
    for i, vz in enumerate(np.asarray(episode.imu_vel_z, dtype=np.float64).tolist()):
        ns = _ns(i, int(IMU_RATE))
        yield (
            ns,
            1,
            topics.velocity,
            msgs.TWIST_STAMPED,
            {
                "header": _header(ns, FRAMES["imu"]),
                "twist": {"linear": {"x": 0.0, "y": 0.0, "z": vz}},
            },
        )


def _pcm(audio: np.ndarray) -> tuple[str, np.ndarray]:
    """The sample format and the integer samples that hold `audio` exactly (16 bits where they suffice)."""
    for sample_format, bits in (("S16LE", 16), ("S32LE", 32)):
        scaled = audio.astype(np.float64) * 2.0 ** (bits - 1)
        ints = np.clip(np.round(scaled), -(2 ** (bits - 1)), 2 ** (bits - 1) - 1)
        if bits == 32 or np.array_equal(ints, scaled):
            return sample_format, ints.astype(f"<i{bits // 8}")
    raise AssertionError("unreachable")


def _audio(episode: Episode, topics: Topics) -> Iterator[Item]:
    sample_format, ints = _pcm(episode.audio)
    rate, channels = int(episode.audio_rate), int(ints.shape[1])
    yield (
        0,
        2,
        topics.audio_info,
        msgs.AUDIO_INFO,
        {
            "channels": channels,
            "sample_rate": rate,
            "sample_format": sample_format,
            "bitrate": rate * channels * 8 * ints.dtype.itemsize,
            "coding_format": "wave",
        },
    )
    for j in range(0, ints.shape[0], AUDIO_CHUNK):
        ns = _ns(j, rate)
        yield (
            ns,
            3,
            topics.audio,
            msgs.AUDIO_DATA_STAMPED,
            {
                "header": _header(ns, "mic"),
                "audio": {"data": np.ascontiguousarray(ints[j : j + AUDIO_CHUNK]).tobytes()},
            },
        )


def _joints(episode: Episode, names: list[str], topics: Topics) -> Iterator[Item]:
    position = np.asarray(episode.wheel_pos, dtype=np.float64)
    velocity = np.gradient(position, 1.0 / IMU_RATE, axis=0) if position.shape[0] > 1 else position * 0
    for i, (p, v) in enumerate(zip(position.tolist(), velocity.tolist(), strict=True)):
        ns = _ns(i, int(IMU_RATE))
        yield (
            ns,
            4,
            topics.joint_states,
            msgs.JOINT_STATE,
            {
                "header": _header(ns),
                "name": names,
                "position": p,
                "velocity": v,
            },
        )


def _transform(
    ns: int, parent: str, child: str, xyz: Any, wxyz: Any = (1.0, 0.0, 0.0, 0.0)
) -> dict[str, Any]:
    return {
        "header": _header(ns, parent),
        "child_frame_id": child,
        "transform": {
            "translation": dict(zip("xyz", map(float, xyz), strict=True)),
            "rotation": {"w": float(wxyz[0]), "x": float(wxyz[1]), "y": float(wxyz[2]), "z": float(wxyz[3])},
        },
    }


def _pose(episode: Episode, topics: Topics) -> Iterator[Item]:
    trace = episode.trace()
    robot = trace.robot
    static = [_transform(0, FRAMES["base"], FRAMES["imu"], robot.imu_pos_body)]
    static += [_transform(0, FRAMES["base"], MIC_FRAMES[k], robot.mic_pos_body[k]) for k in range(2)]
    yield 0, 5, topics.tf_static, msgs.TF_MESSAGE, {"transforms": static}
    step = max(1, round(1.0 / (POSE_RATE * trace.physics_dt)))
    for k in range(0, trace.time.shape[0], step):
        ns = msgs.seconds_ns(float(trace.time[k]))
        tf = _transform(ns, FRAMES["world"], FRAMES["base"], trace.base_pos[k], trace.base_quat[k])
        yield ns, 6, topics.tf, msgs.TF_MESSAGE, {"transforms": [tf]}


def _contacts(episode: Episode, topics: Topics) -> Iterator[Item]:
    for c in sorted(episode.events().contacts, key=lambda c: c.time):
        ns = msgs.seconds_ns(c.time)
        yield (
            ns,
            7,
            topics.contacts,
            msgs.CONTACT,
            {
                "header": _header(ns, FRAMES["world"]),
                "position": dict(zip("xyz", c.position, strict=True)),
                "normal": dict(zip("xyz", c.normal, strict=True)),
                "impulse": c.impulse,
                "normal_speed": c.normal_speed,
                "duration": c.duration,
                "obstacle_kind": c.obstacle_kind,
                "material": c.material,
            },
        )


def anomaly_runs(episode: Episode) -> list[tuple[int, int, str, str, int]]:
    """[i0, i1) sample ranges of the label timeline that are not normal, each with its kind, sub-kind name
    and wheel: where the label, the sub-kind or the wheel changes, a new run starts. A sub-kind outside
    `sim.vocab.SUB_KINDS` (an import's own name) is the one of the episode's labelled span that holds the run,
    else `unspecified`."""
    keys = np.stack([episode.label, episode.sub_kind, episode.label_wheel], axis=1).astype(np.int64)
    change = np.flatnonzero(np.any(np.diff(keys, axis=0) != 0, axis=1)) + 1
    bounds = [0, *change.tolist(), keys.shape[0]]
    spans = (episode.events().anomalies or ()) if episode.source == IMPORTED else ()
    runs = []
    for i0, i1 in itertools.pairwise(bounds):
        label, sub_kind, wheel = (int(v) for v in keys[i0])
        if label == NORMAL:
            continue
        name = SUB_KINDS[sub_kind] if sub_kind else UNSPECIFIED
        middle = (i0 + i1) / 2 / IMU_RATE
        name = next(
            (a.sub_kind for a in spans if a.onset <= middle < a.end and a.kind == LABELS[label]), name
        )
        runs.append((i0, i1, LABELS[label], name, wheel))
    return runs


def _anomalies(episode: Episode, topics: Topics) -> Iterator[Item]:
    rate = int(IMU_RATE)
    for i0, i1, kind, sub_kind, wheel in anomaly_runs(episode):
        ns = _ns(i0, rate)
        yield (
            ns,
            8,
            topics.labels,
            msgs.ANOMALY_INTERVAL,
            {
                "header": _header(ns),
                "start": msgs.time_msg(ns),
                "end": msgs.time_msg(_ns(i1, rate)),
                "kind": kind,
                "sub_kind": sub_kind,
                "wheel": wheel,
            },
        )


def wheel_joint_names(episode: Episode) -> list[str]:
    """The wheels' joint names: `<wheel>_wheel_joint` after the simulated robot's wheel names, else
    `wheel_<k>_joint`."""
    if episode.source == SIMULATED:
        return [f"{name}_wheel_joint" for name in episode.trace().robot.wheel_names]
    return [f"wheel_{k}_joint" for k in range(episode.wheel_pos.shape[1])]


def write_bag(
    episode_folder: Path, out: Path, metadata: dict[str, str], topics: Topics | None = None
) -> BagSummary:
    """Write the episode folder `episode_folder` as the bag `out` (atomically: complete, or not at all).

    Args:
        episode_folder: an episode of a dataset (`benchmarks.episode`).
        out: the `.mcap` file to write.
        metadata: what the bag's metadata record says besides the episode's id, category and split.
        topics: the topics to write on (default `Topics()`).
    """
    topics = topics or Topics()
    episode = read_episode(episode_folder)
    streams = [_audio(episode, topics), _anomalies(episode, topics)]
    if "imu" in episode.modalities:  # an audio-only import's IMU arrays are placeholders
        streams += [_imu(episode, topics), _velocity(episode, topics)]
    if episode.wheel_pos.shape[1]:
        streams.append(_joints(episode, wheel_joint_names(episode), topics))
    if episode.source == SIMULATED:
        streams += [_pose(episode, topics), _contacts(episode, topics)]
    counts: dict[str, int] = {}
    first, last = None, 0
    with atomic_file(out) as handle:
        writer = Writer(handle)
        schemas: dict[str, Any] = {}
        for ns, _, topic, type_name, message in heapq.merge(*streams, key=lambda item: item[:2]):
            if type_name not in schemas:
                schemas[type_name] = writer.register_msgdef(type_name, msgs.schema_text(type_name))
            writer.write_message(topic, schemas[type_name], message, log_time=ns, publish_time=ns)
            counts[topic] = counts.get(topic, 0) + 1
            first = ns if first is None else first
            last = ns
        meta = episode.meta
        writer.add_metadata(
            METADATA_NAME,
            {"episode": meta.episode_id, "category": meta.category, "split": meta.split, **metadata},
        )
        writer.finish()
    return BagSummary(Path(out), counts, (last - (first or 0)) / msgs.NS)
