"""Speed of the whole generate path (simulate + render + write one episode), per core."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from benchmarks.dataset import EpisodeSpec, build_episode
from benchmarks.perf.base import PerfStage
from sim.random_scenarios import ScenarioOptions


def _measure(quick: bool) -> dict[str, float]:
    duration = 10.0 if quick else 60.0
    specs = [
        EpisodeSpec(f"perf-{category}", category, "test", 1234 + i, 6.0, ScenarioOptions(
            duration, environment="indoor", obstacle_kind="wall" if category == "collision" else None,
            fault_kind="bearing" if category == "fault" else None, wheel=1 if category == "fault" else None,
            severity=(0.5, 1.0), unit_id=0))
        for i, category in enumerate(("nominal", "collision", "fault"))
    ]  # fmt: skip
    simulated = 0.0
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for spec in specs:
            build_episode(spec, Path(tmp))
            simulated += spec.options.duration
    elapsed = time.perf_counter() - started
    return {"generate_rtf": simulated / elapsed}


STAGE = PerfStage(
    name="generate",
    measure=_measure,
    describe={
        "generate_rtf": "episode seconds (physics + binaural audio + files) generated per second, one core",
    },
)
