"""The ros2 layout: ROS 2 bags in MCAP (what `ros2 bag record` writes since Jazzy), one recording each.

    SOURCE.mcap                     one bag
    SOURCE/                         a folder: every .mcap file under it is a bag, except that the .mcap
      day1/run01.mcap               files of a rosbag2 folder (one with metadata.yaml) are one bag together
      run02/metadata.yaml  run02/run02_0.mcap  run02/run02_1.mcap
    labels.csv                      recording,start_s,end_s[,kind][,sub_kind]  (--labels; anywhere)

A recording is named by its bag's path under SOURCE without the suffix (a rosbag2 folder: the folder's path).
The streams read, on the topics of `benchmarks.ros2.topics.Topics` (flags or a TOML mapping name others):

- IMU, `sensor_msgs/msg/Imu`, one sample a message: `linear_acceleration` and `angular_velocity`;
- z velocity, `geometry_msgs/msg/TwistStamped` `twist.linear.z`, where the bag has it; otherwise it is
  estimated from the z acceleration as in the folder layout;
- audio, `audio_common_msgs/msg/AudioDataStamped` (timed by its header) or `AudioData` (its first chunk timed
  by its log time, the others following on), with `AudioInfo` (channels, rate, sample format);
- wheel odometry, `sensor_msgs/msg/JointState`, where the bag has it: the wheel joints' positions (or their
  velocities, integrated), the odometry modality;
- labels: a CSV of intervals (seconds from the bag's first message, its log time) or
  `msvdd_bench_msgs/msg/AnomalyInterval` messages (header-stamp times), `--labels-topic`.

Header stamps decide alignment: each stream is laid out by the streaming scorer's gap policy
(`benchmarks.importers.timed`), the episode starts at the first IMU sample at or after every stream's start
and ends where the first stream ends. Then audio is resampled to 44.1 kHz stereo and the IMU-rate streams are
brought to 200 Hz (`benchmarks.importers.signals`).
"""

from __future__ import annotations

import functools
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
from scipy import integrate

from benchmarks.importers import bags
from benchmarks.importers.bags import Bag, BagInfo
from benchmarks.importers.config import ANOMALY_KINDS, ImportConfig, Ros2Config, SourceError
from benchmarks.importers.folder import check_sub_kind, read_labels, read_split_file
from benchmarks.importers.signals import estimate_vel_z, pick_channels, to_stereo_rate
from benchmarks.importers.timed import Series, StreamReport, assemble, common_span, nominal_rate, on_imu_grid
from benchmarks.importers.writer import UNSPECIFIED, Planned, Recording, Span
from benchmarks.ros2 import msgs
from benchmarks.ros2.topics import READ_TYPES, REQUIRED
from msvdd.contract import IMU_RATE

SAMPLE_FORMATS: dict[str, tuple[str, float, float]] = {
    "U8": ("u1", 128.0, 128.0),
    "S16LE": ("<i2", 0.0, 2.0**15),
    "S24LE": ("<i4", 0.0, 2.0**23),
    "S32LE": ("<i4", 0.0, 2.0**31),
    "F32LE": ("<f4", 0.0, 1.0),
    "F64LE": ("<f8", 0.0, 1.0),
}
"""`AudioInfo.sample_format` -> (NumPy type of one sample, offset, full scale): value = (raw - offset) /
full scale. S24LE is packed in 3 bytes (widened to 4 before reading)."""
RAW_CODINGS: tuple[str, ...] = ("", "wave", "wav", "raw", "pcm")
"""`AudioInfo.coding_format` values of uncompressed PCM (case ignored); compressed audio is not read."""
WHEEL_TOKEN = "wheel"
"""Without `wheel_joints`, the wheels are the joints whose name holds this (case ignored)."""


LabelSpan = tuple[float, float, str, str, int]
"""A labelled interval: start and end (s from the bag's start), kind, sub-kind, wheel (-1: not known)."""


def _where(bag: Bag, topic: str | None = None) -> str:
    name = str(bag.files[0]) if len(bag.files) == 1 else f"bag {bag.name} ({bag.files[0].parent})"
    return name if topic is None else f"{name}, topic {topic}"


def _streams(bag: Bag, info: BagInfo, ros2: Ros2Config) -> dict[str, str]:
    """The streams to read from the bag and their topics, after checking they exist and carry a type read.

    Raises:
        SourceError: a required or named topic missing (naming the bag's topics), or an unsupported type.
    """
    wanted = {s: getattr(ros2.topics, s) for s in READ_TYPES if s != "labels" or ros2.labels_topic}
    # A bag without the labels topic has no labelled anomaly (`plan` checks that some bag has it).
    out: dict[str, str] = {}
    for stream, topic in wanted.items():
        found = info.topics.get(topic)
        if found is None:
            if stream in REQUIRED or (stream in ros2.named and stream != "labels"):
                raise SourceError(
                    f"{_where(bag)}: no topic {topic!r} for the {stream} stream "
                    f"({' or '.join(READ_TYPES[stream])}); the bag's topics: {bags.describe(info.topics)}; "
                    f"allowed: name the topic with --{stream.replace('_', '-')}-topic or in a --topics file"
                )
            continue
        if found.type not in READ_TYPES[stream]:
            raise SourceError(
                f"{_where(bag, topic)}: message type {found.type} for the {stream} stream; supported: "
                f"{', '.join(READ_TYPES[stream])}"
            )
        out[stream] = topic
    return out


def _seconds(ns: int, origin_ns: int) -> float:
    return (ns - origin_ns) / msgs.NS


def _header_s(message: Any, origin_ns: int) -> float:
    return _seconds(msgs.time_ns(message.header.stamp), origin_ns)


def _topic_spans(bag: Bag, topic: str, origin_ns: int) -> list[LabelSpan]:
    """The `AnomalyInterval` messages of the labels topic as label spans."""
    where = _where(bag, topic)
    out: list[LabelSpan] = []
    for _, log_ns, m in bags.read(bag, [topic]):
        start, end = _seconds(msgs.time_ns(m.start), origin_ns), _seconds(msgs.time_ns(m.end), origin_ns)
        at = f"{where}, message logged {_seconds(log_ns, origin_ns):.3f} s after the bag's start"
        if not start < end:
            raise SourceError(f"{at}: start {start:.3f} s >= end {end:.3f} s; allowed: start < end")
        if m.kind not in ANOMALY_KINDS:
            raise SourceError(f"{at}: kind {m.kind!r}; allowed: {', '.join(ANOMALY_KINDS)}")
        out.append((start, end, str(m.kind), check_sub_kind(m.sub_kind or UNSPECIFIED, at), int(m.wheel)))
    return out


def _decode_pcm(data: bytes, sample_format: str, channels: int, where: str) -> np.ndarray:
    """(k, channels) float64 samples of one chunk of interleaved PCM."""
    dtype, offset, scale = SAMPLE_FORMATS[sample_format]
    raw = np.frombuffer(data, dtype=np.uint8)
    width = 3 if sample_format == "S24LE" else np.dtype(dtype).itemsize
    if raw.size % (width * channels):
        raise SourceError(
            f"{where}: a chunk of {raw.size} bytes is not whole {sample_format} frames of {channels} "
            "channel(s); allowed: chunks of whole frames"
        )
    if sample_format == "S24LE":  # 3 bytes a sample: put them in the top of an int32, then scale back
        wide = np.zeros((raw.size // 3, 4), dtype=np.uint8)
        wide[:, 1:] = raw.reshape(-1, 3)
        values = wide.view("<i4").reshape(-1) / 256.0
    else:
        values = raw.view(dtype).astype(np.float64)
    return ((values - offset) / scale).reshape(-1, channels)


def _audio(
    messages: dict[str, list[tuple[int, Any]]],
    streams: dict[str, str],
    info: BagInfo,
    bag: Bag,
    config: ImportConfig,
    ros2: Ros2Config,
) -> tuple[Series, dict[str, Any]]:
    """The audio stream laid out at its own rate, and what `AudioInfo` said, for the provenance."""
    info_where = _where(bag, streams["audio_info"])
    formats = {
        (int(m.channels), int(m.sample_rate), str(m.sample_format), str(m.coding_format).lower())
        for _, m in messages[streams["audio_info"]]
    }
    if len(formats) != 1:
        raise SourceError(f"{info_where}: {len(formats)} different formats; allowed: one audio format")
    channels, rate, sample_format, coding = next(iter(formats))
    if coding not in RAW_CODINGS:
        raise SourceError(
            f"{info_where}: coding_format {coding!r}; allowed: uncompressed PCM "
            f"({', '.join(repr(c) for c in RAW_CODINGS)})"
        )
    if sample_format not in SAMPLE_FORMATS or channels < 1 or rate < 1:
        raise SourceError(
            f"{info_where}: sample_format {sample_format!r}, {channels} channel(s), {rate} Hz; allowed: "
            f"sample formats {', '.join(SAMPLE_FORMATS)}, at least one channel, a rate > 0"
        )
    if config.audio_rate is not None and rate != config.audio_rate:
        raise SourceError(
            f"{info_where}: sample rate {rate} Hz, but --audio-rate is {config.audio_rate:g} Hz; allowed: "
            "audio at --audio-rate only (leave --audio-rate out to resample any rate)"
        )
    where = _where(bag, streams["audio"])
    stamped = info.topics[streams["audio"]].type == msgs.AUDIO_DATA_STAMPED
    chunks: list[tuple[float | None, np.ndarray]] = []
    for i, (log_ns, m) in enumerate(messages[streams["audio"]]):
        t = _header_s(m, info.start_ns) if stamped else _seconds(log_ns, info.start_ns) if i == 0 else None
        payload = m.audio if stamped else m
        data = getattr(payload, "data", None)
        if data is None:  # another package's AudioData under the same name
            fields = ", ".join(getattr(payload, "__slots__", ())) or "none"
            raise SourceError(
                f"{where}: its AudioData has no field `data` (its fields: {fields}); supported: "
                "audio_common_msgs/AudioData as `uint8[] data` (ros-drivers/audio_common)"
            )
        chunks.append((t, _decode_pcm(bytes(data), sample_format, channels, where)))
    facts = {
        "audio_rate": rate,
        "audio_channels": channels,
        "audio_format": sample_format,
        "audio_stamped": stamped,
    }
    return assemble(chunks, float(rate), ros2.policy, hold=False, where=where), facts


def _per_sample(
    messages: list[tuple[int, Any]], values: Any, origin_ns: int, ros2: Ros2Config, where: str
) -> Series:
    """A stream of one sample a message (`values(message)` -> its row), laid out at its nominal rate."""
    stamps = np.array([_header_s(m, origin_ns) for _, m in messages])
    rate = nominal_rate(stamps, f"{where} (are its header stamps set?)")
    rows = [
        (float(t), np.asarray([values(m)], dtype=np.float64))
        for t, (_, m) in zip(stamps, messages, strict=True)
    ]
    return assemble(rows, rate, ros2.policy, hold=True, where=where)


def _imu_row(m: Any) -> list[float]:
    """Accelerometer xyz then gyroscope xyz of an `Imu` message."""
    acc, gyro = m.linear_acceleration, m.angular_velocity
    return [acc.x, acc.y, acc.z, gyro.x, gyro.y, gyro.z]


def _joint_rows(messages: list[tuple[int, Any]], ros2: Ros2Config, where: str) -> tuple[tuple[str, ...], str]:
    """The wheel joints and which field holds them (`position`, else `velocity`), from the first message."""
    first = messages[0][1]
    names = ros2.wheel_joints or tuple(n for n in first.name if WHEEL_TOKEN in n.lower())
    if not names:
        raise SourceError(
            f"{where}: no joint name holds {WHEEL_TOKEN!r} (joints: {', '.join(first.name) or '(none)'}); "
            "allowed: name the wheel joints with --wheel-joints or wheel_joints in a --topics file"
        )
    for field_name in ("position", "velocity"):
        if len(getattr(first, field_name)) == len(first.name):
            return names, field_name
    raise SourceError(f"{where}: the joint states hold neither positions nor velocities of every joint")


def _wheels(
    messages: list[tuple[int, Any]], origin_ns: int, ros2: Ros2Config, where: str
) -> tuple[Series, dict[str, Any]]:
    """The wheel joints' positions (or velocities) laid out at their nominal rate, and the provenance."""
    names, field_name = _joint_rows(messages, ros2, where)

    def row(m: Any) -> list[float]:
        values = getattr(m, field_name)
        try:
            return [float(values[list(m.name).index(n)]) for n in names]
        except (ValueError, IndexError):
            raise SourceError(
                f"{where}: a message at {_header_s(m, origin_ns):.3f} s lacks the {field_name} of a wheel "
                f"joint ({', '.join(names)}); allowed: every message with every wheel joint"
            ) from None

    series = _per_sample(messages, row, origin_ns, ros2, where)
    return series, {"wheel_joints": list(names), "wheel_pos_from_velocity": field_name == "velocity"}


def _load(bag: Bag, info: BagInfo, streams: dict[str, str], spans: list[LabelSpan], config: ImportConfig,
          ros2: Ros2Config) -> Recording:  # fmt: skip
    read = [t for s, t in streams.items() if s != "labels"]
    messages: dict[str, list[tuple[int, Any]]] = {t: [] for t in read}
    for topic, log_ns, m in bags.read(bag, read):
        messages[topic].append((log_ns, m))
    origin = info.start_ns
    audio, provenance = _audio(messages, streams, info, bag, config, ros2)
    series = {"audio": audio}
    series["imu"] = imu = _per_sample(
        messages[streams["imu"]], _imu_row, origin, ros2, _where(bag, streams["imu"])
    )
    if "velocity" in streams:
        series["velocity"] = _per_sample(
            messages[streams["velocity"]],
            lambda m: [m.twist.linear.z],
            origin,
            ros2,
            _where(bag, streams["velocity"]),
        )
    if "joint_states" in streams:
        series["joint_states"], wheel_facts = _wheels(
            messages[streams["joint_states"]], origin, ros2, _where(bag, streams["joint_states"])
        )
        provenance |= wheel_facts
    t0, n = common_span(list(series.values()), imu)
    if n < 1:
        raise SourceError(f"{_where(bag)}: its streams ({', '.join(streams)}) share no stretch of time")
    imu6 = on_imu_grid(imu, t0, n)
    vel_z = (
        on_imu_grid(series["velocity"], t0, n)[:, 0] if "velocity" in series else estimate_vel_z(imu6[:, 2])
    )
    wheel_pos = None
    if "joint_states" in series:
        wheel_pos = on_imu_grid(series["joint_states"], t0, n)
        if provenance["wheel_pos_from_velocity"]:
            wheel_pos = integrate.cumulative_trapezoid(wheel_pos, dx=1.0 / IMU_RATE, axis=0, initial=0.0)
    a0 = round((t0 - audio.start_s) * audio.rate)
    a1 = a0 + int(np.ceil(n / IMU_RATE * audio.rate))
    stereo = pick_channels(audio.values[a0:a1], config.channels, _where(bag, streams["audio"]))
    samples = to_stereo_rate(stereo, audio.rate, _where(bag, streams["audio"]))
    report = StreamReport(
        counts={name: s.count for name, s in series.items()},
        filled_s=tuple(span for s in series.values() for span in s.spans(s.filled, t0)),
        reset_s=tuple(span for s in series.values() for span in s.spans(s.resets, t0)),
    )
    rec_spans = []
    for start, end, kind, sub_kind, wheel in spans:
        if end - t0 <= 0:
            raise SourceError(
                f"{_where(bag)}: the {kind} span {start:.3f}-{end:.3f} s (from the bag's start) ends before "
                f"every stream has started ({t0:.3f} s); allowed: spans inside the recording"
            )
        rec_spans.append(Span(max(0.0, start - t0), end - t0, kind, sub_kind, wheel))
    provenance |= {
        "bag_files": [str(f) for f in bag.files],
        "topics": {s: t for s, t in streams.items()},
        "start_s": round(t0, 9),
        "imu_rate": imu.rate,
        "vel_z_estimated_from_az": "velocity" not in series,
    }
    return Recording(
        samples,
        vel_z.astype(np.float32),
        imu6.astype(np.float32),
        tuple(rec_spans),
        provenance=provenance,
        wheel_pos=wheel_pos,
        streams=report,
    )


def plan(source: Path, config: ImportConfig, ros2: Ros2Config) -> tuple[list[Planned], dict[str, object]]:
    """The bags at `source` as planned recordings (every bag's topics checked first), and the facts for the
    manifest.

    Raises:
        SourceError: no bag, an unreadable or truncated one, a missing topic or an unsupported message type,
            a bad label CSV, split file or label message.
    """
    found = bags.find_bags(source)
    names = {b.name for b in found}
    if len(names) < len(found):
        raise SourceError(f"{source}: two bags share a name (a file NAME.mcap beside a folder NAME)")
    csv_spans = read_labels(Path(ros2.labels), names, config.anomaly_kind) if ros2.labels else {}
    fixed = read_split_file(Path(ros2.split_file), names) if ros2.split_file else {}
    plans: list[Planned] = []
    infos = {bag.name: bags.bag_info(bag) for bag in found}
    if ros2.labels_topic and not any(ros2.topics.labels in i.topics for i in infos.values()):
        raise SourceError(
            f"{source}: no bag has the labels topic {ros2.topics.labels!r}; the first bag's topics: "
            f"{bags.describe(infos[found[0].name].topics)}; allowed: a topic of "
            f"{READ_TYPES['labels'][0]} in the bags with an anomaly"
        )
    for bag in found:
        info = infos[bag.name]
        streams = _streams(bag, info, ros2)
        if "labels" in streams:
            spans = _topic_spans(bag, streams["labels"], info.start_ns)
        else:
            spans = [(s.start_s, s.end_s, s.kind, s.sub_kind, s.wheel) for s in csv_spans.get(bag.name, [])]
        plans.append(
            Planned(
                name=bag.name,
                group="",
                pool=fixed.get(bag.name, "auto"),
                anomalous=bool(spans),
                unit_id=0,
                load=functools.partial(_load, bag, info, streams, spans, config, ros2),
            )
        )
    facts: dict[str, object] = {
        "labels": ros2.labels,
        "labels_topic": ros2.topics.labels if ros2.labels_topic else None,
        "split_file": ros2.split_file,
        "topics": asdict(ros2.topics),
    }
    return plans, facts
