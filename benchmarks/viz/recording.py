"""Log one episode (and optionally a detector's scores on it) to a Rerun recording, headless by default."""

from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path

import rerun as rr

from benchmarks.dataset import window_starts
from benchmarks.episode import IMPORTED, Episode, is_episode_folder, read_episode
from benchmarks.errors import InputNotFoundError, UserError
from benchmarks.viz.blueprint import build_blueprint
from benchmarks.viz.config import TIMELINE, VizConfig
from benchmarks.viz.events import detection_events, log_events, trace_events
from benchmarks.viz.imported import span_events
from benchmarks.viz.plan import Plan, layout, plan_recording
from benchmarks.viz.scene import log_scene
from benchmarks.viz.scoring import EpisodeScores, episode_duration, score_episode
from benchmarks.viz.series import (
    log_audio,
    log_imu,
    log_scores,
    log_spectrogram,
    log_truth,
    log_wheel_speeds,
)
from benchmarks.viz.serve import GRPC_PORT, move_time_cursor, require_display
from msvdd.atomic import atomic_path
from msvdd.contract import WINDOW_S, Detector
from sim.trace import Trace

APPLICATION_ID = "msvdd-bench"
"""Rerun application id of every recording (the viewer groups recordings by it)."""


def find_episode(dataset_dir: str | os.PathLike[str], episode_id: str) -> Path:
    """The folder of `episode_id` in a dataset; FileNotFoundError naming the path and some known ids."""
    data = Path(dataset_dir)
    if not data.is_dir():
        raise InputNotFoundError(f"dataset folder not found: {data}")
    if not episode_id or Path(episode_id).name != episode_id or episode_id.startswith("."):
        raise UserError(f"episode id {episode_id!r} is not a folder name of {data}")
    folder = data / episode_id
    if not folder.is_dir():
        known = sorted(p.name for p in data.iterdir() if is_episode_folder(p))
        hint = f"; episodes there include {', '.join(known[:6])}" if known else "; it holds no episodes"
        raise InputNotFoundError(f"episode folder not found: {folder}{hint}")
    return folder


def load_model(model_dir: str | os.PathLike[str]) -> tuple[str, Detector]:
    """A saved detector folder (from `msvdd-bench train`): (method name, detector).

    Raises:
        FileNotFoundError: the folder or its files are missing (the message names the path).
        ValueError: the folder holds a model of another format or method registry.
    """
    from benchmarks.methods import load_detector

    folder = Path(model_dir)
    if not folder.is_dir():
        raise InputNotFoundError(f"model folder not found: {folder}")
    return load_detector(folder)


def require_episode_modalities(episode: Episode, method: str) -> None:
    """Refuse to score an episode with a method that reads a sensor the episode lacks (an audio-only
    import), as `train` and `evaluate` refuse it on the dataset."""
    from benchmarks.modalities import require_modalities

    require_modalities(episode.path, episode.modalities, method)


def log_recording(
    rec: rr.RecordingStream,
    episode: Episode,
    trace: Trace | None,
    scores: EpisodeScores | None,
    config: VizConfig,
    hop_s: float,
    audio_playback: bool = True,
    plan: Plan | None = None,
) -> Plan:
    """Log everything of one episode into an open recording stream (the lower-level entry).

    Args:
        rec: the recording (any sinks).
        episode: the episode's sensor files.
        trace: its simulator trace; None for an imported episode (no scene, wheels or contact events:
            its labelled anomaly spans are the events, and IMU plots only if it has an IMU).
        scores: a detector's scores on it, or None.
        config: display settings.
        hop_s: window hop, s: the last-2-s spectrogram is logged at every window end.
        audio_playback: also log the episode's audio file for the viewer's audio player.
        plan: what `plan_recording` worked out for the blueprint (computed here when None).

    Returns:
        The plan it logged with (anomaly spans, struck obstacles, spectrogram, score axis).
    """
    if plan is None:
        plan = plan_recording(episode, trace, scores, config)
    if trace is not None:
        log_scene(rec, trace, config, plan.struck)
        log_wheel_speeds(rec, trace, config)
    if "imu" in episode.modalities:
        log_imu(rec, episode)
    log_audio(rec, episode, config)
    if scores is not None:
        ends = scores.end_s
    else:
        ends = window_starts(episode_duration(episode), hop_s, first_s=0.0) + WINDOW_S
    log_spectrogram(rec, plan.spectrogram, ends, config)
    log_truth(rec, episode, trace.robot.wheel_names if trace is not None else ())
    events = trace_events(trace) if trace is not None else span_events(episode)
    if scores is not None:
        log_scores(rec, scores, plan.spans, plan.duration_s, plan.score_axis)
        events += detection_events(scores)
    log_events(rec, events)
    if audio_playback:
        blob = episode.audio_bytes()
        rec.send_columns(
            "audio",
            indexes=[rr.TimeColumn(TIMELINE, duration=[0.0])],
            columns=rr.AssetAudio.columns(blob=[blob], media_type=["audio/flac"]),
        )
    return plan


def _read_and_score(
    dataset_dir: str | os.PathLike[str],
    episode_id: str,
    model_dir: str | os.PathLike[str] | None,
    hop_s: float,
) -> tuple[Episode, Trace | None, EpisodeScores | None]:
    """The episode, its simulator trace (None for a recording) and, with a model, its window scores."""
    episode = read_episode(find_episode(dataset_dir, episode_id))
    trace = episode.trace() if episode.source != IMPORTED else None
    if model_dir is None:
        return episode, trace, None
    method, detector = load_model(model_dir)
    require_episode_modalities(episode, method)
    return episode, trace, score_episode(episode, detector, method, hop_s, model_dir=Path(model_dir))


def log_episode(
    dataset_dir: str | os.PathLike[str],
    episode_id: str,
    *,
    model_dir: str | os.PathLike[str] | None = None,
    save: str | os.PathLike[str] | None = None,
    spawn: bool = False,
    hop_s: float = 0.5,
    config: VizConfig | None = None,
    audio_playback: bool = True,
) -> Path | None:
    """Log one episode of a dataset to Rerun: a `.rrd` file (`save`), a spawned viewer (`spawn`), or both.

    Args:
        dataset_dir: dataset folder (from `msvdd-bench generate`).
        episode_id: episode folder name, e.g. `test-collision-000`.
        model_dir: a saved detector folder; its scores, threshold and detections are logged too.
        save: write the recording to this file (atomically: nothing is left on error).
        spawn: open a native Rerun viewer and stream to it (needs a display); its time cursor is then put
            at the first anomaly.
        hop_s: hop between the scored 2 s windows, s.
        config: display settings.
        audio_playback: embed the episode's audio file for the viewer's audio player.

    Returns:
        The written file, or None when only a viewer was spawned.

    Raises:
        FileNotFoundError: dataset, episode or model folder (or a file in them) missing.
        ValueError: neither `save` nor `spawn`, a bad hop, or a model that cannot score this episode.
        UserError: `spawn` without a display.
    """
    if save is None and not spawn:
        raise ValueError("log_episode needs save=PATH (a .rrd file) or spawn=True")
    if spawn:
        require_display()
    if not hop_s > 0:
        raise UserError(f"hop_s = {hop_s} is invalid; allowed: > 0 s")
    config = config or VizConfig()
    episode, trace, scores = _read_and_score(dataset_dir, episode_id, model_dir, hop_s)
    title = f"{episode_id} ({episode.meta.category}, unit {episode.meta.unit_id})"
    plan = plan_recording(episode, trace, scores, config)
    method_name = scores.method if scores is not None else None
    blueprint = build_blueprint(layout(plan, episode, trace, method_name, title, audio_playback, config))
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=f"{Path(dataset_dir).name}/{episode_id}")
    target = Path(save) if save is not None else None
    with contextlib.ExitStack() as stack:  # the .rrd file is renamed into place at the end, removed on error
        tmp = stack.enter_context(atomic_path(target, suffix=".rrd")) if target is not None else None
        try:
            if spawn:
                rec.spawn(connect=tmp is None, default_blueprint=blueprint)
                if tmp is not None:
                    rec.set_sinks(rr.GrpcSink(), rr.FileSink(tmp), default_blueprint=blueprint)
            elif tmp is not None:
                rec.save(tmp, default_blueprint=blueprint)
            rec.send_recording_name(episode_id)
            log_recording(rec, episode, trace, scores, config, hop_s, audio_playback, plan)
            rec.flush()
            rec.disconnect()
            if spawn and plan.first_anomaly is not None:
                viewer = f"rerun+http://127.0.0.1:{GRPC_PORT}/proxy"
                failed = move_time_cursor(viewer, TIMELINE, plan.first_anomaly.start)
                if failed is not None:
                    print(f"note: could not move the viewer to the first anomaly ({failed})", file=sys.stderr)
        except BaseException:
            if tmp is not None:  # stop the file sink before its file is removed
                with contextlib.suppress(Exception):
                    rec.disconnect()
            raise
    return target
