"""The shape of a performance stage measured by `msvdd-bench perf`."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class PerfStage:
    """A stage benchmark: runs the real code path and returns named figures (ratios, rates, ms)."""

    name: str
    """Stage name for `--stage` (sim, audio, detector, generate)."""
    measure: Callable[[bool], dict[str, float]]
    """measure(quick) -> figures; `quick` shrinks the workload for smoke tests."""
    describe: dict[str, str]
    """One line per figure: what it means and its target."""
