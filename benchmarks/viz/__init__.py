"""Rerun visualisation of one episode: the robot in its arena, what it heard and felt, the detector's scores.

from benchmarks.viz import log_episode
log_episode("runs/demo/dataset", "test-collision-001", model_dir="runs/demo/models/msvdd-seed0",
            save="collision.rrd")   # then: rerun collision.rrd
# without a display: rerun --serve-web --bind 127.0.0.1 collision.rrd (or `msvdd-bench viz --serve-web`)

The recording's blueprint (`blueprint.py`) opens paused with the first anomaly selected, every plot on one
time axis, and the 3D view following the robot; `shots.py` photographs it in headless Chromium.
"""

from benchmarks.viz.blueprint import build_blueprint
from benchmarks.viz.config import TIMELINE, VizConfig
from benchmarks.viz.recording import APPLICATION_ID, find_episode, load_model, log_episode, log_recording
from benchmarks.viz.scoring import EpisodeScores, score_episode

__all__ = [
    "APPLICATION_ID",
    "TIMELINE",
    "EpisodeScores",
    "VizConfig",
    "build_blueprint",
    "find_episode",
    "load_model",
    "log_episode",
    "log_recording",
    "score_episode",
]
