"""Speed of `msvdd-bench viz`: logging one generated episode (with a detector's scores) to a .rrd file, also
against the reference kernel (`benchmarks.perf.base.fft_reference_s`: one FFT convolution as long as the
episode's audio) measured in the same process before and after the logging (the faster), on the same clock.
Each logging time is the best of 3 after an untimed one (the first pays Rerun's start-up)."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.dataset import EpisodeSpec, build_episode
from benchmarks.episode import read_episode
from benchmarks.methods import make, save_detector
from benchmarks.perf.base import PerfStage, best_time, fft_reference_s
from msvdd import preprocess
from sim.random_scenarios import ScenarioOptions


def _measure(quick: bool) -> dict[str, float]:
    duration = 10.0 if quick else 60.0
    options = ScenarioOptions(
        duration, environment="indoor", fault_kind="bearing", wheel=1, severity=(0.5, 1.0), unit_id=0
    )
    spec = EpisodeSpec("perf-fault", "fault", "test", 4321, 6.0, options)
    from benchmarks.viz import log_episode

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        build_episode(spec, root / "data")
        episode = read_episode(root / "data" / spec.episode_id)
        windows = preprocess.frame_windows(
            preprocess.decimate_audio(episode.audio), episode.imu_vel_z, np.arange(4) * 0.5, imu6=episode.imu6
        )
        model = save_detector(make("audio-rms", seed=0, scale="smoke").fit(windows), "audio-rms", root / "m")
        samples = round(duration * 44100)
        before = fft_reference_s(samples, clock=time.perf_counter)
        repeats = 1 if quick else 3
        plain_s = best_time(
            lambda r: log_episode(root / "data", spec.episode_id, save=root / f"plain{r}.rrd"),
            repeats,
            time.perf_counter,
        )
        scored_s = best_time(
            lambda r: log_episode(
                root / "data", spec.episode_id, model_dir=model, save=root / f"scored{r}.rrd"
            ),
            repeats,
            time.perf_counter,
        )
        reference = min(before, fft_reference_s(samples, clock=time.perf_counter))
        size_mb = (root / "scored0.rrd").stat().st_size / 1e6
    return {
        "viz_log_s": plain_s,
        "viz_log_rtf": duration / plain_s,
        "viz_scored_log_s": scored_s,
        "viz_log_vs_fft": plain_s / reference,
        "viz_scored_log_vs_fft": scored_s / reference,
        "viz_file_mb_per_min": size_mb * 60.0 / duration,
    }


STAGE = PerfStage(
    name="viz",
    measure=_measure,
    describe={
        "viz_log_s": "seconds to log one episode (60 s; 10 s with --quick) to a .rrd, no model, best of 3 "
        "after one untimed; target < 5",
        "viz_log_rtf": "episode seconds logged per second of wall time, no model",
        "viz_scored_log_s": "the same with audio-rms scores every 0.5 s (read model, score, log)",
        "viz_file_mb_per_min": ".rrd size per minute of episode with scores and embedded audio, MB",
        "viz_log_vs_fft": "logging time, no model / one FFT convolution as long as the episode's audio "
        "(stereo, 4096 taps) in the same process (lower is better)",
        "viz_scored_log_vs_fft": "the same with audio-rms scores every 0.5 s (lower is better)",
    },
    ratios={"viz_log_vs_fft": "lower", "viz_scored_log_vs_fft": "lower"},
)
