"""The topics of a bag: where each stream is (the defaults are what `export-bag` writes and what
`import --layout ros2` reads) and the message types each stream may carry."""

from __future__ import annotations

from dataclasses import dataclass, fields

from benchmarks.ros2 import msgs


@dataclass(frozen=True)
class Topics:
    """The topic of each stream of a bag."""

    imu: str = "/imu/data"
    """`sensor_msgs/msg/Imu`: accelerometer and gyroscope, one sample a message."""
    velocity: str = "/imu/velocity"
    """`geometry_msgs/msg/TwistStamped`: the IMU's z-axis velocity (`twist.linear.z`, the paper's input)."""
    audio: str = "/audio/audio_stamped"
    """`audio_common_msgs/msg/AudioDataStamped` (or unstamped `AudioData`): interleaved PCM in chunks."""
    audio_info: str = "/audio/audio_info"
    """`audio_common_msgs/msg/AudioInfo`: the audio's rate, channels and sample format."""
    joint_states: str = "/joint_states"
    """`sensor_msgs/msg/JointState`: the wheels' encoder positions (or their velocities)."""
    labels: str = "/ground_truth/anomalies"
    """`msvdd_bench_msgs/msg/AnomalyInterval`: the ground-truth anomaly intervals, one a message."""
    contacts: str = "/ground_truth/contacts"
    """`msvdd_bench_msgs/msg/Contact`: the simulator's robot-obstacle contacts (written, not read)."""
    tf: str = "/tf"
    """`tf2_msgs/msg/TFMessage`: the robot's pose, `odom` to `base_link` (written, not read)."""
    tf_static: str = "/tf_static"
    """`tf2_msgs/msg/TFMessage`: where the IMU and the microphones sit on the robot (written, not read)."""


STREAMS: tuple[str, ...] = tuple(f.name for f in fields(Topics))
"""Every stream's name (the fields of `Topics`)."""

READ_TYPES: dict[str, tuple[str, ...]] = {
    "imu": (msgs.IMU,),
    "velocity": (msgs.TWIST_STAMPED,),
    "audio": (msgs.AUDIO_DATA_STAMPED, msgs.AUDIO_DATA),
    "audio_info": (msgs.AUDIO_INFO,),
    "joint_states": (msgs.JOINT_STATE,),
    "labels": (msgs.ANOMALY_INTERVAL,),
}
"""The streams `import --layout ros2` reads, with the message types each may carry."""

REQUIRED: tuple[str, ...] = ("imu", "audio", "audio_info")
"""Streams every bag must have; the others are read where the bag has them (or where named)."""
