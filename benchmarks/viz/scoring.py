"""Score a whole episode with a saved detector: 2 s windows slid at a hop, each score at its END time."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from benchmarks.dataset import window_starts
from benchmarks.episode import Episode
from benchmarks.errors import UserError
from msvdd import preprocess
from msvdd.contract import AUDIO_RATE, IMU_RATE, WINDOW_S, Detector, WindowError

SCORE_BATCH = 64
"""Windows scored per call to the detector (bounds memory on long episodes)."""


@dataclass(frozen=True)
class EpisodeScores:
    """A detector's scores over one episode."""

    method: str
    """Registry name of the method."""
    start_s: np.ndarray
    """(k,) window start times, s."""
    end_s: np.ndarray
    """(k,) window end times, s: when a causal detector knows the score."""
    score: np.ndarray
    """(k,) float64 anomaly scores, higher = more anomalous."""
    threshold: float
    """The detector's decision threshold (fixed at fit time)."""

    @property
    def detected(self) -> np.ndarray:
        """(k,) bool: score > threshold."""
        return np.asarray(self.score > self.threshold)


def episode_duration(episode: Episode) -> float:
    """Length covered by both the audio and the IMU, s."""
    return min(episode.audio.shape[0] / float(episode.audio_rate), episode.imu_vel_z.shape[0] / IMU_RATE)


def score_episode(
    episode: Episode, detector: Detector, method: str, hop_s: float = 0.5, model_dir: Path | None = None
) -> EpisodeScores:
    """Slide 2 s windows over an episode and score them.

    Args:
        episode: the episode read from disk (44.1 kHz audio, 200 Hz IMU).
        detector: a fitted detector.
        method: its registry name (for labels).
        hop_s: hop between window starts, s.
        model_dir: the model folder, named in errors.

    Raises:
        UserError: the episode cannot be cut into windows this detector reads (the message names the
            model folder and the episode).
    """
    audio4410 = preprocess.decimate_audio(episode.audio, rate=float(episode.audio_rate))
    duration = min(audio4410.shape[0] / AUDIO_RATE, episode_duration(episode))
    starts = window_starts(duration, hop_s, first_s=0.0)
    scores = np.zeros(starts.size, dtype=np.float64)
    where = f"model {model_dir or method} on episode {episode.path}"
    for lo in range(0, starts.size, SCORE_BATCH):
        batch_starts = starts[lo : lo + SCORE_BATCH]
        windows = preprocess.frame_windows(audio4410, episode.imu_vel_z, batch_starts, imu6=episode.imu6)
        try:
            batch = np.asarray(detector.score(windows), dtype=np.float64)
        except WindowError as exc:  # windows it does not read (a bug inside it keeps its traceback)
            raise UserError(f"{where}: the detector cannot score these windows: {exc}") from exc
        if batch.shape != batch_starts.shape:
            raise ValueError(f"{where}: score() returned shape {batch.shape}, expected {batch_starts.shape}")
        scores[lo : lo + batch_starts.size] = batch
    threshold = float(detector.threshold_)
    if not np.isfinite(threshold):
        raise ValueError(f"{where}: threshold_ is {threshold}, not a finite number")
    return EpisodeScores(method, starts, starts + WINDOW_S, scores, threshold)
