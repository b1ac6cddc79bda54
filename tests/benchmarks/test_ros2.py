"""ROS 2 bags: `import --layout ros2` on bags written with `mcap-ros2-support` (jitter, a dropped audio chunk,
an out-of-order IMU message), a detector trained on the nominal ones; `export-bag` and back to the same
windows; the schemas and counts of a written bag; bad bags named in one line, nothing half written."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.well_known import MessageEncoding, Profile, SchemaEncoding
from mcap_ros2.writer import Writer

from benchmarks.cli import main
from benchmarks.commands.import_ import _TOPIC_FLAGS
from benchmarks.dataset import load_window_rows, open_dataset
from benchmarks.episode import read_episode, read_imu_signals
from benchmarks.errors import UserError
from benchmarks.importers import (
    ImportConfig,
    SourceError,
    SplitConfig,
    import_dataset,
    read_topic_mapping,
    ros2_config,
)
from benchmarks.importers.ros2 import _decode_pcm
from benchmarks.importers.timed import StreamCount, assemble
from benchmarks.pipeline import score_and_measure, train_method
from benchmarks.ros2 import msgs
from benchmarks.ros2.topics import READ_TYPES, Topics
from benchmarks.ros2.writer import AUDIO_CHUNK, anomaly_runs
from msvdd.stream import GapPolicy

SECONDS = 8.0
AUDIO_RATE, CHUNK = 16000, 1600
"""Bag audio: 16 kHz mono S16LE in 0.1 s chunks."""
WHEELS = ("left_wheel_joint", "right_wheel_joint")
FAULT = (3.2, 8.0)
"""The faulty bags' labelled anomaly, s from the bag's first message."""
T0_NS = 1_700_000_000 * msgs.NS
"""The bags' clock starts at a real ROS time."""


def _ns(t: float) -> int:
    return T0_NS + msgs.seconds_ns(t)


def _header(t: float, frame: str = "") -> dict[str, Any]:
    return {"stamp": msgs.time_msg(_ns(t)), "frame_id": frame}


def _robot_bag(
    path: Path,
    rng: np.random.Generator,
    faulty: bool,
    *,
    stamped_audio: bool = True,
    extra: str = "",
    chunk_size: int = 1 << 20,
) -> None:
    """A robot's bag: IMU at 200 Hz with +-1 ms stamp jitter and message 700 received after message 701;
    16 kHz audio chunks with chunk 30 missing; two wheels' joint states at 200 Hz. A faulty bag adds a
    900 Hz tone to the audio and a 37 Hz vibration to the IMU over `FAULT`."""
    writer = Writer(open(path, "wb"), chunk_size=chunk_size)  # noqa: SIM115 - closed by finish below
    types = (msgs.IMU, msgs.JOINT_STATE, msgs.AUDIO_INFO, msgs.AUDIO_DATA_STAMPED, msgs.AUDIO_DATA)
    schemas = {t: writer.register_msgdef(t, msgs.schema_text(t)) for t in types}
    items: list[tuple[int, str, str, dict[str, Any]]] = []
    n = round(SECONDS * 200)
    t = np.arange(n) / 200
    stamps = t + rng.uniform(-0.001, 0.001, n)
    on = faulty & (t >= FAULT[0]) & (t < FAULT[1])
    acc_z = 9.81 + 0.05 * rng.standard_normal(n) + np.where(on, 1.5 * np.sin(2 * np.pi * 37 * t), 0.0)
    speed = rng.uniform(2.0, 3.0)
    for i in range(n):
        received = stamps[i + 1] + 1e-4 if i == 700 else stamps[i]  # 700 comes after 701: out of order
        imu = {"header": _header(stamps[i], "imu_link"), "orientation_covariance": [-1.0] + [0.0] * 8,
               "linear_acceleration": {"x": 0.1 * rng.standard_normal(), "y": 0.0, "z": acc_z[i]},
               "angular_velocity": {"x": 0.0, "y": 0.0, "z": 0.02 * rng.standard_normal()}}  # fmt: skip
        items.append((_ns(received), "/imu/data", msgs.IMU, imu))
        joints = {"header": _header(t[i] + rng.uniform(-0.001, 0.001)), "name": ["caster", *WHEELS],
                  "position": [0.0, speed * t[i], -speed * t[i]], "velocity": [0, speed, -speed]}  # fmt: skip
        items.append((_ns(t[i]), "/joint_states", msgs.JOINT_STATE, joints))
    ta = np.arange(round(SECONDS * AUDIO_RATE)) / AUDIO_RATE
    hum = 0.2 * np.sin(2 * np.pi * rng.uniform(110, 130) * ta) + 0.02 * rng.standard_normal(ta.size)
    fault = faulty & (ta >= FAULT[0]) & (ta < FAULT[1])
    audio = np.round((hum + np.where(fault, 0.2 * np.sin(2 * np.pi * 900 * ta), 0.0)) * 2**15).astype("<i2")
    info = {"channels": 1, "sample_rate": AUDIO_RATE, "sample_format": "S16LE", "coding_format": "wave"}
    items.append((_ns(0.0), "/audio/audio_info", msgs.AUDIO_INFO, info))
    for k, j in enumerate(range(0, audio.size, CHUNK)):
        if k == 30:
            continue  # a chunk the recorder never got
        data = audio[j : j + CHUNK].tobytes()
        if stamped_audio:
            message = {"header": _header(j / AUDIO_RATE, "mic"), "audio": {"data": data}}
            items.append((_ns(j / AUDIO_RATE), "/audio/audio_stamped", msgs.AUDIO_DATA_STAMPED, message))
        else:
            topic = Topics().audio  # the default topic, whichever of the two types it carries
            items.append((_ns(j / AUDIO_RATE + 0.002), topic, msgs.AUDIO_DATA, {"data": data}))
    if extra:
        schema = writer.register_msgdef(extra, "string data\n")
        writer.write_message("/status", schema, {"data": "ok"}, log_time=_ns(0.0))
    for log_ns, topic, type_name, message in sorted(items, key=lambda item: item[0]):
        writer.write_message(topic, schemas[type_name], message, log_time=log_ns)
    writer.finish()


@pytest.fixture(scope="module")
def robot_bags(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Six nominal bags (one with unstamped audio) and three faulty ones, with a label CSV."""
    root = tmp_path_factory.mktemp("bags") / "robot"
    (root / "faulty").mkdir(parents=True)
    rng = np.random.default_rng(7)
    for i in range(6):
        _robot_bag(root / f"nominal-{i}.mcap", rng, False, stamped_audio=i != 2)
    for i in range(3):
        _robot_bag(root / "faulty" / f"run-{i}.mcap", rng, True)
    rows = "".join(f"faulty/run-{i},{FAULT[0]},{FAULT[1]},mechanical,bearing\n" for i in range(3))
    (root.parent / "labels.csv").write_text("recording,start_s,end_s,kind,sub_kind\n" + rows)
    return root


@pytest.fixture(scope="module")
def robot(robot_bags: Path) -> Path:
    config = ImportConfig(scale="smoke", split=SplitConfig(test_fraction=0.34, val_fraction=0.25))
    layout = ros2_config({}, {}, labels=str(robot_bags.parent / "labels.csv"))
    return import_dataset("ros2", robot_bags, robot_bags.parent / "ds", config, layout, progress=False)


def test_bags_import_with_their_irregular_stamps_counted(robot: Path) -> None:
    data = open_dataset(robot)
    manifest = data.manifest
    assert manifest.modalities == ("audio", "imu", "odometry")
    assert manifest.imported is not None and manifest.imported.layout == "ros2"
    splits = {e.recording: (e.spec.split, e.spec.category) for e in manifest.episodes}
    assert splits["faulty/run-0"] == ("test", "fault") and splits["nominal-0"] == ("train", "nominal")
    assert sorted(s for s, _ in splits.values()) == ["test"] * 5 + ["train"] * 3 + ["val"]
    streams = manifest.imported.facts["streams"]
    for name, counts in streams.items():
        # the out-of-order IMU message: its successor came first (one sample held), then it was dropped late
        assert counts["imu"] | {"messages": 0} == {"messages": 0, "gaps_filled": 1, "samples_filled": 1,
            "resets": 0, "messages_dropped": 1, "samples_dropped": 1}, name  # fmt: skip
        audio = counts["audio"]
        # the lost chunk: filled with zeros, except in the unstamped audio, where nothing shows it
        lost = (0, 0) if name == "nominal-2" else (1, CHUNK)
        assert (audio["gaps_filled"], audio["samples_filled"], audio["messages_dropped"]) == (*lost, 0), name
        assert counts["joint_states"]["messages_dropped"] == 0 and counts["joint_states"]["resets"] == 0
        assert counts["windows_skipped"] == 0 and counts["windows_with_fill"] >= 1
    assert manifest.to_dict() == json.loads((robot / "manifest.json").read_text())
    episode = read_episode(
        robot / next(e.episode_id for e in manifest.episodes if e.recording == "nominal-0")
    )
    assert episode.modalities == ("audio", "imu", "odometry") and episode.wheel_pos.shape[1] == 2
    # the wheels' positions at 200 Hz from the bag's start: +-speed * t, the caster left out
    speed = episode.wheel_pos[200, 0] - episode.wheel_pos[0, 0]
    assert 2.0 < speed < 3.0
    np.testing.assert_allclose(episode.wheel_pos[:, 1], -episode.wheel_pos[:, 0])
    np.testing.assert_allclose(np.diff(episode.wheel_pos[:, 0]), speed / 200, rtol=1e-9)
    n = episode.imu6.shape[0]  # from the first IMU sample after every stream started to the first end
    assert SECONDS * 200 - 4 <= n < SECONDS * 200 and abs(episode.audio.shape[0] / 44100 - n / 200) < 1 / 200
    meta = json.loads((episode.path / "meta.json").read_text())["recording"]
    assert meta["vel_z_estimated_from_az"] is True and meta["wheel_joints"] == list(WHEELS)
    start = meta["start_s"]  # the episode's 0 on the bag's clock (its first message at 0)
    assert 0 <= start < 0.01
    hole = slice(round((3.0 - start) * 44100) + 50, round((3.1 - start) * 44100) - 50)
    assert np.all(episode.audio[hole] == 0) and np.all(np.any(episode.audio[hole.stop + 100 :] != 0, axis=0))
    unstamped = next(e.episode_id for e in manifest.episodes if e.recording == "nominal-2")
    assert json.loads((robot / unstamped / "meta.json").read_text())["recording"]["audio_stamped"] is False


def test_a_detector_trained_on_the_nominal_bags_scores_the_faulty_ones_above(
    robot: Path, tmp_path: Path
) -> None:
    data = open_dataset(robot, verify=False)
    model = train_method(data, "gaussian-early", 0, "smoke", tmp_path / "model")
    scores, per_method, rows = score_and_measure(data, [model], progress=False)
    s = scores[0].scores
    kinds = np.array([r.kind for r in rows])
    assert {"normal", "mechanical"} == set(kinds)
    assert s[kinds == "mechanical"].min() > s[kinds == "normal"].max()
    assert per_method["gaussian-early"][0].auc == 1.0


def test_the_labels_csv_times_count_from_the_bags_first_message(robot: Path) -> None:
    data = open_dataset(robot, verify=False)
    fault = next(e for e in data.manifest.episodes if e.recording == "faulty/run-1")
    events = json.loads((robot / fault.spec.episode_id / "events.json").read_text())["anomalies"]
    # the episode starts at the first IMU sample at or after every stream's start (the bag's start, within
    # the jitter): the span's times hardly move
    assert len(events) == 1 and abs(events[0]["onset"] - FAULT[0]) < 0.006
    labels = {r.start_s: r.kind for r in data.windows if r.episode == fault.spec.episode_id}
    assert labels == {0.0: "normal", 4.0: "mechanical"}  # 2 s, half in the fault: ambiguous, left out


def test_an_exported_simulated_dataset_imports_back_to_the_same_windows(
    tiny_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bags = tmp_path / "bags"
    assert main(["export-bag", str(tiny_dataset), "--all", "--out", str(bags), "--no-progress"]) == 0
    original = open_dataset(tiny_dataset)
    assert sorted(p.stem for p in bags.iterdir()) == sorted(original.episode_ids)
    out = tmp_path / "ds"
    assert main(["import", str(bags), "--layout", "ros2", "--labels-topic", Topics().labels, "--out",
                 str(out), "--no-progress"]) == 0  # fmt: skip
    assert "modalities: audio, imu, odometry" in capsys.readouterr().out
    back = open_dataset(out)
    episode_of = {e.recording: e.episode_id for e in back.manifest.episodes}
    rows = original.windows
    a, _ = load_window_rows(original.path, rows)
    b, _ = load_window_rows(back.path, [replace(r, episode=episode_of[r.episode]) for r in rows])
    for field in ("audio", "imu", "imu6", "odometry"):  # 16-bit audio and float32 IMU travel exactly
        np.testing.assert_array_equal(getattr(b, field), getattr(a, field), err_msg=field)
    for episode_id in original.episode_ids:  # the label timeline, its sub-kinds and faulty wheels too
        names = ("label", "sub_kind", "label_wheel", "wheel_pos")
        first, second = (read_imu_signals(d / e, names) for d, e in
                         ((original.path, episode_id), (back.path, episode_of[episode_id])))  # fmt: skip
        assert all(np.array_equal(first[k], second[k]) for k in names), episode_id
    labels = {(r.episode, r.start_s): (r.kind, r.sub_kind, r.wheel) for r in back.windows}
    shared = [(r, labels.get((episode_of[r.episode], r.start_s))) for r in rows]
    assert all(got == (r.kind, r.sub_kind, r.wheel) for r, got in shared if got is not None)
    assert sum(got is not None for _, got in shared) > len(rows) // 3
    assert back.manifest.imported is not None
    for counts in back.manifest.imported.facts["streams"].values():  # the bags' stamps are regular
        assert all(counts[s]["gaps_filled"] == counts[s]["messages_dropped"] == counts[s]["resets"] == 0
                   for s in ("imu", "velocity", "audio", "joint_states"))  # fmt: skip


def test_an_exported_bag_holds_its_schemas_and_message_counts(tiny_dataset: Path, tmp_path: Path) -> None:
    data = open_dataset(tiny_dataset, verify=False)
    episode_id = next(e for e, c in data.categories().items() if c == "collision")
    bag = tmp_path / "one.mcap"
    assert main(["export-bag", str(tiny_dataset), "--episode", episode_id, "--out", str(bag)]) == 0
    episode = read_episode(tiny_dataset / episode_id)
    with open(bag, "rb") as handle:
        reader = make_reader(handle)
        assert reader.get_header().profile == Profile.ROS2
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        schemas = {s.name: s for s in summary.schemas.values()}
        for schema in schemas.values():
            assert schema.encoding == SchemaEncoding.ROS2 and schema.data.decode() == msgs.schema_text(
                schema.name
            )
        counts = {c.topic: summary.statistics.channel_message_counts[i] for i, c in summary.channels.items()}
        types = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
        assert all(c.message_encoding == MessageEncoding.CDR for c in summary.channels.values())
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
    topics, n = Topics(), episode.imu6.shape[0]
    assert types == {
        topics.imu: msgs.IMU,
        topics.velocity: msgs.TWIST_STAMPED,
        topics.audio: msgs.AUDIO_DATA_STAMPED,
        topics.audio_info: msgs.AUDIO_INFO,
        topics.joint_states: msgs.JOINT_STATE,
        topics.tf: msgs.TF_MESSAGE,
        topics.tf_static: msgs.TF_MESSAGE,
        topics.contacts: msgs.CONTACT,
        topics.labels: msgs.ANOMALY_INTERVAL,
    }
    assert counts[topics.imu] == counts[topics.velocity] == counts[topics.joint_states] == n
    assert (
        counts[topics.audio] == -(-episode.audio.shape[0] // AUDIO_CHUNK) and counts[topics.audio_info] == 1
    )
    assert counts[topics.tf_static] == 1 and counts[topics.tf] >= 50 * (n // 200)
    assert counts[topics.contacts] == len(episode.events().contacts) > 0
    assert counts[topics.labels] == len(anomaly_runs(episode)) > 0
    assert metadata["msvdd-bench"]["episode"] == episode_id
    assert summary.statistics.message_start_time == 0
    again = tmp_path / "again.mcap"
    assert main(["export-bag", str(tiny_dataset), "--episode", episode_id, "--out", str(again)]) == 0
    assert again.read_bytes() == bag.read_bytes()


def test_schema_text_concatenates_every_dependency_once() -> None:
    text = msgs.schema_text(msgs.TF_MESSAGE)
    sections = text.split(msgs.SEPARATOR + "\n")
    assert sections[0] == "geometry_msgs/TransformStamped[] transforms\n"
    names = [s.splitlines()[0].removeprefix("MSG: ") for s in sections[1:]]
    assert names == [
        "geometry_msgs/TransformStamped",
        "std_msgs/Header",
        "builtin_interfaces/Time",
        "geometry_msgs/Transform",
        "geometry_msgs/Vector3",
        "geometry_msgs/Quaternion",
    ]
    assert all(msgs.defined(t) for types in READ_TYPES.values() for t in types)


# ------------------------------------------------------------------------------------- the policy


def test_streams_are_laid_out_by_the_streaming_scorers_gap_policy() -> None:
    """Analytic: 10 Hz stream, one-sample messages; the policy's jitter 0.02 s, longest fill 0.25 s."""
    policy = GapPolicy(jitter_s=0.02, max_fill_s=0.25)
    times = [0.0, 0.11, 0.19, 0.5, 0.5, 0.4, 1.2, None]  # jitter, jitter, fill 2, duplicate, late, reset 6
    chunks = [(t, np.array([[float(i)]])) for i, t in enumerate(times)]
    series = assemble(chunks, 10.0, policy, hold=True, where="test")
    held = [0, 1, 2, 2, 2, 3, 3, 3, 3, 3, 3, 3, 6, 7]
    assert series.values[:, 0].tolist() == held
    assert series.filled == ((3, 5),) and series.resets == ((6, 12),)
    assert series.count == StreamCount(messages=8, gaps_filled=1, samples_filled=2, resets=1,
                                       messages_dropped=2, samples_dropped=2)  # fmt: skip
    zeros = assemble(chunks[:4], 10.0, policy, hold=False, where="test")
    assert zeros.values[:, 0].tolist() == [0, 1, 2, 0, 0, 3]
    with pytest.raises(SourceError, match=r"a gap of 100\.0 s"):
        assemble([(0.0, np.zeros((1, 1))), (100.1, np.zeros((1, 1)))], 10.0, policy, True, "test")


def test_pcm_sample_formats_decode_to_full_scale() -> None:
    assert _decode_pcm(np.array([-32768, 16384], "<i2").tobytes(), "S16LE", 1, "t").tolist() == [
        [-1.0],
        [0.5],
    ]
    packed = bytes([0x00, 0x00, 0x80, 0xFF, 0xFF, 0x3F])  # -2^23 and 2^22 - 1, 3 bytes each
    np.testing.assert_array_equal(_decode_pcm(packed, "S24LE", 2, "t"), [[-1.0, (2**22 - 1) / 2**23]])
    assert _decode_pcm(bytes([0, 128, 192]), "U8", 1, "t")[:, 0].tolist() == [-1.0, 0.0, 0.5]
    with pytest.raises(SourceError, match="not whole S16LE frames of 2 channel"):
        _decode_pcm(b"\x00\x01\x02", "S16LE", 2, "t")


def test_flags_the_mapping_file_and_the_defaults(tmp_path: Path) -> None:
    assert tuple(READ_TYPES) == _TOPIC_FLAGS
    mapping = tmp_path / "topics.toml"
    mapping.write_text('imu = "/robot/imu"\naudio = "/mic"\nwheel_joints = ["wl", "wr"]\n')
    config = ros2_config(read_topic_mapping(mapping), {"audio": "/mic2", "imu": None})
    assert (config.topics.imu, config.topics.audio, config.topics.audio_info) == (
        "/robot/imu",
        "/mic2",
        Topics().audio_info,
    )
    assert (
        config.named == ("imu", "audio") and config.wheel_joints == ("wl", "wr") and not config.labels_topic
    )
    assert config.policy == GapPolicy()
    mapping.write_text('imu = "/robot/imu"\nmicrophone = "/mic"\n')
    with pytest.raises(UserError, match=r"key 'microphone' is unknown; allowed: imu, velocity, audio"):
        read_topic_mapping(mapping)


# ---------------------------------------------------------------------------------------- bad bags


def _other_audio_bag(path: Path) -> None:
    """A bag whose audio is another package's `audio_common_msgs/AudioDataStamped` (typed sample arrays)."""
    writer = Writer(open(path, "wb"))  # noqa: SIM115 - closed by finish below
    imu = writer.register_msgdef(msgs.IMU, msgs.schema_text(msgs.IMU))
    info = writer.register_msgdef(msgs.AUDIO_INFO, msgs.schema_text(msgs.AUDIO_INFO))
    header = msgs.schema_text(msgs.AUDIO_DATA_STAMPED).split(msgs.SEPARATOR)[1]  # std_msgs/Header's section
    text = "std_msgs/Header header\naudio_common_msgs/AudioData audio\n" + msgs.SEPARATOR + header
    text += (
        f"{msgs.SEPARATOR}\nMSG: audio_common_msgs/AudioData\nfloat32[] float32_data\nint16[] int16_data\n"
    )
    audio = writer.register_msgdef(msgs.AUDIO_DATA_STAMPED, text)
    for i in range(400):
        writer.write_message("/imu/data", imu, {"header": _header(i / 200)}, log_time=_ns(i / 200))
    fmt = {"channels": 1, "sample_rate": 16000, "sample_format": "S16LE"}
    writer.write_message("/audio/audio_info", info, fmt, log_time=_ns(0))
    for j in range(20):
        message = {"header": _header(j / 10), "audio": {"int16_data": [0] * 1600}}
        writer.write_message(Topics().audio, audio, message, log_time=_ns(j / 10))
    writer.finish()


def _import_fails(source: Path, out: Path, capsys: pytest.CaptureFixture[str], *extra: str) -> str:
    code = main(["import", str(source), "--layout", "ros2", "--out", str(out), "--no-progress", *extra])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err, err
    assert not out.exists() and not list(out.parent.glob(f".{out.name}*"))  # nothing half written
    return err


def test_bad_bags_exit_2_with_one_line_and_leave_nothing(
    robot_bags: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    source, out = tmp_path / "src", tmp_path / "out"
    source.mkdir()
    bag = source / "a.mcap"
    _robot_bag(bag, np.random.default_rng(1), False, chunk_size=1 << 15)  # chunks of 32 KiB
    data = bag.read_bytes()
    err = _import_fails(source, out, capsys, "--imu-topic", "/imu")
    assert "a.mcap: no topic '/imu' for the imu stream (sensor_msgs/msg/Imu); the bag's topics: " in err
    assert "/audio/audio_info (audio_common_msgs/msg/AudioInfo, 1), /audio/audio_stamped" in err
    assert "/imu/data (sensor_msgs/msg/Imu, 1600)" in err and "--imu-topic" in err
    err = _import_fails(source, out, capsys, "--labels-topic", "/labels")
    assert "no bag has the labels topic '/labels'" in err
    _robot_bag(bag, np.random.default_rng(2), False, extra="std_msgs/msg/String")
    err = _import_fails(source, out, capsys, "--imu-topic", "/status")
    assert err.endswith("a.mcap, topic /status: message type std_msgs/msg/String for the imu stream; "
                        "supported: sensor_msgs/msg/Imu")  # fmt: skip
    _other_audio_bag(bag)
    err = _import_fails(source, out, capsys)
    assert "its AudioData has no field `data` (its fields: float32_data, int16_data); supported: " in err
    bag.write_bytes(data[: len(data) // 2])
    err = _import_fails(source, out, capsys)
    assert (
        f"a.mcap: truncated: the file ends after {len(data) // 2} bytes, inside the record that starts" in err
    )
    assert "its last complete message was logged" in err and "mcap recover" in err
    bag.write_bytes(b"#ROSBAG V2.0\n" + bytes(100))
    assert "a.mcap: not an MCAP file" in _import_fails(source, out, capsys)
    bag.unlink()
    with pytest.raises(SourceError, match="no bag"):
        import_dataset("ros2", source, out, ImportConfig(), progress=False)


def test_export_refuses_what_it_cannot_write(
    tiny_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for argv in (["--episode", "nope", "--out", str(tmp_path / "x.mcap")],
                 ["--episode", "test-fault-000", "--out", str(tmp_path / "x.bag")],
                 ["--all", "--out", str(tmp_path)]):  # fmt: skip
        assert main(["export-bag", str(tiny_dataset), *argv]) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and err.startswith("msvdd-bench export-bag: error:"), err
    assert not list(tmp_path.iterdir())
