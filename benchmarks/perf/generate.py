"""Speed of the whole generate path (simulate + render + write one episode), per core, and its cost against
the reference kernel (`benchmarks.perf.base.fft_reference_s`: one FFT convolution as long as all the audio
generated) measured in the same process before and after the episodes (the faster of the two), on the same
wall clock.

The rate is a worker's steady state: one episode of the same unit and length is built first, untimed for
the rate, as every worker of a dataset builds its first episode once and hundreds after it. What that first
episode pays once per process (loading the compiled kernels, the unit's reference level, the allocator's
first blocks: the memory an episode of that length needs, which the process keeps for the next, see
`benchmarks.allocator`) is reported on its own, `generate_first_episode_s`."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from benchmarks.dataset import EpisodeSpec, build_episode
from benchmarks.perf.base import PerfStage, fft_reference_s
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
    first = EpisodeSpec("perf-first", "nominal", "test", 1233, 6.0, ScenarioOptions(
        duration, environment="indoor", severity=(0.5, 1.0), unit_id=0))  # fmt: skip
    samples = round(sum(spec.options.duration for spec in specs) * 44100)
    before = fft_reference_s(samples, clock=time.perf_counter)
    simulated = 0.0
    with tempfile.TemporaryDirectory() as tmp:
        started = time.perf_counter()
        build_episode(first, Path(tmp))
        first_s = time.perf_counter() - started
        started = time.perf_counter()
        for spec in specs:
            build_episode(spec, Path(tmp))
            simulated += spec.options.duration
        elapsed = time.perf_counter() - started
    reference = min(before, fft_reference_s(samples, clock=time.perf_counter))
    return {
        "generate_rtf": simulated / elapsed,
        "generate_vs_fft": elapsed / reference,
        "generate_first_episode_s": first_s,
    }


STAGE = PerfStage(
    name="generate",
    measure=_measure,
    describe={
        "generate_rtf": "episode seconds (physics + binaural audio + files) generated per second, one core "
        "(target >= 90)",
        "generate_vs_fft": "generate wall time / one FFT convolution as long as the episodes' audio (stereo, "
        "4096 taps) in the same process (lower is better)",
        "generate_first_episode_s": "wall seconds of a process's first episode (as long as each timed "
        "one): the rate's once-per-process costs with it",
    },
    ratios={"generate_vs_fft": "lower"},
)
