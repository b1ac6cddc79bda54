"""The ROS 2 message definitions a bag's schemas embed, as ROS 2 `.msg` text, and their concatenation.

A ROS 2 MCAP schema (encoding `ros2msg`) holds the message's own definition followed by every type it uses,
each after a line of 80 `=` and a `MSG: pkg/Type` line, as rosbag2 writes it; `schema_text` builds that from
the definitions below (the standard ones of `common_interfaces`, `geometry2` and `audio_common`, without their
comments, and two of this project's: `msvdd_bench_msgs/msg/AnomalyInterval` and `Contact`). Nothing is read
from the network or from a ROS installation.
"""

from __future__ import annotations

import math

SEPARATOR = "=" * 80
"""The line between the definitions of a concatenated schema."""

PRIMITIVES: frozenset[str] = frozenset(
    {
        *("bool", "byte", "char", "float32", "float64", "string", "wstring"),
        *("int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64"),
    }
)
"""Field types that are not messages."""

IMU = "sensor_msgs/msg/Imu"
JOINT_STATE = "sensor_msgs/msg/JointState"
TWIST_STAMPED = "geometry_msgs/msg/TwistStamped"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
AUDIO_DATA = "audio_common_msgs/msg/AudioData"
AUDIO_DATA_STAMPED = "audio_common_msgs/msg/AudioDataStamped"
AUDIO_INFO = "audio_common_msgs/msg/AudioInfo"
ANOMALY_INTERVAL = "msvdd_bench_msgs/msg/AnomalyInterval"
CONTACT = "msvdd_bench_msgs/msg/Contact"

_DEFINITIONS: dict[str, str] = {
    "builtin_interfaces/Time": "int32 sec\nuint32 nanosec\n",
    "std_msgs/Header": "builtin_interfaces/Time stamp\nstring frame_id\n",
    "geometry_msgs/Vector3": "float64 x\nfloat64 y\nfloat64 z\n",
    "geometry_msgs/Point": "float64 x\nfloat64 y\nfloat64 z\n",
    "geometry_msgs/Quaternion": "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
    "geometry_msgs/Twist": "Vector3 linear\nVector3 angular\n",
    "geometry_msgs/TwistStamped": "std_msgs/Header header\nTwist twist\n",
    "geometry_msgs/Transform": "Vector3 translation\nQuaternion rotation\n",
    "geometry_msgs/TransformStamped": "std_msgs/Header header\nstring child_frame_id\nTransform transform\n",
    "tf2_msgs/TFMessage": "geometry_msgs/TransformStamped[] transforms\n",
    "sensor_msgs/Imu": (
        "std_msgs/Header header\n"
        "geometry_msgs/Quaternion orientation\n"
        "float64[9] orientation_covariance\n"
        "geometry_msgs/Vector3 angular_velocity\n"
        "float64[9] angular_velocity_covariance\n"
        "geometry_msgs/Vector3 linear_acceleration\n"
        "float64[9] linear_acceleration_covariance\n"
    ),
    "sensor_msgs/JointState": (
        "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n"
    ),
    "audio_common_msgs/AudioData": "uint8[] data\n",
    "audio_common_msgs/AudioDataStamped": "std_msgs/Header header\naudio_common_msgs/AudioData audio\n",
    "audio_common_msgs/AudioInfo": (
        "uint8 channels\nuint32 sample_rate\nstring sample_format\nuint32 bitrate\nstring coding_format\n"
    ),
    "msvdd_bench_msgs/AnomalyInterval": (
        "# A labelled anomaly over [start, end) of the recording's clock; published at its start.\n"
        "std_msgs/Header header\n"
        "builtin_interfaces/Time start\n"
        "builtin_interfaces/Time end\n"
        "string kind  # collision or mechanical\n"
        "string sub_kind  # an obstacle kind, a fault kind, or free text\n"
        "int32 wheel  # the faulty wheel's index for a mechanical anomaly; -1 otherwise\n"
    ),
    "msvdd_bench_msgs/Contact": (
        "# A robot-obstacle contact; header.stamp is its first instant, header.frame_id the world frame.\n"
        "std_msgs/Header header\n"
        "geometry_msgs/Point position\n"
        "geometry_msgs/Vector3 normal  # unit, from the obstacle to the robot\n"
        "float64 impulse  # normal impulse over the contact, N s\n"
        "float64 normal_speed  # approach speed along the normal, m/s\n"
        "float64 duration  # s\n"
        "string obstacle_kind\n"
        "string material\n"
    ),
}
"""Definition text by `pkg/Type`."""


def short_name(type_name: str) -> str:
    """`pkg/Type` of `pkg/msg/Type` (or of `pkg/Type`)."""
    parts = type_name.split("/")
    return f"{parts[0]}/{parts[-1]}"


def full_name(type_name: str) -> str:
    """`pkg/msg/Type` of `pkg/Type` (or of `pkg/msg/Type`): how rosbag2 names a schema."""
    package, name = short_name(type_name).split("/")
    return f"{package}/msg/{name}"


def _field_types(package: str, text: str) -> list[str]:
    """The message types (`pkg/Type`) the fields of a definition use, in order."""
    found: list[str] = []
    for line in text.splitlines():
        words = line.split("#", 1)[0].split()
        if len(words) < 2:
            continue
        base = words[0].split("[", 1)[0].split("<=", 1)[0]
        if base in PRIMITIVES:
            continue
        found.append(base if "/" in base else f"{package}/{base}")
    return found


def _dependencies(name: str) -> list[str]:
    """Every type `name` uses, directly or not, depth first in order of first use."""
    order: list[str] = []

    def visit(current: str) -> None:
        for dep in _field_types(current.split("/")[0], _DEFINITIONS[current]):
            if dep not in order:
                order.append(dep)
                visit(dep)

    visit(name)
    return order


def schema_text(type_name: str) -> str:
    """The concatenated definition of `type_name` (`pkg/msg/Type`) that a ROS 2 MCAP schema holds.

    Raises:
        KeyError: a type this module does not define.
    """
    name = short_name(type_name)
    parts = [_DEFINITIONS[name].rstrip("\n")]
    for dep in _dependencies(name):
        parts.append(f"{SEPARATOR}\nMSG: {dep}\n{_DEFINITIONS[dep].rstrip(chr(10))}")
    return "\n".join(parts) + "\n"


def defined(type_name: str) -> bool:
    """Whether this module defines `type_name` (`pkg/msg/Type` or `pkg/Type`)."""
    return short_name(type_name) in _DEFINITIONS


NS = 1_000_000_000
"""Nanoseconds per second."""


def time_msg(ns: int) -> dict[str, int]:
    """A `builtin_interfaces/Time` of `ns` nanoseconds (>= 0)."""
    sec, nanosec = divmod(int(ns), NS)
    return {"sec": sec, "nanosec": nanosec}


def time_ns(stamp: object) -> int:
    """Nanoseconds of a decoded `builtin_interfaces/Time`."""
    return int(stamp.sec) * NS + int(stamp.nanosec)  # type: ignore[attr-defined]


def seconds_ns(seconds: float) -> int:
    """Nanoseconds of `seconds`, rounded to the nearest one."""
    return math.floor(seconds * NS + 0.5)
