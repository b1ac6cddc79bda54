"""The speed gate: a `msvdd-bench perf` JSON's ratio figures against a baseline's (`perf --baseline`).

Only ratio figures are compared: each is measured against a reference in the same run (`PerfStage.ratios`),
so the machine's speed and load cancel and two runs, even on different machines, can be put side by side.
A figure regresses when it is more than `max_slowdown` worse than the baseline's: a cost ratio (lower is
better) above baseline x (1 + max_slowdown), a speed-up (higher is better) below baseline / (1 +
max_slowdown).
Pure arithmetic on two JSON documents (no measuring, no imports beyond the standard library).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from benchmarks.errors import UserError

DEFAULT_MAX_SLOWDOWN = 0.20
"""Tolerated slowdown of a ratio figure against the baseline's (0.20: 20 % worse fails)."""


@dataclass(frozen=True)
class RatioCheck:
    """One ratio figure compared with its baseline."""

    figure: str
    """The figure's name."""
    better: str
    """"lower" (a cost against the reference) or "higher" (a speed-up)."""
    baseline: float
    """The baseline's value."""
    candidate: float
    """This run's value."""
    max_slowdown: float
    """The tolerated slowdown (0.20 = 20 %)."""

    @property
    def slowdown(self) -> float:
        """How many times slower the candidate is than the baseline on this figure (1: same; > 1: slower)."""
        if self.better == "lower":
            return self.candidate / self.baseline if self.baseline > 0 else math.inf
        return self.baseline / self.candidate if self.candidate > 0 else math.inf

    @property
    def limit(self) -> float:
        """The worst value the candidate may have and still pass."""
        factor = 1.0 + self.max_slowdown
        return self.baseline * factor if self.better == "lower" else self.baseline / factor

    @property
    def regressed(self) -> bool:
        """More than `max_slowdown` worse than the baseline (a non-finite value counts as regressed)."""
        if not (math.isfinite(self.candidate) and math.isfinite(self.baseline)):
            return True
        return self.slowdown > 1.0 + self.max_slowdown

    def message(self) -> str:
        """One line: the figure, both values, the slowdown and the limit."""
        bound = "<=" if self.better == "lower" else ">="
        verdict = "REGRESSED" if self.regressed else "ok"
        return (
            f"{verdict}: {self.figure} {self.baseline:.4g} (baseline) -> {self.candidate:.4g} (this run), "
            f"x{self.slowdown:.3g} slower ({self.better} is better); limit {bound} {self.limit:.4g} "
            f"(x{1.0 + self.max_slowdown:.3g})"
        )


def ratio_directions(candidate: Mapping[str, Any], baseline: Mapping[str, Any]) -> dict[str, str]:
    """The ratio figures and their directions: the candidate's declarations, else the baseline's (a JSON
    written before ratios were recorded has none)."""
    merged: dict[str, str] = {}
    for doc in (baseline, candidate):
        ratios = doc.get("ratios", {})
        if not isinstance(ratios, dict):
            raise UserError(f"'ratios' in a perf JSON must map figures to 'lower' or 'higher': {ratios!r}")
        for name, better in ratios.items():
            if better not in ("lower", "higher"):
                raise UserError(f"ratio figure {name!r} has direction {better!r}; allowed: lower, higher")
            merged[str(name)] = str(better)
    return merged


def compare_perf(
    baseline: Mapping[str, Any],
    candidate: Mapping[str, Any],
    max_slowdown: float = DEFAULT_MAX_SLOWDOWN,
    directions: Mapping[str, str] | None = None,
) -> list[RatioCheck]:
    """Every ratio figure both runs measured, compared (in the order the ratios are declared). UserError when
    the two cannot be compared: no ratio figure in common, one a `--quick` run and the other not, or a bad
    limit."""
    if not (max_slowdown >= 0 and math.isfinite(max_slowdown)):
        raise UserError(f"the tolerated slowdown must be a finite number >= 0, not {max_slowdown}")
    if bool(baseline.get("quick", False)) != bool(candidate.get("quick", False)):
        raise UserError("one perf run is --quick and the other is not: their figures cannot be compared")
    ratios = dict(directions) if directions is not None else ratio_directions(candidate, baseline)
    checks = []
    for name, better in ratios.items():
        if name not in candidate or name not in baseline:
            continue
        try:
            base, cand = float(baseline[name]), float(candidate[name])
        except (TypeError, ValueError) as exc:
            raise UserError(f"ratio figure {name!r} is not a number ({exc})") from exc
        checks.append(RatioCheck(name, better, base, cand, max_slowdown))
    if not checks:
        raise UserError(
            "the baseline and this run have no ratio figure in common (measure the same --stage in both)"
        )
    return checks
