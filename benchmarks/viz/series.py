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

from dataclasses import dataclass

import numpy as np
import rerun as rr

from benchmarks.episode import Episode
from benchmarks.viz import palette
from benchmarks.viz.config import TIMELINE, VizConfig
from benchmarks.viz.scoring import EpisodeScores
from benchmarks.viz.signals import band_spectrogram, colorize_db, display_indices, minmax_envelope, run_starts
from msvdd.contract import WINDOW_S
from sim.trace import Trace
from sim.vocab import LABELS, MECHANICAL, NORMAL, SUB_KINDS

EPISODE_ASPECT = 4.0
"""Width : height the whole-episode spectrogram is stretched to (at least), for a readable strip."""


def _times(t: np.ndarray) -> rr.TimeColumn:
    return rr.TimeColumn(TIMELINE, duration=np.asarray(t, dtype=np.float64))


def _style(rec: rr.RecordingStream, path: str, names: list[str], colors: list[tuple[int, ...]] | None = None,
           step: bool = False) -> None:  # fmt: skip
    rec.log(
        path,
        rr.SeriesLines(
            names=names,
            colors=colors,
            interpolation_mode=rr.components.InterpolationMode.StepAfter if step else None,
        ),
        static=True,
    )


def log_imu(rec: rr.RecordingStream, episode: Episode) -> None:
    """Every IMU sample: z velocity (the paper's input), accelerometer and gyro axes."""
    t = _times(episode.imu_time)
    rec.send_columns("signals/imu/vel_z", indexes=[t], columns=rr.Scalars.columns(scalars=episode.imu_vel_z))
    _style(rec, "signals/imu/vel_z", ["z velocity (m/s)"])
    rec.send_columns("signals/imu/acc", indexes=[t], columns=rr.Scalars.columns(scalars=episode.imu6[:, :3]))
    _style(rec, "signals/imu/acc", ["acc x (m/s²)", "acc y (m/s²)", "acc z (m/s²)"])
    rec.send_columns("signals/imu/gyro", indexes=[t], columns=rr.Scalars.columns(scalars=episode.imu6[:, 3:]))
    _style(rec, "signals/imu/gyro", ["gyro x (rad/s)", "gyro y (rad/s)", "gyro z (rad/s)"])


def log_wheel_speeds(rec: rr.RecordingStream, trace: Trace, config: VizConfig) -> None:
    """Wheel joint speeds, one series per wheel, at the display rate."""
    idx = display_indices(trace.time, config.pose_rate_hz)
    rec.send_columns(
        "signals/wheels/speed",
        indexes=[_times(trace.time[idx])],
        columns=rr.Scalars.columns(scalars=np.asarray(trace.wheel_speed)[idx]),
    )
    _style(rec, "signals/wheels/speed", [f"{name} (rad/s)" for name in trace.robot.wheel_names])


def envelope_block(audio_rate: float, config: VizConfig) -> int:
    """Audio samples per envelope row."""
    return max(1, round(audio_rate / config.envelope_rate_hz))


def log_audio(rec: rr.RecordingStream, episode: Episode, config: VizConfig) -> None:
    """Both microphones as a min/max envelope (one row per block, at the block's start time)."""
    block = envelope_block(episode.audio_rate, config)
    colours = {"left": (70, 110, 220, 255), "right": (60, 170, 110, 255)}
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


def log_spectrogram(
    rec: rr.RecordingStream, spec: Spectrogram, window_ends: np.ndarray, config: VizConfig
) -> None:
    """The whole-episode image with a moving cursor, and the last-2-s image at each window end."""
    bands, frames, _ = spec.image.shape
    # A minute is thousands of columns but ~100 bands: stretch the rows so the strip reads at ~4:1.
    stretch = max(1.0, frames / (EPISODE_ASPECT * bands))
    rec.log("spectrogram/episode/image", rr.Transform3D(scale=[1.0, stretch, 1.0]), static=True)
    rec.log("spectrogram/episode/image", rr.Image(spec.image, color_model="RGB"), static=True)
    rows, labels = frequency_ticks(spec.band_centres)
    rec.log(
        "spectrogram/episode/image/ticks",
        rr.Points2D(
            np.stack([np.zeros_like(rows), rows], 1), labels=labels, colors=[palette.CURSOR], radii=0.5
        ),
        static=True,
    )
    hop = config.spectrogram_hop_s
    t0 = float(spec.frame_times[0]) if frames else 0.0
    end = float(spec.frame_times[-1]) + hop if frames else 0.0
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
        return
    last = np.clip(np.searchsorted(spec.frame_times, ends, side="left"), width, frames)
    cols = (last - width)[:, None] + np.arange(width)
    images = np.ascontiguousarray(np.moveaxis(spec.image[:, cols], 1, 0))  # (k, B, width, 3)
    rec.log(
        "spectrogram/window",
        rr.Image.from_fields(format=rr.components.ImageFormat(width=width, height=bands, color_model="RGB",
                                                              channel_datatype="U8")),
        static=True,
    )  # fmt: skip
    rec.log(
        "spectrogram/window/ticks",
        rr.Points2D(
            np.stack([np.zeros_like(rows), rows], 1), labels=labels, colors=[palette.CURSOR], radii=0.5
        ),
        static=True,
    )
    rec.send_columns(
        "spectrogram/window",
        indexes=[_times(ends)],
        columns=rr.Image.columns(buffer=images.reshape(ends.size, -1)),
    )


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


def log_scores(rec: rr.RecordingStream, scores: EpisodeScores) -> None:
    """Score and threshold at every window end; detections where score > threshold; the alarm lane."""
    t = _times(scores.end_s)
    rec.send_columns("detector/score", indexes=[t], columns=rr.Scalars.columns(scalars=scores.score))
    _style(rec, "detector/score", [f"{scores.method} score"], [palette.SCORE])
    threshold = np.full(scores.score.shape, scores.threshold)
    rec.send_columns("detector/threshold", indexes=[t], columns=rr.Scalars.columns(scalars=threshold))
    _style(rec, "detector/threshold", ["threshold"], [palette.THRESHOLD])
    hit = scores.detected
    rec.log(
        "detector/detection",
        rr.SeriesPoints(
            names=["detection"], colors=[palette.DETECTION], markers=["Cross"], marker_sizes=[4.0]
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
        rr.StateConfiguration(values=["alarm", "quiet"], colors=[palette.DETECTION, (70, 70, 70, 255)]),
        static=True,
    )
    if starts.size:
        rec.send_columns(
            "states/detector",
            indexes=[_times(scores.end_s[starts])],
            columns=rr.StateChange.columns(state=alarm[starts].tolist()),
        )
