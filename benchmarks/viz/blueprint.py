"""The default layout: the 3D scene beside the score, the label lanes and the sensor plots; spectrograms
and the event log underneath. All time-series views share one linked time axis."""

from __future__ import annotations

import rerun.blueprint as rrb

from benchmarks.viz.config import TIMELINE


def _linked() -> rrb.TimeAxis:
    return rrb.TimeAxis(link=rrb.components.LinkAxis.LinkToGlobal)


def _series(name: str, *paths: str) -> rrb.TimeSeriesView:
    return rrb.TimeSeriesView(name=name, contents=[f"+ /{p}" for p in paths], axis_x=_linked())


def build_blueprint(title: str, scored: bool, audio_playback: bool) -> rrb.Blueprint:
    """The layout a person reads an episode with.

    Args:
        title: name of the 3D view (e.g. the episode id).
        scored: whether detector scores were logged (adds the score plot on top of the right column).
        audio_playback: whether the recording holds the audio file (adds an audio player view).
    """
    right: list[rrb.Container | rrb.View] = []
    shares: list[float] = []
    if scored:
        right.append(_series("Anomaly score, threshold, detections", "detector/**"))
        shares.append(2.0)
    right.append(rrb.StateTimelineView(name="Ground truth and detector", origin="/states"))
    shares.append(1.0)
    right.append(_series("IMU z velocity", "signals/imu/vel_z"))
    shares.append(1.5)
    right.append(
        rrb.Tabs(
            _series("Accelerometer", "signals/imu/acc"),
            _series("Gyroscope", "signals/imu/gyro"),
            _series("Wheel speeds", "signals/wheels/speed"),
            _series("Label index", "truth/label"),
            name="IMU axes and wheels",
        )
    )
    shares.append(1.5)
    right.append(_series("Microphones (min/max envelope)", "signals/audio/**"))
    shares.append(1.5)
    bottom: list[rrb.Container | rrb.View] = [
        rrb.Spatial2DView(name="Spectrogram (whole episode, cursor = now)", origin="/spectrogram/episode"),
        rrb.Spatial2DView(name="Spectrogram (last 2 s)", origin="/spectrogram/window"),
        rrb.TextLogView(name="Events", origin="/events"),
    ]
    bottom_shares = [3.0, 1.0, 2.0]
    if audio_playback:
        bottom.append(rrb.AudioView(name="Listen", origin="/audio"))
        bottom_shares.append(1.0)
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.Horizontal(
                rrb.Spatial3DView(name=title, origin="/world"),
                rrb.Vertical(*right, row_shares=shares),
                column_shares=[1.0, 1.2],
            ),
            rrb.Horizontal(*bottom, column_shares=bottom_shares),
            row_shares=[3.0, 1.0],
        ),
        rrb.TimePanel(timeline=TIMELINE, expanded=True),
        collapse_panels=False,
    )
