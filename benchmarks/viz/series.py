"""Time series on the `time` timeline: IMU, wheel speeds, audio envelope, spectrograms, labels, scores.

Entity layout:
- `signals/imu/vel_z`, `signals/imu/acc` (x, y, z), `signals/imu/gyro` (x, y, z): every IMU sample;
- `signals/wheels/speed`: one series per wheel at the display rate;
- `signals/audio/left`, `signals/audio/right`: min and max of each ~1 ms block;
- `spectrogram/episode/image`: the whole episode's spectrogram (static image, time left to right, high
  bands on top, rows stretched to a readable aspect) and `.../image/cursor`: the current time over it;
- `spectrogram/window`: the last 2 s (what a detector scoring now hears), at every window end;
- `truth/label`: ground-truth label index per IMU sample (0 normal, 1 collision, 2 mechanical);
- `states/truth`, `states/detector`: the same as lanes in a state timeline;
- `detector/score`, `detector/threshold` at every window END time, `detector/detection` at the windows
  whose score exceeds the threshold.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import rerun as rr

from benchmarks.episode import Episode
from benchmarks.viz import palette
from benchmarks.viz.config import TIMELINE, VizConfig
from benchmarks.viz.focus import AnomalySpan, ScoreAxis, score_axis
from benchmarks.viz.scoring import EpisodeScores
from benchmarks.viz.signals import band_spectrogram, colorize_db, display_indices, minmax_envelope, run_starts
from msvdd.contract import WINDOW_S
from sim.trace import Trace
from sim.vocab import LABELS, MECHANICAL, NORMAL, SUB_KINDS

EPISODE_ASPECT = 4.0
"""Width : height the whole-episode spectrogram is stretched to (at least), for a readable strip."""


def _times(t: np.ndarray) -> rr.TimeColumn:
    return rr.TimeColumn(TIMELINE, duration=np.asarray(t, dtype=np.float64))


def _style(
    rec: rr.RecordingStream,
    path: str,
    names: list[str],
    colors: Sequence[tuple[int, ...]] | None = None,
    step: bool = False,
    width: float | None = None,
) -> None:
    rec.log(
        path,
        rr.SeriesLines(
            names=names,
            colors=list(colors) if colors is not None else None,
            widths=None if width is None else [width] * len(names),
            interpolation_mode=rr.components.InterpolationMode.StepAfter if step else None,
        ),
        static=True,
    )


def log_imu(rec: rr.RecordingStream, episode: Episode) -> None:
    """Every IMU sample: z velocity (the paper's input), accelerometer and gyro axes."""
    t = _times(episode.imu_time)
    rec.send_columns("signals/imu/vel_z", indexes=[t], columns=rr.Scalars.columns(scalars=episode.imu_vel_z))
    _style(rec, "signals/imu/vel_z", ["z velocity (m/s)"], [palette.IMU])
    xyz = list(palette.AXES)
    rec.send_columns("signals/imu/acc", indexes=[t], columns=rr.Scalars.columns(scalars=episode.imu6[:, :3]))
    _style(rec, "signals/imu/acc", ["acc x (m/s²)", "acc y (m/s²)", "acc z (m/s²)"], xyz)
    rec.send_columns("signals/imu/gyro", indexes=[t], columns=rr.Scalars.columns(scalars=episode.imu6[:, 3:]))
    _style(rec, "signals/imu/gyro", ["gyro x (rad/s)", "gyro y (rad/s)", "gyro z (rad/s)"], xyz)


def log_wheel_speeds(rec: rr.RecordingStream, trace: Trace, config: VizConfig) -> None:
    """Wheel joint speeds, one series per wheel, at the display rate."""
    idx = display_indices(trace.time, config.pose_rate_hz)
    rec.send_columns(
        "signals/wheels/speed",
        indexes=[_times(trace.time[idx])],
        columns=rr.Scalars.columns(scalars=np.asarray(trace.wheel_speed)[idx]),
    )
    names = trace.robot.wheel_names
    colours = [palette.series_colour(i)[1] for i in range(len(names))]
    _style(rec, "signals/wheels/speed", [f"{name} (rad/s)" for name in names], colours)


def envelope_block(audio_rate: float, config: VizConfig) -> int:
    """Audio samples per envelope row."""
    return max(1, round(audio_rate / config.envelope_rate_hz))


def log_audio(rec: rr.RecordingStream, episode: Episode, config: VizConfig) -> None:
    """Both microphones as a min/max envelope (one row per block, at the block's start time)."""
    block = envelope_block(episode.audio_rate, config)
    colours = palette.MICROPHONES
    for channel, name in enumerate(("left", "right")):
        mins, maxs = minmax_envelope(episode.audio[:, channel], block)
        t = np.arange(mins.size) * (block / episode.audio_rate)
        rec.send_columns(
            f"signals/audio/{name}",
            indexes=[_times(t)],
            columns=rr.Scalars.columns(scalars=np.stack([mins, maxs], axis=1)),
        )
        _style(rec, f"signals/audio/{name}", [f"{name} min", f"{name} max"], [colours[name]] * 2)


@dataclass(frozen=True)
class Spectrogram:
    """A coloured display spectrogram of one episode."""

    frame_times: np.ndarray
    """(F,) time of each image column, s."""
    image: np.ndarray
    """(B, F, 3) uint8, highest band on the top row."""
    band_centres: np.ndarray
    """(B,) band centre frequencies, Hz (low first, i.e. bottom row first)."""


def _colour_table() -> np.ndarray:
    from matplotlib import colormaps

    return (colormaps["magma"](np.linspace(0.0, 1.0, 256))[:, :3] * 255).round().astype(np.uint8)


def episode_spectrogram(episode: Episode, config: VizConfig) -> Spectrogram:
    """Spectrogram of the two microphones' mean."""
    mono = np.asarray(episode.audio, dtype=np.float64).mean(axis=1)
    times, centres, db = band_spectrogram(
        mono,
        float(episode.audio_rate),
        config.spectrogram_nfft,
        config.spectrogram_hop_s,
        config.spectrogram_bands,
        config.spectrogram_fmin_hz,
        config.spectrogram_fmax_hz,
    )
    return Spectrogram(times, colorize_db(db, config.spectrogram_range_db, _colour_table()), centres)


TICKS_HZ = (100.0, 300.0, 1000.0, 3000.0, 10000.0)
"""Frequencies marked along the left edge of the spectrogram, Hz."""


def frequency_ticks(band_centres: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """Image rows (pixel centres, top row 0 = highest band) of the `TICKS_HZ` inside the bands, and labels."""
    centres = np.asarray(band_centres, dtype=np.float64)
    inside = [f for f in TICKS_HZ if centres.size and centres[0] <= f <= centres[-1]]
    band = np.array([int(np.argmin(np.abs(np.log(centres / f)))) for f in inside], dtype=np.float64)
    rows = centres.size - 1 - band + 0.5
    return rows, [f"{f / 1000:g} kHz" if f >= 1000 else f"{f:g} Hz" for f in inside]


@dataclass(frozen=True)
class SpectrogramLayout:
    """Where a spectrogram image lies in its 2D view, and the margins left for its axis labels (view units:
    one unit is one image column across, one stretched image row up)."""

    width: float
    """Image width (columns)."""
    height: float
    """Image height after stretching its rows."""
    stretch: float
    """Vertical scale of the image rows."""
    left: float
    """Margin left of the image for the frequency labels."""
    bottom: float
    """Margin under the image for the time labels."""
    lift: float
    """How far above its row a frequency label's point sits: the viewer draws a label under its point."""

    @property
    def x_range(self) -> tuple[float, float]:
        """Horizontal bounds the view shows."""
        return -self.left, self.width

    @property
    def y_range(self) -> tuple[float, float]:
        """Vertical bounds the view shows (y grows downwards in 2D views)."""
        return 0.0, self.height + self.bottom


LABEL_MARGIN = 0.14
"""Left margin of the whole-episode spectrogram for its frequency labels, as a fraction of its width."""


def spectrogram_layout(spec: Spectrogram, aspect: float = EPISODE_ASPECT) -> SpectrogramLayout:
    """A minute is thousands of columns but ~100 bands: stretch the rows so the strip reads at ~`aspect`:1,
    and leave margins for labels."""
    bands, frames, _ = spec.image.shape
    stretch = max(1.0, frames / (aspect * max(bands, 1)))
    height = bands * stretch
    left = LABEL_MARGIN * frames
    return SpectrogramLayout(float(frames), height, stretch, left, 0.22 * height, 0.11 * height)


def time_ticks(duration_s: float, most: int = 8) -> np.ndarray:
    """Round times (s) to label a time axis of `duration_s` with: a 1-2-5 step, at most `most` ticks."""
    for step in (0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 30.0, 60.0, 120.0, 300.0):
        if duration_s / step <= most:
            break
    return np.arange(0.0, duration_s + 1e-9, step)


def _label_points(
    rec: rr.RecordingStream, path: str, xy: np.ndarray, labels: list[str], static: bool = True
) -> None:
    rec.log(
        path,
        rr.Points2D(xy, labels=labels, colors=[palette.LABEL], radii=0.01, show_labels=True),
        static=static,
    )


def spaced_ticks(rows: np.ndarray, labels: list[str], min_gap: float) -> tuple[np.ndarray, list[str]]:
    """The ticks, top row first, without those closer than `min_gap` rows to the one kept above them (low
    bands are merged into few rows, so 100 Hz and 300 Hz can land almost on top of each other)."""
    order = np.argsort(rows)
    kept: list[int] = []
    for i in order:
        if not kept or rows[i] - rows[kept[-1]] >= min_gap:
            kept.append(int(i))
    return np.asarray(rows)[kept], [labels[i] for i in kept]


def log_spectrogram(
    rec: rr.RecordingStream, spec: Spectrogram, window_ends: np.ndarray, config: VizConfig
) -> SpectrogramLayout:
    """The whole-episode image with a moving cursor and labelled axes, and the last-2-s image at each window
    end; returns where the whole-episode image lies (for the view's bounds)."""
    bands, frames, _ = spec.image.shape
    layout = spectrogram_layout(spec)
    rec.log("spectrogram/episode/image", rr.Transform3D(scale=[1.0, layout.stretch, 1.0]), static=True)
    rec.log("spectrogram/episode/image", rr.Image(spec.image, color_model="RGB"), static=True)
    rows, labels = spaced_ticks(*frequency_ticks(spec.band_centres), min_gap=0.14 * bands)
    _label_points(
        rec,
        "spectrogram/episode/frequency",
        np.stack([np.full_like(rows, -0.5 * layout.left), rows * layout.stretch - layout.lift], 1),
        labels,
    )
    hop = config.spectrogram_hop_s
    t0 = float(spec.frame_times[0]) if frames else 0.0
    end = float(spec.frame_times[-1]) + hop if frames else 0.0
    seconds = time_ticks(end)
    _label_points(
        rec,
        "spectrogram/episode/seconds",
        np.stack([(seconds - t0) / hop + 0.5, np.full_like(seconds, layout.height)], 1),
        [f"{s:g} s" for s in seconds],
    )
    cursor_t = np.arange(0.0, end, 1.0 / config.cursor_rate_hz)
    x = (cursor_t - t0) / hop + 0.5
    strips = np.stack([np.stack([x, np.zeros_like(x)], 1), np.stack([x, np.full_like(x, bands)], 1)], axis=1)
    rec.send_columns(
        "spectrogram/episode/image/cursor",
        indexes=[_times(cursor_t)],
        columns=rr.LineStrips2D.columns(
            strips=list(strips), colors=np.tile(palette.CURSOR, (x.size, 1)).astype(np.uint8)
        ),
    )
    width = max(1, round(WINDOW_S / hop))
    ends = np.asarray(window_ends, dtype=np.float64)
    if ends.size == 0 or frames < width:
        return layout
    last = np.clip(np.searchsorted(spec.frame_times, ends, side="left"), width, frames)
    cols = (last - width)[:, None] + np.arange(width)
    images = np.ascontiguousarray(np.moveaxis(spec.image[:, cols], 1, 0))  # (k, B, width, 3)
    rec.log(
        "spectrogram/window/image",
        rr.Image.from_fields(format=rr.components.ImageFormat(width=width, height=bands, color_model="RGB",
                                                              channel_datatype="U8")),
        static=True,
    )  # fmt: skip
    _label_points(
        rec,
        "spectrogram/window/frequency",
        np.stack([np.full_like(rows, -0.5 * window_label_margin(width)), rows - 0.11 * bands], 1),
        labels,
    )
    rec.send_columns(
        "spectrogram/window/image",
        indexes=[_times(ends)],
        columns=rr.Image.columns(buffer=images.reshape(ends.size, -1)),
    )
    return layout


def window_label_margin(width: int) -> float:
    """Left margin of the last-2-s spectrogram for its frequency labels, image columns."""
    return 0.45 * width


def state_name(label: int, sub_kind: int, wheel: int, wheel_names: tuple[str, ...]) -> str:
    """A ground-truth state as shown in the state lane, e.g. `mechanical: bearing (front_left)`."""
    if label == NORMAL:
        return LABELS[NORMAL]
    text = f"{LABELS[label]}: {SUB_KINDS[sub_kind]}"
    if label == MECHANICAL and 0 <= wheel < len(wheel_names):
        text += f" ({wheel_names[wheel]})"
    return text


def log_truth(rec: rr.RecordingStream, episode: Episode, wheel_names: tuple[str, ...]) -> None:
    """The label index per IMU sample, and its runs as a state lane."""
    t = np.asarray(episode.imu_time, dtype=np.float64)
    label = np.asarray(episode.label, dtype=np.int64)
    rec.send_columns(
        "truth/label", indexes=[_times(t)], columns=rr.Scalars.columns(scalars=label.astype(np.float64))
    )
    names = ["label (0 normal, 1 collision, 2 mechanical)"]
    _style(rec, "truth/label", names, [palette.LABEL_COLORS["collision"]], step=True)
    sub = np.asarray(episode.sub_kind, dtype=np.int64)
    wheel = np.asarray(episode.label_wheel, dtype=np.int64)
    keys = (label * 1000 + sub) * 100 + wheel + 1
    starts = run_starts(keys)
    names = [state_name(int(label[i]), int(sub[i]), int(wheel[i]), wheel_names) for i in starts]
    unique = sorted(set(names), key=names.index)
    rec.log(
        "states/truth",
        rr.StateConfiguration(values=unique, colors=[palette.LABEL_COLORS[n.split(":")[0]] for n in unique]),
        static=True,
    )
    rec.send_columns("states/truth", indexes=[_times(t[starts])], columns=rr.StateChange.columns(state=names))


def truth_steps(
    spans: list[AnomalySpan], duration_s: float, low: float, high: float
) -> tuple[np.ndarray, np.ndarray]:
    """The ground truth as a step series: `low` while normal, `high` inside every anomaly span.

    Returns:
        (times, values): a value holds from its time to the next (step-after interpolation); starts at 0 s
        and ends at `duration_s`.
    """
    times, values = [0.0], [low]
    for span in spans:
        if span.start <= times[-1]:
            values[-1] = high
        else:
            times.append(span.start)
            values.append(high)
        times.append(span.end)
        values.append(low)
    if times[-1] < duration_s:
        times.append(duration_s)
        values.append(values[-1])
    keep = np.asarray(times) <= max(duration_s, 0.0)
    return np.asarray(times)[keep], np.asarray(values)[keep]


def log_scores(
    rec: rr.RecordingStream, scores: EpisodeScores, spans: list[AnomalySpan], duration_s: float,
    axis: ScoreAxis | None = None,
) -> None:  # fmt: skip
    """Score at every window end; the threshold as a line over the whole episode; detections where
    score > threshold; the ground truth as a step in the strip under the scores (see `ScoreAxis`); the
    alarm lane."""
    axis = axis if axis is not None else score_axis(scores.score, scores.threshold)
    t = _times(scores.end_s)
    rec.send_columns("detector/score", indexes=[t], columns=rr.Scalars.columns(scalars=scores.score))
    _style(rec, "detector/score", [f"{scores.method} score"], [palette.SCORE], width=2.0)
    threshold_t = np.unique(np.concatenate([[0.0], scores.end_s, [duration_s]]))
    rec.send_columns(
        "detector/threshold",
        indexes=[_times(threshold_t)],
        columns=rr.Scalars.columns(scalars=np.full(threshold_t.shape, scores.threshold)),
    )
    _style(rec, "detector/threshold", ["threshold"], [palette.THRESHOLD], width=1.5)
    truth_t, truth_v = truth_steps(spans, duration_s, axis.truth_low, axis.truth_high)
    rec.send_columns("detector/truth", indexes=[_times(truth_t)], columns=rr.Scalars.columns(scalars=truth_v))
    truth_colour = palette.LABEL_COLORS[spans[0].label] if spans else palette.LABEL_COLORS["collision"]
    _style(rec, "detector/truth", ["true anomaly (up = anomalous)"], [truth_colour], step=True, width=2.0)
    hit = scores.detected
    rec.log(
        "detector/detection",
        rr.SeriesPoints(
            names=["detection"], colors=[palette.DETECTION], markers=["Cross"], marker_sizes=[6.0]
        ),
        static=True,
    )
    if hit.any():
        rec.send_columns(
            "detector/detection",
            indexes=[_times(scores.end_s[hit])],
            columns=rr.Scalars.columns(scalars=scores.score[hit]),
        )
    alarm = np.where(hit, "alarm", "quiet")
    starts = run_starts(hit)
    rec.log(
        "states/detector",
        rr.StateConfiguration(
            values=["alarm", "quiet", NO_SCORE], colors=[palette.DETECTION, palette.QUIET, palette.NO_SCORE]
        ),
        static=True,
    )
    if starts.size:
        rec.send_columns(
            "states/detector",
            indexes=[_times(np.concatenate([[0.0], scores.end_s[starts]]))],
            columns=rr.StateChange.columns(state=[NO_SCORE, *alarm[starts].tolist()]),
        )


NO_SCORE = "no score yet"
"""Detector lane state before the first window ends (a score needs a whole window)."""
