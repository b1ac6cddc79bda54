"""What `msvdd-bench import` is told: the options every layout shares, and those of the folder, windows and
ros2 layouts; with the parsers of their text forms (`--imu-columns`, `--channels`, the ros2 topic mapping)."""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

from benchmarks.errors import UserError
from benchmarks.ros2.topics import READ_TYPES, Topics
from msvdd.stream import GapPolicy

LAYOUTS: tuple[str, ...] = ("folder", "mimii", "windows", "ros2")
"""Source layouts `import` reads (one module each in `benchmarks.importers`)."""
ANOMALY_KINDS: tuple[str, ...] = ("collision", "mechanical")
"""Kinds an imported anomaly can have: the benchmark's (metrics and reports split by them)."""
TIME_UNITS: dict[str, float] = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
"""Units of an IMU CSV's time column, with their length in seconds."""
IMU_FIELDS: tuple[str, ...] = ("t", "ax", "ay", "az", "gx", "gy", "gz")
"""Canonical IMU CSV fields: time, accelerometer xyz (m/s^2), gyroscope xyz (rad/s)."""
OPTIONAL_IMU_FIELDS: tuple[str, ...] = ("vz",)
"""Optional field: z-axis velocity (m/s); without it, it is estimated from `az`."""


class SourceError(UserError):
    """A source file or folder to import is missing, unreadable or inconsistent; the message names the
    file, the field or column, the value and what is allowed."""


@dataclass(frozen=True)
class SplitConfig:
    """How recordings without anomaly labels are shared between training, validation and test."""

    test_fraction: float = 0.25
    """Share of the nominal recordings of each group held out for test: the last ones in name order."""
    val_fraction: float = 0.1
    """Share of the remaining nominal recordings held out as validation: the last ones before the test."""

    def __post_init__(self) -> None:
        for name, value in (("--test-fraction", self.test_fraction), ("--val-fraction", self.val_fraction)):
            if not (math.isfinite(value) and 0.0 <= value < 1.0):
                raise UserError(f"{name} = {value} is invalid; allowed: 0 <= fraction < 1")


@dataclass(frozen=True)
class ImportConfig:
    """Options shared by every layout."""

    train_hop_s: float = 1.0
    """Hop between 2 s windows of training and validation recordings, s."""
    test_hop_s: float = 2.0
    """Hop between 2 s windows of test recordings, s."""
    scale: str = "short"
    """Training budget `train` uses on the dataset by default (smoke, short, full)."""
    anomaly_kind: str = "mechanical"
    """Kind of an anomaly whose source does not say (`collision` or `mechanical`)."""
    channels: tuple[int, ...] | None = None
    """Channels of a multichannel file to keep (one: duplicated; two: left, right); None: mono or stereo."""
    audio_rate: float | None = None
    """Sample rate every audio file must have, Hz; None: any (each is resampled to 44.1 kHz)."""
    split: SplitConfig = field(default_factory=SplitConfig)
    """How nominal recordings are split."""

    def __post_init__(self) -> None:
        from benchmarks.methods.base import check_scale

        for name, value in (("--train-hop", self.train_hop_s), ("--test-hop", self.test_hop_s)):
            if not (math.isfinite(value) and value > 0):
                raise UserError(f"{name} = {value} is invalid; allowed: > 0 s")
        check_scale(self.scale)
        if self.anomaly_kind not in ANOMALY_KINDS:
            raise UserError(
                f"--anomaly-kind = {self.anomaly_kind!r} is invalid; allowed: {', '.join(ANOMALY_KINDS)}"
            )
        if self.channels is not None and len(self.channels) not in (1, 2):
            raise UserError(f"--channels = {self.channels} is invalid; allowed: one or two channel indices")
        if self.audio_rate is not None and not (math.isfinite(self.audio_rate) and self.audio_rate > 0):
            raise UserError(f"--audio-rate = {self.audio_rate} is invalid; allowed: > 0 Hz")


@dataclass(frozen=True)
class ImuColumns:
    """Which CSV column holds each IMU field (`--imu-columns t=time,ax=acc_x,...`)."""

    t: str = "t"
    """Time stamps (unit: `FolderConfig.time_unit`)."""
    ax: str = "ax"
    """Accelerometer x, m/s^2."""
    ay: str = "ay"
    """Accelerometer y, m/s^2."""
    az: str = "az"
    """Accelerometer z, m/s^2."""
    gx: str = "gx"
    """Gyroscope x, rad/s."""
    gy: str = "gy"
    """Gyroscope y, rad/s."""
    gz: str = "gz"
    """Gyroscope z, rad/s."""
    vz: str | None = None
    """z-axis velocity, m/s (the paper's IMU input); None: estimated from `az`."""


def parse_imu_columns(text: str) -> ImuColumns:
    """`t=time,ax=acc_x,...`: any subset of the fields, the others keep their canonical column names.

    Raises:
        UserError: a malformed pair, an unknown or repeated field.
    """
    allowed = (*IMU_FIELDS, *OPTIONAL_IMU_FIELDS)
    found: dict[str, str] = {}
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        key, sep, column = (s.strip() for s in part.partition("="))
        if not sep or not key or not column:
            raise UserError(f"--imu-columns: {part!r} is not FIELD=COLUMN (e.g. ax=acc_x)")
        if key not in allowed:
            raise UserError(f"--imu-columns: field {key!r} is unknown; allowed: {', '.join(allowed)}")
        if key in found:
            raise UserError(f"--imu-columns: field {key!r} is given twice")
        found[key] = column
    return ImuColumns(**found)


def parse_channels(text: str) -> tuple[int, ...]:
    """`0,1` (left, right) or `3` (one channel, duplicated)."""
    try:
        channels = tuple(int(c) for c in text.split(","))
    except ValueError:
        raise UserError(f"--channels = {text!r} is invalid; allowed: one or two indices, e.g. 0,1") from None
    if len(channels) not in (1, 2) or min(channels) < 0:
        raise UserError(f"--channels = {text!r} is invalid; allowed: one or two indices >= 0, e.g. 0,1")
    return channels


@dataclass(frozen=True)
class FolderConfig:
    """Options of the folder layout (audio files with IMU CSVs and a label CSV)."""

    imu_columns: ImuColumns = field(default_factory=ImuColumns)
    """Column of each IMU field."""
    time_unit: str = "s"
    """Unit of the time column: s, ms, us or ns."""
    imu_rate: float | None = None
    """IMU rate the time stamps must show, Hz (within 5 %); None: any (resampled to 200 Hz)."""
    labels: str | None = None
    """Label CSV (recording, start_s, end_s[, kind][, sub_kind]); None: no anomalies."""
    split_file: str | None = None
    """CSV (recording, split) fixing the split of some recordings; None: the split rule for all."""
    no_imu: bool = False
    """The recordings have no IMU: import audio only."""
    max_length_mismatch_s: float = 0.1
    """Largest difference between a recording's audio and IMU durations, s (both are cut to the shorter)."""

    def __post_init__(self) -> None:
        if self.time_unit not in TIME_UNITS:
            raise UserError(f"--time-unit = {self.time_unit!r} is invalid; allowed: {', '.join(TIME_UNITS)}")
        if self.imu_rate is not None and not (math.isfinite(self.imu_rate) and self.imu_rate > 0):
            raise UserError(f"--imu-rate = {self.imu_rate} is invalid; allowed: > 0 Hz")
        if not (math.isfinite(self.max_length_mismatch_s) and self.max_length_mismatch_s >= 0):
            raise UserError(
                f"--max-length-mismatch = {self.max_length_mismatch_s} is invalid; allowed: >= 0 s"
            )


@dataclass(frozen=True)
class WindowsConfig:
    """Options of the windows layout (pre-cut normal-train, normal-test and abnormal window arrays)."""

    audio_rate: float = 4410.0
    """Sample rate of the audio windows, Hz (the paper's code: 4410, 44.1 kHz decimated by 10)."""
    imu_rate: float = 200.0
    """Sample rate of the IMU windows, Hz."""

    def __post_init__(self) -> None:
        for name, value in (("--audio-rate", self.audio_rate), ("--imu-rate", self.imu_rate)):
            if not (math.isfinite(value) and value > 0):
                raise UserError(f"{name} = {value} is invalid; allowed: > 0 Hz")


@dataclass(frozen=True)
class Ros2Config:
    """Options of the ros2 layout (ROS 2 bags in MCAP)."""

    topics: Topics = field(default_factory=Topics)
    """Topic of each stream (`benchmarks.ros2.topics.Topics`)."""
    named: tuple[str, ...] = ()
    """Streams whose topic a flag or the mapping file named: a bag without it is refused (the default topic
    of an optional stream, `velocity` or `joint_states`, is read where the bag has it; the labels topic
    need only be in the bags that hold an anomaly)."""
    labels: str | None = None
    """Label CSV (recording, start_s, end_s[, kind][, sub_kind]; seconds from the recording's first
    message); None: no label CSV."""
    labels_topic: bool = False
    """Read the anomaly intervals of `topics.labels` (`msvdd_bench_msgs/msg/AnomalyInterval`)."""
    split_file: str | None = None
    """CSV (recording, split) fixing the split of some recordings; None: the split rule for all."""
    wheel_joints: tuple[str, ...] | None = None
    """Joints of `sensor_msgs/msg/JointState` that are the wheels, in order; None: every joint whose name
    holds `wheel`, in the order of the first message."""
    policy: GapPolicy = field(default_factory=GapPolicy)
    """How jitter, gaps, duplicate and late stamps are treated: the streaming scorer's policy."""

    def __post_init__(self) -> None:
        if self.labels is not None and self.labels_topic:
            raise UserError("--labels and --labels-topic: give one source of labels, not both")
        if self.wheel_joints is not None and not self.wheel_joints:
            raise UserError("wheel joints: an empty list; allowed: one or more joint names")


def gap_policy(jitter_s: float | None, max_fill_s: float | None) -> GapPolicy:
    """The streaming scorer's `GapPolicy` with `--jitter` and `--max-fill` where given (None: its default).

    Raises:
        UserError: a value the policy refuses (naming the flag).
    """
    default = GapPolicy()
    jitter = default.jitter_s if jitter_s is None else jitter_s
    fill = default.max_fill_s if max_fill_s is None else max_fill_s
    if not (math.isfinite(jitter) and jitter >= 0):
        raise UserError(f"--jitter = {jitter} is invalid; allowed: >= 0 s")
    if not (math.isfinite(fill) and fill >= jitter):
        raise UserError(f"--max-fill = {fill} is invalid; allowed: >= the jitter tolerance ({jitter:g} s)")
    return GapPolicy(jitter_s=jitter, max_fill_s=fill)


MAPPING_KEYS: tuple[str, ...] = (*READ_TYPES, "wheel_joints")
"""Keys of a ros2 topic mapping file: a topic per stream read, and the wheel joints."""


def read_topic_mapping(path: Path) -> dict[str, str | tuple[str, ...]]:
    """A TOML topic mapping file: `imu = "/my/imu"`, ..., `wheel_joints = ["wl", "wr"]` (any subset).

    Raises:
        UserError: unreadable TOML, an unknown key, or a value of the wrong type.
    """
    try:
        doc = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise UserError(f"--topics {path}: not a readable TOML file ({exc})") from exc
    out: dict[str, str | tuple[str, ...]] = {}
    for key, value in doc.items():
        if key not in MAPPING_KEYS:
            raise UserError(f"--topics {path}: key {key!r} is unknown; allowed: {', '.join(MAPPING_KEYS)}")
        if key == "wheel_joints":
            if not (isinstance(value, list) and value and all(isinstance(v, str) and v for v in value)):
                raise UserError(f"--topics {path}: wheel_joints = {value!r}; allowed: a list of joint names")
            out[key] = tuple(value)
        elif isinstance(value, str) and value.startswith("/"):
            out[key] = value
        else:
            raise UserError(f'--topics {path}: {key} = {value!r}; allowed: a topic name such as "/imu/data"')
    return out


def ros2_config(
    mapping: dict[str, str | tuple[str, ...]], flags: dict[str, str | None], **options: object
) -> Ros2Config:
    """A `Ros2Config` from a topic mapping (`read_topic_mapping`, may be empty), topic flags by stream (None:
    not given; a flag wins over the file; a `labels` topic reads the labels from it) and the other options
    (`Ros2Config`'s other fields)."""
    given = {**mapping, **{k: v for k, v in flags.items() if v is not None}}
    names = {f.name for f in fields(Topics)}
    topics = replace(Topics(), **{k: v for k, v in given.items() if k in names and isinstance(v, str)})
    wheels = given.get("wheel_joints")
    return Ros2Config(
        topics=topics,
        named=tuple(k for k in READ_TYPES if k in given),
        labels_topic="labels" in given,
        wheel_joints=wheels if isinstance(wheels, tuple) else None,
        **options,  # type: ignore[arg-type]
    )
