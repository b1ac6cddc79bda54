"""What one recording shows and where the viewer looks, worked out before anything is logged: the blueprint
goes to the sink first, so it has to know the anomaly spans, the score axis and the spectrogram's bounds."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from benchmarks.episode import Episode
from benchmarks.viz.blueprint import Layout
from benchmarks.viz.config import VizConfig
from benchmarks.viz.focus import (
    AnomalySpan,
    ScoreAxis,
    anomaly_spans,
    box_distance,
    score_axis,
    struck_obstacles,
)
from benchmarks.viz.scoring import EpisodeScores, episode_duration
from benchmarks.viz.series import Spectrogram, episode_spectrogram, spectrogram_layout, window_label_margin
from msvdd.contract import WINDOW_S
from sim.trace import Trace


@dataclass(frozen=True)
class Plan:
    """Everything derived from an episode that both the blueprint and the logging need."""

    duration_s: float
    """Episode length shown on every time axis, s."""
    spans: list[AnomalySpan]
    """Ground-truth anomaly spans, in time order."""
    struck: list[int]
    """Indices of the obstacles the robot hit (their labels are shown)."""
    spectrogram: Spectrogram
    """The display spectrogram."""
    score_axis: ScoreAxis | None
    """y axis of the score plot (scores, threshold and the ground-truth strip), or None without scores."""

    @property
    def first_anomaly(self) -> AnomalySpan | None:
        """Where the viewer should look first."""
        return self.spans[0] if self.spans else None


def plan_recording(
    episode: Episode, trace: Trace | None, scores: EpisodeScores | None, config: VizConfig
) -> Plan:
    """Spans, struck obstacles, spectrogram and score axis of one episode."""
    duration = episode_duration(episode)
    spans = [s for s in anomaly_spans(episode.imu_time, episode.label) if s.start < duration]
    struck = struck_obstacles(trace) if trace is not None else []
    axis = score_axis(scores.score, scores.threshold) if scores is not None else None
    return Plan(duration, spans, struck, episode_spectrogram(episode, config), axis)


def _blocked(trace: Trace, start: np.ndarray, end: np.ndarray, samples: int = 24) -> bool:
    """Whether an obstacle (at the episode's start) stands on the segment from `start` to `end`."""
    positions = np.asarray(trace.obstacle_pos, dtype=np.float64)
    for k, o in enumerate(trace.obstacles):
        centre = positions[0, k] if positions.ndim == 3 and len(positions) else np.asarray(o.position)
        for f in np.linspace(0.1, 1.0, samples):
            if box_distance(start + f * (end - start), centre, np.asarray(o.size), o.yaw) == 0.0:
                return True
    return False


def eye(trace: Trace, follow_radius_m: float = 1.75) -> tuple[
    tuple[float, float, float], tuple[float, float, float]
]:  # fmt: skip
    """(camera position, look target) that frames the robot at the start, from 45 degrees above.

    The distance is the one the viewer keeps while following the ring of `follow_radius_m` around the robot
    (1.5 times its bounding radius), so the view does not jump when following starts. The camera looks in
    towards the arena's centre from outside the robot's spot (the arena behind it), or from the first of
    eight other headings that no obstacle blocks, so that no wall hides the robot.
    """
    # The ring's bounding sphere has radius sqrt(2) r: 1.5 sqrt(2) r away is 1.5 r across and 1.5 r up.
    distance_m = height_m = 1.5 * follow_radius_m
    start = np.asarray(trace.base_pos[0], dtype=np.float64) if len(trace.base_pos) else np.zeros(3)
    outward = float(np.arctan2(start[1], start[0])) if np.linalg.norm(start[:2]) > 0.3 else -0.75 * np.pi
    headings = outward + np.deg2rad([0, 45, -45, 90, -90, 135, -135, 180])
    target = start + np.array([0.0, 0.0, 0.01])  # the ring's centre
    candidates = [
        start + np.array([distance_m * np.cos(a), distance_m * np.sin(a), height_m]) for a in headings
    ]
    position = next((c for c in candidates if not _blocked(trace, target, c)), candidates[0])
    return (
        (float(position[0]), float(position[1]), float(position[2])),
        (float(target[0]), float(target[1]), float(target[2])),
    )


def layout(
    plan: Plan,
    episode: Episode,
    trace: Trace | None,
    method: str | None,
    title: str,
    audio_playback: bool,
    config: VizConfig,
) -> Layout:
    """The blueprint's inputs for one recording."""
    spec = spectrogram_layout(plan.spectrogram)
    bands = plan.spectrogram.image.shape[0]
    width = max(1, round(WINDOW_S / config.spectrogram_hop_s))
    return Layout(
        title=title,
        duration_s=plan.duration_s,
        first_anomaly=plan.first_anomaly,
        method=method,
        score_range=(plan.score_axis.bottom, plan.score_axis.top) if plan.score_axis is not None else None,
        audio_playback=audio_playback,
        eye=eye(trace, config.follow_radius_m) if trace is not None else None,
        spectrogram_x=spec.x_range,
        spectrogram_y=spec.y_range,
        window_x=(-window_label_margin(width), float(width)),
        window_y=(0.0, float(bands)),
        wheel_names=trace.robot.wheel_names if trace is not None else (),
        imu="imu" in episode.modalities,
    )
