"""The default layout, made to be read at a glance on a 1440x900 or 1920x1080 screen.

Left: the 3D scene following the robot, the event table, the spectrogram. Right, one column on one time axis
from 0 to the episode's end: the anomaly score with its threshold, the detections and the ground truth;
the ground-truth and detector lanes; the IMU z velocity; the microphones; IMU axes and wheel speeds in tabs.
The side panels start collapsed, playback starts paused (not at the last frame), and the first anomaly is the
time selection. Legends are off: each plot's title names its lines and their colours.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import rerun.blueprint as rrb

from benchmarks.viz import palette
from benchmarks.viz.config import TIMELINE
from benchmarks.viz.focus import AnomalySpan

TRUTH_COLOUR_NAMES: dict[str, str] = {"collision": "orange", "mechanical": "magenta"}
"""How the score plot's title names the colour of the ground-truth step (see `palette.LABEL_COLORS`)."""


@dataclass(frozen=True)
class Layout:
    """What the blueprint needs to know about one recording."""

    title: str
    """Name of the 3D view (e.g. the episode id)."""
    duration_s: float
    """Episode length: every time axis spans 0 to this, s."""
    first_anomaly: AnomalySpan | None = None
    """The first ground-truth anomaly: the time selection, and named in the score plot's title."""
    method: str | None = None
    """The detector's name when its scores were logged (adds the score plot and the detector lane)."""
    score_range: tuple[float, float] | None = None
    """y range of the score plot: every score and the threshold inside."""
    audio_playback: bool = True
    """Whether the recording holds the audio file (adds an audio player tab)."""
    eye: tuple[tuple[float, float, float], tuple[float, float, float]] | None = ((-3.0, -3.0, 2.5), (0, 0, 0))
    """(camera position, look target) of the 3D view at the start, world frame, m; None: no 3D scene (an
    imported episode has no simulator trace)."""
    spectrogram_x: tuple[float, float] = (0.0, 1.0)
    """Horizontal bounds of the whole-episode spectrogram view (image columns, label margin included)."""
    spectrogram_y: tuple[float, float] = (0.0, 1.0)
    """Vertical bounds of the whole-episode spectrogram view."""
    window_x: tuple[float, float] = (0.0, 1.0)
    """Horizontal bounds of the last-2-s spectrogram view."""
    window_y: tuple[float, float] = (0.0, 1.0)
    """Vertical bounds of the last-2-s spectrogram view."""
    wheel_names: tuple[str, ...] = field(default_factory=tuple)
    """Wheel names, in the order of the wheel-speed lines (none: no wheel-speed plot)."""
    imu: bool = True
    """Whether the episode has an IMU (adds its plots)."""


def time_axis(duration_s: float) -> rrb.TimeAxis:
    """One time axis for every plot: 0 to the episode's end, linked so that zooming one zooms all."""
    return rrb.TimeAxis(
        link=rrb.components.LinkAxis.LinkToGlobal,
        view_range=rrb.TimeRange(
            start=rrb.TimeRangeBoundary.absolute(seconds=0.0),
            end=rrb.TimeRangeBoundary.absolute(seconds=float(duration_s)),
        ),
    )


def _series(
    name: str, paths: list[str], duration_s: float, y_range: tuple[float, float] | None = None
) -> rrb.TimeSeriesView:
    return rrb.TimeSeriesView(
        name=name,
        contents=[f"+ /{p}" for p in paths],
        axis_x=time_axis(duration_s),
        axis_y=rrb.ScalarAxis(range=y_range) if y_range is not None else None,
        plot_legend=rrb.PlotLegend(visible=False),
    )


def score_title(layout: Layout) -> str:
    """Title of the score plot: what each line is, by colour."""
    truth = "orange"
    if layout.first_anomaly is not None:
        truth = TRUTH_COLOUR_NAMES.get(layout.first_anomaly.label, truth)
    return (
        f"{layout.method} score (blue), threshold (red), detections (red x), "
        f"true anomaly ({truth} step at the bottom)"
    )


def _colour_list(names: tuple[str, ...] | list[str]) -> str:
    return ", ".join(f"{name} {palette.series_colour(i)[0]}" for i, name in enumerate(names))


def _right_column(layout: Layout) -> rrb.Vertical:
    """The time-aligned plots, top to bottom."""
    d = layout.duration_s
    views: list[rrb.Container | rrb.View] = []
    shares: list[float] = []
    if layout.method is not None:
        views.append(_series(score_title(layout), ["detector/**"], d, layout.score_range))
        shares.append(3.2)
    lanes = "Detector alarm (top lane), ground truth (bottom lane)" if layout.method else "Ground truth"
    views.append(rrb.StateTimelineView(name=lanes, origin="/states", time_view=time_axis(d)))
    shares.append(1.6)
    if layout.imu:
        views.append(_series("IMU z velocity, m/s", ["signals/imu/vel_z"], d))
        shares.append(1.6)
    views.append(_series("Microphones, min/max per ms: left (blue), right (green)", ["signals/audio/**"], d))
    shares.append(1.6)
    tabs: list[rrb.Container | rrb.View] = []
    if layout.imu:
        tabs.append(_series("Accelerometer, m/s²: x red, y green, z blue", ["signals/imu/acc"], d))
        tabs.append(_series("Gyroscope, rad/s: x red, y green, z blue", ["signals/imu/gyro"], d))
    if layout.wheel_names:
        wheels = f"Wheel speeds, rad/s: {_colour_list(layout.wheel_names)}"
        tabs.append(_series(wheels, ["signals/wheels/speed"], d))
    if tabs:
        views.append(rrb.Tabs(*tabs, name="IMU axes and wheels"))
        shares.append(1.6)
    return rrb.Vertical(*views, row_shares=shares)


def _left_column(layout: Layout) -> rrb.Vertical:
    """The 3D scene, the events, the spectrograms."""
    events = rrb.TextLogView(
        name="Events (time, s)",
        origin="/events",
        columns=rrb.TextLogColumns(
            timeline_columns=[rrb.encodings.TimelineColumn(TIMELINE, visible=False)],
            text_log_columns=[
                rrb.encodings.TextLogColumn("loglevel"),
                rrb.encodings.TextLogColumn("body"),
                rrb.encodings.TextLogColumn("entitypath", visible=False),
            ],
        ),
    )
    bottom: list[rrb.Container | rrb.View] = [
        rrb.Spatial2DView(
            name="Spectrogram of the episode (white line = now)",
            origin="/spectrogram/episode",
            visual_bounds=rrb.VisualBounds2D(x_range=layout.spectrogram_x, y_range=layout.spectrogram_y),
        ),
        rrb.Spatial2DView(
            name="Spectrogram of the last 2 s (what the detector hears now)",
            origin="/spectrogram/window",
            visual_bounds=rrb.VisualBounds2D(x_range=layout.window_x, y_range=layout.window_y),
        ),
    ]
    if layout.audio_playback:
        bottom.append(rrb.AudioView(name="Listen", origin="/audio"))
    sound = rrb.Tabs(*bottom, name="Sound")
    if layout.eye is None:
        return rrb.Vertical(events, sound, row_shares=[1.0, 1.0])
    position, target = layout.eye
    scene = rrb.Spatial3DView(
        name=layout.title,
        origin="/world",
        eye_controls=rrb.EyeControls3D(
            kind=rrb.components.Eye3DKind.Orbital,
            position=position,
            look_target=target,
            tracking_entity="/world/robot/frame",
        ),
    )
    return rrb.Vertical(scene, events, sound, row_shares=[3.4, 1.5, 1.5])


def time_panel(layout: Layout) -> rrb.TimePanel:
    """Paused on the `time` timeline, the first anomaly selected (press play to loop over it)."""
    selection = None
    loop = None
    if layout.first_anomaly is not None:
        span = layout.first_anomaly
        end = max(span.end, span.start + 0.05)
        selection = rrb.components.AbsoluteTimeRange(min=round(span.start * 1e9), max=round(end * 1e9))
        loop = rrb.components.LoopMode.Selection
    return rrb.TimePanel(
        timeline=TIMELINE,
        state="collapsed",
        play_state=rrb.components.PlayState.Paused,
        time_selection=selection,
        loop_mode=loop,
    )


def build_blueprint(layout: Layout) -> rrb.Blueprint:
    """The layout a person reads an episode with."""
    return rrb.Blueprint(
        rrb.Horizontal(_left_column(layout), _right_column(layout), column_shares=[2.0, 3.0]),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        time_panel(layout),
    )
