"""Speed of the whole generate path (simulate + render + write one episode), per core."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from benchmarks.dataset import EpisodeSpec, build_episode
from benchmarks.perf.base import PerfStage


def _measure(quick: bool) -> dict[str, float]:
    duration = 10.0 if quick else 60.0
    specs = [
        EpisodeSpec(f"perf-{category}", category, "test", 1234 + i, 0, 6.0, duration, "indoor",
                    "wall" if category == "collision" else None, "bearing" if category == "fault" else None,
                    1 if category == "fault" else None, (0.5, 1.0), 1.0)
        for i, category in enumerate(("nominal", "collision", "fault"))
    ]  # fmt: skip
    simulated = 0.0
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for spec in specs:
            build_episode(spec, Path(tmp))
            simulated += spec.duration_s
    elapsed = time.perf_counter() - started
    return {"generate_rtf": simulated / elapsed}


STAGE = PerfStage(
    name="generate",
    measure=_measure,
    describe={
        "generate_rtf": "episode seconds (physics + binaural audio + files) generated per second, one core",
    },
)
