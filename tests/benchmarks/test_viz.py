"""Rerun recordings of an episode: written headless, read back, checked entity by entity; bad input."""

from __future__ import annotations

import dataclasses
import json
import math
import re
import sys
import urllib.request
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rerun.blueprint as rrb
from rerun.chunk import RrdReader

import synth_audio
from benchmarks.cli import main
from benchmarks.dataset import window_starts
from benchmarks.episode import EpisodeMeta, read_episode, write_episode
from benchmarks.errors import UserError
from benchmarks.methods import make, save_detector
from benchmarks.viz import VizConfig, log_episode, score_episode
from benchmarks.viz.focus import struck_obstacles
from benchmarks.viz.scene import wheel_fault_changes
from benchmarks.viz.series import envelope_block
from benchmarks.viz.serve import free_port, has_display, viewer_url
from benchmarks.viz.signals import display_indices
from msvdd import preprocess
from sim.trace import ContactEvents, FaultRecord, ObstacleRecord, RobotInfo, Trace, TransientEvents
from sim.vocab import COLLISION, MECHANICAL, SUB_KINDS

DURATION = 3.0
PHYS_DT = 0.005
IMU_RATE = 200.0
AUDIO_RATE = 44100
EPISODE = "test-fault-000"


def tiny_trace(faults: tuple[tuple[int, float, float], ...] = ((1, 1.5, 1.0),)) -> Trace:
    """A 3 s skid-steer trace driving a circle: one wall contact at 1.2 s, faults (wheel, onset, length)."""
    rng = np.random.default_rng(0)
    n, m = round(DURATION / PHYS_DT), round(DURATION * IMU_RATE)
    t = np.arange(n) * PHYS_DT
    heading = 0.4 * t
    pos = np.stack([np.cos(heading), np.sin(heading), np.full(n, 0.08)], axis=1)
    yaw = heading + np.pi / 2
    quat = np.stack([np.cos(yaw / 2), np.zeros(n), np.zeros(n), np.sin(yaw / 2)], axis=1)
    wheels = ("front_left", "front_right", "back_left", "back_right")
    wheel_pos = np.array([[0.15, 0.2, 0.0], [0.15, -0.2, 0.0], [-0.15, 0.2, 0.0], [-0.15, -0.2, 0.0]])
    robot = RobotInfo(
        "skid4", 3, 20.0, wheels, np.full(4, 0.08), wheel_pos, np.array([[0.2, 0.1, 0.1], [0.2, -0.1, 0.1]]),
        np.zeros(3), 20.0, 12, 4, 20000.0, 30, 0.4, 0.3,
    )  # fmt: skip
    speed = np.full((n, 4), 5.0)
    contacts = ContactEvents(
        np.array([1.2]), np.array([[1.0, 0.5, 0.1]]), np.array([[1.0, 0, 0]]), np.array([2.5]),
        np.array([0.4]), np.array([0.05]), ("wall",), ("plaster",),
    )  # fmt: skip
    transients = TransientEvents(
        np.array([0.7]), np.array([[0.5, 0.8, 0.0]]), np.array([2]), np.array([0.3]), ("seam",),
        np.array([0.004]),
    )  # fmt: skip
    fault_records = tuple(FaultRecord("bearing", w, 0.6, on, d, 3.57, 2100.0, 0.04) for w, on, d in faults)
    imu_time = np.arange(m) / IMU_RATE
    label = np.zeros(m, np.int8)
    sub_kind = np.zeros(m, np.int16)
    label_wheel = -np.ones(m, np.int8)
    coll = (imu_time >= 1.2) & (imu_time < 1.3)
    label[coll], sub_kind[coll] = COLLISION, SUB_KINDS.index("wall")
    w, on, d = faults[0]
    mech = (imu_time >= on) & (imu_time < on + d) & ~coll
    label[mech], sub_kind[mech], label_wheel[mech] = MECHANICAL, SUB_KINDS.index("bearing"), w
    obstacle = ObstacleRecord("wall", "plaster", np.array([1.2, 0.5, 0.5]), np.array([0.05, 1.0, 0.5]), 0.1)
    return Trace(
        "tiny", 7, "indoor", "tile", DURATION, PHYS_DT, IMU_RATE, robot, np.array([3.0, 3.0]), t,
        np.cumsum(speed, axis=0) * PHYS_DT, speed, rng.normal(size=(n, 4)), pos, quat,
        rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), rng.normal(size=(n, 2, 3)), imu_time,
        0.01 * rng.normal(size=m), rng.normal(size=(m, 3)), rng.normal(size=(m, 3)), contacts, transients,
        fault_records, (obstacle,), np.tile(obstacle.position, (m, 1, 1)), label, sub_kind, label_wheel,
    )  # fmt: skip


def tiny_audio() -> synth_audio.Audio:
    """3 s of a 1 kHz tone in noise, louder after the contact."""
    rng = np.random.default_rng(1)
    t = np.arange(round(DURATION * AUDIO_RATE)) / AUDIO_RATE
    tone = 0.1 * np.sin(2 * np.pi * 1000.0 * t) * (1.0 + 4.0 * (t > 1.2))
    samples = np.stack([tone, 0.5 * tone], axis=1) + 0.01 * rng.normal(size=(t.size, 2))
    return synth_audio.Audio(samples.astype(np.float32), AUDIO_RATE)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A dataset folder with one hand-made episode (no manifest: the viewer reads episode folders)."""
    root = tmp_path_factory.mktemp("vizdata") / "data"
    meta = EpisodeMeta(EPISODE, "fault", "test", 3, 7, 10.0, DURATION)
    write_episode(root / EPISODE, meta, {"name": "tiny"}, tiny_trace(), tiny_audio())
    return root


@pytest.fixture(scope="module")
def model(dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An `audio-rms` detector fitted on the episode's first windows."""
    episode = read_episode(dataset / EPISODE)
    windows = preprocess.frame_windows(
        preprocess.decimate_audio(episode.audio),
        episode.imu_vel_z,
        np.array([0.0, 0.25, 0.5]),
        imu6=episode.imu6,
    )
    detector = make("audio-rms", seed=0, scale="smoke").fit(windows)
    return save_detector(detector, "audio-rms", tmp_path_factory.mktemp("vizmodel") / "rms")


def _rows(path: Path) -> dict[str, int]:
    """Temporal rows per `entity:component` of a recording, read back from the file."""
    summary = RrdReader(path).store().summary()
    rows: dict[str, int] = {}
    static: set[str] = set()
    for line in summary.splitlines():
        found = re.match(r"(\S+)\s+rows=(\d+)\s+static=(\w+)\s+timelines=\[.*?\]\s+cols=\[(.*)\]", line)
        assert found, line
        entity, count, is_static, cols = found.groups()
        for col in re.findall(r"'([^']+)'", cols):
            if col == "time":
                continue
            key = f"{entity}:{col}"
            if is_static == "True":
                static.add(key)
            else:
                rows[key] = rows.get(key, 0) + int(count)
    rows.update({f"static {k}": 1 for k in static})
    return rows


def _column(path: Path, entity: str, component: str) -> tuple[np.ndarray, np.ndarray]:
    """(times in s, values) of one temporal scalar component, read back from the file."""
    times, values = [], []
    for chunk in RrdReader(path).store().stream().to_chunks():
        if chunk.entity_path != entity or chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        names = batch.schema.names
        col = next(n for n in names if n.endswith(component))
        times.append(batch.column("time").cast("int64").to_numpy() / 1e9)
        values.append(np.array([np.asarray(v, dtype=np.float64) for v in batch.column(col).to_pylist()]))
    order = np.argsort(np.concatenate(times))
    return np.concatenate(times)[order], np.concatenate(values)[order]


def _blueprint(path: Path) -> dict[str, dict[str, Any]]:
    """The default blueprint of a recording: entity path -> {`Archetype:field`: value} (one instance: the
    value itself, several: their list)."""
    reader = RrdReader(path)
    out: dict[str, dict[str, Any]] = {}
    for chunk in reader.store(store=reader.blueprints()[0]).stream().to_chunks():
        batch = chunk.to_record_batch()
        fields = out.setdefault(chunk.entity_path, {})
        for name in batch.schema.names:
            if ":" not in name:
                continue
            value = batch.column(name).to_pylist()[-1]
            fields[name] = value[0] if isinstance(value, list) and len(value) == 1 else value
    return out


def _views(blueprint: dict[str, dict[str, Any]], kind: str) -> dict[str, dict[str, Any]]:
    """View entity path -> its fields, for the views of one class (`TimeSeries`, `3D`, ...)."""
    return {p: f for p, f in blueprint.items() if f.get("ViewBlueprint:class_identifier") == kind}


@pytest.fixture(scope="module")
def recording(dataset: Path, model: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("viz") / "sub" / "episode.rrd"
    path = log_episode(dataset, EPISODE, model_dir=model, save=out)
    assert path == out
    return out


def test_recording_has_every_entity_with_the_logged_row_counts(dataset: Path, recording: Path) -> None:
    rows = _rows(recording)
    episode = read_episode(dataset / EPISODE)
    trace = episode.trace()
    cfg = VizConfig()
    m = episode.imu_time.size
    for entity in ("signals/imu/vel_z", "signals/imu/acc", "signals/imu/gyro", "truth/label"):
        assert rows[f"/{entity}:Scalars:scalars"] == m, entity
    block = envelope_block(AUDIO_RATE, cfg)
    assert block == 44
    for side in ("left", "right"):
        assert rows[f"/signals/audio/{side}:Scalars:scalars"] == math.ceil(episode.audio.shape[0] / block)
    n_windows = window_starts(DURATION, 0.5, first_s=0.0).size
    assert n_windows == 3
    assert rows["/detector/score:Scalars:scalars"] == n_windows
    assert rows["/detector/threshold:Scalars:scalars"] == n_windows + 1  # from 0 s: a line over the episode
    assert rows["/detector/truth:Scalars:scalars"] >= 4  # the ground-truth step inside the score plot
    n_pose = display_indices(trace.time, cfg.pose_rate_hz).size
    assert rows["/world/robot:Transform3D:translation"] == n_pose
    assert rows["/signals/wheels/speed:Scalars:scalars"] == n_pose
    for name in trace.robot.wheel_names:
        assert rows[f"/world/robot/wheels/{name}/tyre:Transform3D:quaternion"] == n_pose
        assert f"static /world/robot/wheels/{name}/tyre:Cylinders3D:radii" in rows
    assert rows["/world/robot/wheels/front_right/tyre:Cylinders3D:colors"] == 3  # healthy, faulty, healthy
    assert rows["/world/contacts:Points3D:positions"] == 1
    assert rows["/world/transients:Points3D:positions"] == 1
    n_obstacle_rows = display_indices(trace.imu_time, cfg.pose_rate_hz).size
    assert rows["/world/obstacles/struck:Boxes3D:centers"] == n_obstacle_rows  # the wall it hit
    assert rows["/states/truth:StateChange:state"] == 5  # normal, collision, normal, mechanical, normal
    assert rows["/spectrogram/window/image:Image:buffer"] == n_windows
    assert "static /spectrogram/episode/image:Image:buffer" in rows
    assert rows["/spectrogram/episode/image/cursor:LineStrips2D:strips"] == 60  # 20 Hz over 3 s
    assert rows["/audio:AssetAudio:blob"] == 1
    # collision + transient + fault onset + fault end + detection edges
    assert rows["/events:TextLog:text"] >= 4
    for key in ("static /world/arena/floor:Boxes3D:half_sizes", "static /world/robot/body:Boxes3D:half_sizes",
                "static /world/trajectory:LineStrips3D:strips"):  # fmt: skip
        assert key in rows
    views = [v["ViewBlueprint:class_identifier"] for v in _blueprint(recording).values()
             if "ViewBlueprint:class_identifier" in v]  # fmt: skip
    # 3D; score, IMU z, microphones, accelerometer, gyroscope, wheels; lanes; 2 spectrograms; events; audio
    expected = ["3D", *["TimeSeries"] * 6, "StateTimeline", "2D", "2D", "TextLog", "Audio"]
    assert sorted(views) == sorted(expected)


def test_scores_threshold_and_detections_match_the_detector(
    dataset: Path, model: Path, recording: Path
) -> None:
    from benchmarks.methods import load_detector

    name, detector = load_detector(model)
    scores = score_episode(read_episode(dataset / EPISODE), detector, name, 0.5)
    t, score = _column(recording, "/detector/score", "scalars")
    np.testing.assert_allclose(t, [2.0, 2.5, 3.0])  # logged at window END times
    np.testing.assert_allclose(score.ravel(), scores.score)
    _, threshold = _column(recording, "/detector/threshold", "scalars")
    np.testing.assert_allclose(threshold.ravel(), detector.threshold_)
    # the tone gets 5x louder after 1.2 s: later windows score higher than the training windows
    assert scores.detected.any()
    rows = _rows(recording)
    assert rows["/detector/detection:Scalars:scalars"] == int(scores.detected.sum())
    t_label, label = _column(recording, "/truth/label", "scalars")
    np.testing.assert_allclose(t_label, np.arange(600) / IMU_RATE)
    assert set(np.unique(label)) == {0.0, 1.0, 2.0}


def test_without_model_no_detector_entities(dataset: Path, tmp_path: Path) -> None:
    out = log_episode(dataset, EPISODE, save=tmp_path / "plain.rrd", audio_playback=False)
    assert out is not None
    rows = _rows(out)
    assert not any(k.startswith("/detector") for k in rows)
    assert "/audio:AssetAudio:blob" not in rows
    assert rows["/spectrogram/window/image:Image:buffer"] == 3


def test_wheel_fault_changes_merge_overlaps() -> None:
    trace = tiny_trace(faults=((1, 1.0, 1.0), (1, 1.5, 1.0), (0, 0.5, 0.2)))
    t, faulty = wheel_fault_changes(trace, 1)
    np.testing.assert_allclose(t, [0.0, 1.0, 2.5])
    np.testing.assert_array_equal(faulty, [False, True, False])
    t0, f0 = wheel_fault_changes(trace, 0)
    np.testing.assert_allclose(t0, [0.0, 0.5, 0.7])
    np.testing.assert_array_equal(f0, [False, True, False])
    assert wheel_fault_changes(trace, 3)[1].tolist() == [False]


def test_bad_input_names_the_path(dataset: Path, model: Path, tmp_path: Path) -> None:
    out = tmp_path / "x.rrd"
    with pytest.raises(FileNotFoundError, match="nowhere"):
        log_episode(tmp_path / "nowhere", EPISODE, save=out)
    with pytest.raises(FileNotFoundError, match=f"test-nope-000.*{EPISODE}"):
        log_episode(dataset, "test-nope-000", save=out)
    with pytest.raises(ValueError, match="not a folder name"):
        log_episode(dataset, "../data", save=out)
    with pytest.raises(FileNotFoundError, match="no-model"):
        log_episode(dataset, EPISODE, model_dir=tmp_path / "no-model", save=out)
    other = tmp_path / "other-format"
    other.mkdir()
    info = json.loads((model / "method.json").read_text())
    (other / "method.json").write_text(json.dumps({**info, "format_version": 99}))
    with pytest.raises(ValueError, match=r"other-format.*format_version 99"):
        log_episode(dataset, EPISODE, model_dir=other, save=out)
    with pytest.raises(ValueError, match="save=PATH"):
        log_episode(dataset, EPISODE)
    with pytest.raises(ValueError, match="hop_s"):
        log_episode(dataset, EPISODE, save=out, hop_s=0.0)
    assert list(tmp_path.glob("*.rrd")) == [] and not list(tmp_path.glob(".x.rrd*"))


def test_cli_writes_a_recording_and_reports_errors(
    dataset: Path, model: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cli.rrd"
    assert (
        main(["viz", "--data", str(dataset), "--episode", EPISODE, "--model", str(model), "--save", str(out)])
        == 0
    )
    printed = capsys.readouterr().out
    assert f"rerun {out}" in printed
    assert f"rerun --serve-web --bind 127.0.0.1 {out}" in printed  # the way to view it without a display
    assert _rows(out)["/detector/score:Scalars:scalars"] == 3
    assert main(["viz", "--data", str(dataset), "--episode", "missing-000", "--save", str(out)]) == 2
    assert "msvdd-bench viz: error: episode folder not found" in capsys.readouterr().err


def test_generated_episode_scores_match_the_evaluation_windows(tiny_dataset: Path, tmp_path: Path) -> None:
    """On a real generated fault episode, the viewer's score at END time s + 2 equals the score the
    evaluation gives the dataset's window starting at s (same decimation, framing and detector)."""
    from benchmarks.dataset import load_window_rows, open_dataset

    data = open_dataset(tiny_dataset)
    train, _ = data.load_windows("train")
    model = save_detector(
        make("iforest-early", seed=0, scale="smoke").fit(train), "iforest-early", tmp_path / "m"
    )
    rows = [r for r in data.rows("test") if r.kind == "mechanical"]
    assert rows, "the tiny preset has fault windows"
    episode_id = rows[0].episode
    rows = [r for r in rows if r.episode == episode_id]
    out = log_episode(tiny_dataset, episode_id, model_dir=model, save=tmp_path / "real.rrd")
    assert out is not None
    windows, _ = load_window_rows(tiny_dataset, rows)
    from benchmarks.methods import load_detector

    expected = load_detector(model)[1].score(windows)
    t, score = _column(out, "/detector/score", "scalars")
    for row, value in zip(rows, expected, strict=True):
        hit = np.flatnonzero(np.isclose(t, row.start_s + 2.0))
        assert hit.size == 1, row
        assert score.ravel()[hit[0]] == pytest.approx(value, rel=1e-9)
    episode = read_episode(tiny_dataset / episode_id)
    counts = _rows(out)
    assert counts["/signals/imu/vel_z:Scalars:scalars"] == episode.imu_time.size
    n_windows = window_starts(episode.imu_time.size / IMU_RATE, 0.5, first_s=0.0).size
    assert counts["/detector/score:Scalars:scalars"] == n_windows
    wheel = episode.trace().robot.wheel_names[rows[0].wheel]
    assert counts[f"/world/robot/wheels/{wheel}/tyre:Cylinders3D:colors"] >= 2  # turns red at the onset


FIRST_ANOMALY = (1.2, 1.3)
"""The tiny trace's first anomaly: the wall contact labelled 1.2 s to 1.3 s."""


def test_blueprint_opens_paused_with_the_first_anomaly_selected(recording: Path) -> None:
    bp = _blueprint(recording)
    panel = bp["/time_panel"]
    assert panel["TimePanelBlueprint:timeline"] == "time"
    assert panel["TimePanelBlueprint:play_state"] == rrb.components.PlayState.Paused.value  # not at the end
    selection = panel["TimePanelBlueprint:time_selection"]
    assert (selection["min"], selection["max"]) == tuple(round(t * 1e9) for t in FIRST_ANOMALY)
    assert panel["TimePanelBlueprint:loop_mode"] == rrb.components.LoopMode.Selection.value
    for side in ("/blueprint_panel", "/selection_panel"):  # the viewport gets the whole window
        assert bp[side]["PanelBlueprint:state"] == rrb.components.PanelState.Collapsed.value


def test_every_plot_has_one_time_axis_from_zero_to_the_end_and_no_legend(recording: Path) -> None:
    bp = _blueprint(recording)
    plots = {**_views(bp, "TimeSeries"), **_views(bp, "StateTimeline")}
    assert len(plots) == 7
    for path in plots:
        axis = bp[f"{path}/TimeAxis"]
        assert axis["TimeAxis:link"] == rrb.components.LinkAxis.LinkToGlobal.value
        assert axis["TimeAxis:view_range"] == {"start": 0, "end": round(DURATION * 1e9)}
    for path in _views(bp, "TimeSeries"):
        assert bp[f"{path}/PlotLegend"]["PlotLegend:visible"] is False  # titles name the lines instead
    # every temporal entity of the recording is on the one `time` timeline, in seconds from 0
    summary = RrdReader(recording).store().summary()
    for line in summary.splitlines():
        if "static=False" in line:
            assert "timelines=['time']" in line, line
    for entity in ("/detector/threshold", "/detector/truth", "/truth/label", "/signals/imu/vel_z"):
        assert _column(recording, entity, "scalars")[0][0] == 0.0, entity


def test_score_plot_holds_scores_threshold_and_truth_apart(recording: Path) -> None:
    bp = _blueprint(recording)
    plots = _views(bp, "TimeSeries")
    (score_view,) = [p for p, f in plots.items() if "score" in f["ViewBlueprint:display_name"]]
    low, high = bp[f"{score_view}/ScalarAxis"]["ScalarAxis:range"]
    _, score = _column(recording, "/detector/score", "scalars")
    _, threshold = _column(recording, "/detector/threshold", "scalars")
    t_truth, truth = _column(recording, "/detector/truth", "scalars")
    values = np.concatenate([score.ravel(), threshold.ravel()])
    assert low < truth.min() and truth.max() < values.min() and values.max() < high
    # the step is up inside the labelled anomalies (1.2-1.3 s collision, 1.5-2.5 s fault), down elsewhere
    up = truth.ravel() == truth.max()
    np.testing.assert_allclose(t_truth[up], [1.2, 1.5])
    np.testing.assert_allclose(t_truth[~up][:3], [0.0, 1.3, 2.5])


def test_3d_view_follows_the_robot_and_labels_only_robot_and_struck_obstacle(recording: Path) -> None:
    bp = _blueprint(recording)
    (scene,) = _views(bp, "3D")
    eye = bp[f"{scene}/EyeControls3D"]
    assert eye["EyeControls3D:tracking_entity"] == "/world/robot/frame"  # moves with the robot
    assert "static /world/robot/frame:LineStrips3D:strips" in _rows(recording)
    shown: dict[str, bool] = {}
    for chunk in RrdReader(recording).store().stream().to_chunks():
        names = chunk.to_record_batch().schema.names
        col = next((n for n in names if n.endswith(":show_labels")), None)
        if col is not None:
            shown[chunk.entity_path] = bool(chunk.to_record_batch().column(col).to_pylist()[-1][0])
    assert shown["/world/robot/body"] and shown["/world/obstacles/struck"]
    assert not shown["/world/contacts"]
    tyres = [p for p in shown if p.endswith("/tyre")]
    assert len(tyres) == 4 and not any(shown[p] for p in tyres)
    assert {p for p, on in shown.items() if on and p.startswith("/world")} == {
        "/world/robot/body",
        "/world/obstacles/struck",
    }


def test_spawn_without_a_display_fails_at_once(
    dataset: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import rerun as rr

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(sys, "platform", "linux")

    def no_spawn(*args: object, **kwargs: object) -> None:
        raise AssertionError("a viewer was spawned without a display")

    monkeypatch.setattr(rr.RecordingStream, "spawn", no_spawn)
    assert main(["viz", "--data", str(dataset), "--episode", EPISODE, "--spawn"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "--spawn needs a display" in err[0] and "--serve-web" in err[0] and "--save" in err[0]
    with pytest.raises(UserError, match="DISPLAY"):
        log_episode(dataset, EPISODE, spawn=True)
    assert main(["viz", "--data", str(dataset), "--episode", EPISODE]) == 2
    assert "--serve-web" in capsys.readouterr().err


def test_has_display_by_platform_and_environment() -> None:
    assert not has_display({}, "linux")
    assert has_display({"DISPLAY": ":0"}, "linux")
    assert has_display({"WAYLAND_DISPLAY": "wayland-0"}, "linux")
    assert not has_display({"DISPLAY": ""}, "freebsd14")
    assert has_display({}, "darwin") and has_display({}, "win32")


def test_serve_web_binds_localhost_prints_the_url_and_stops(
    dataset: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    from benchmarks.commands import viz as viz_command

    web, grpc = free_port(), free_port()
    seen: list[str] = []

    def interrupt_after_a_look() -> None:
        url = capsys.readouterr().out.split("open ", 1)[1].split()[0]
        seen.append(url)
        with urllib.request.urlopen(url, timeout=5) as page:
            assert page.status == 200 and b"Rerun" in page.read()
        raise KeyboardInterrupt

    monkeypatch.setattr(viz_command, "_wait_forever", interrupt_after_a_look)
    saved = tmp_path / "served.rrd"
    argv = ["viz", "--data", str(dataset), "--episode", EPISODE, "--serve-web",
            "--web-port", str(web), "--grpc-port", str(grpc), "--save", str(saved), "--no-audio"]  # fmt: skip
    assert main(argv) == 0
    assert seen == [viewer_url(web, grpc)]
    assert seen[0].startswith(f"http://127.0.0.1:{web}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{grpc}%2Fproxy")
    assert saved.is_file() and "stopped" in capsys.readouterr().out
    with pytest.raises(OSError):  # the server is gone
        urllib.request.urlopen(f"http://127.0.0.1:{web}/", timeout=2)
    assert main([*argv[:-1], "--web-port", str(grpc)]) == 2  # same port twice: refused


def test_struck_obstacle_is_the_one_of_that_kind_nearest_the_contact() -> None:
    trace = tiny_trace()
    near = ObstacleRecord("wall", "plaster", np.array([1.2, 0.5, 0.5]), np.array([0.05, 1.0, 0.5]), 0.1)
    far = ObstacleRecord("wall", "plaster", np.array([-2.0, 0.0, 0.5]), np.array([0.05, 1.0, 0.5]), 0.0)
    chair = ObstacleRecord("chair", "wood", np.array([1.0, 0.6, 0.1]), np.array([0.2, 0.2, 0.2]), 0.0)
    obstacles = (far, chair, near)
    positions = np.tile(np.stack([o.position for o in obstacles]), (trace.imu_time.size, 1, 1))
    two = dataclasses.replace(trace, obstacles=obstacles, obstacle_pos=positions)
    assert struck_obstacles(two) == [2]  # the chair is nearer, but the contact names a wall
    no_near = dataclasses.replace(two, obstacles=obstacles[:2], obstacle_pos=positions[:, :2])
    assert struck_obstacles(no_near) == [0]


def test_generated_collision_opens_on_its_first_anomaly(
    tiny_dataset: Path, tiny_model: Path, tmp_path: Path
) -> None:
    """On a generated collision episode scored by M-SVDD: the blueprint selects the first labelled anomaly,
    the score plot's axis holds scores and threshold, and the struck obstacle is the one labelled."""
    from benchmarks.viz.focus import anomaly_spans

    collisions = sorted(p.name for p in tiny_dataset.glob("test-collision-*"))
    assert collisions, "the tiny preset has collision episodes"
    for episode_id in collisions:
        episode = read_episode(tiny_dataset / episode_id)
        spans = anomaly_spans(episode.imu_time, episode.label)
        if spans and len(episode.trace().contacts.time):
            break
    else:
        raise AssertionError("the tiny preset (seed 0) has no collision episode with a labelled contact")
    out = log_episode(tiny_dataset, episode_id, model_dir=tiny_model, save=tmp_path / "c.rrd")
    assert out is not None
    bp = _blueprint(out)
    selection = bp["/time_panel"]["TimePanelBlueprint:time_selection"]
    assert selection["min"] == round(spans[0].start * 1e9)
    assert selection["max"] == round(spans[0].end * 1e9)
    rows = _rows(out)
    assert rows["/world/obstacles/struck:Boxes3D:centers"] > 0
    plots = _views(bp, "TimeSeries")
    (score_view,) = [p for p, f in plots.items() if "msvdd" in f["ViewBlueprint:display_name"]]
    low, high = bp[f"{score_view}/ScalarAxis"]["ScalarAxis:range"]
    _, score = _column(out, "/detector/score", "scalars")
    _, threshold = _column(out, "/detector/threshold", "scalars")
    assert low < min(score.min(), threshold[0]) and max(score.max(), threshold[0]) < high
