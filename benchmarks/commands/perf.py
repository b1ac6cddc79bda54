"""`msvdd-bench perf`: every stage's speed benchmark in one JSON file and one table."""

from __future__ import annotations

import argparse
import importlib
import json
import os
import pkgutil
import platform
import sys
from pathlib import Path
from typing import Any

from benchmarks import perf
from benchmarks.command import Command
from benchmarks.errors import InputNotFoundError, UserError
from benchmarks.perf.base import PerfStage
from benchmarks.perf_gate import DEFAULT_MAX_SLOWDOWN, compare_perf
from msvdd.atomic import atomic_file


def stage_modules() -> list[str]:
    """The modules of `benchmarks.perf` that may hold a stage (not imported: they import torch and mujoco)."""
    return sorted(m.name for m in pkgutil.iter_modules(perf.__path__) if m.name != "base")


def stages() -> dict[str, PerfStage]:
    """Every registered stage, by name."""
    found: dict[str, PerfStage] = {}
    for name in stage_modules():
        module = importlib.import_module(f"{perf.__name__}.{name}")
        stage = getattr(module, "STAGE", None)
        if isinstance(stage, PerfStage):
            found[stage.name] = stage
    return found


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--stage",
        default="all",
        choices=[*stage_modules(), "all"],
        help="the stage to measure (each stage is named after its module in benchmarks/perf/)",
    )
    p.add_argument("--json", type=Path, required=True, help="where to write the figures")
    p.add_argument("--quick", action="store_true", help="tiny workloads (smoke test, figures not meaningful)")
    p.add_argument(
        "--baseline",
        type=Path,
        default=None,
        help="a perf JSON to compare with: exit 1 when a ratio figure (measured against a reference in the "
        "same run) is more than --max-slowdown worse than the baseline's",
    )
    p.add_argument(
        "--max-slowdown",
        type=float,
        default=DEFAULT_MAX_SLOWDOWN,
        help="tolerated slowdown of a ratio figure against --baseline, as a fraction (0.2: 20 %%)",
    )


def _read_baseline(path: Path) -> dict[str, Any]:
    """The baseline perf JSON; InputNotFoundError or UserError (naming the file) when unreadable."""
    if not path.is_file():
        raise InputNotFoundError(f"--baseline {path} does not exist (write it: `msvdd-bench perf --json`)")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except ValueError as exc:
        raise UserError(f"--baseline {path} is not JSON ({exc})") from exc
    if not isinstance(doc, dict):
        raise UserError(f"--baseline {path} is not the JSON of `msvdd-bench perf`")
    return doc


def gate(baseline: dict[str, Any], report: dict[str, Any], max_slowdown: float, source: Path) -> int:
    """Print one line per ratio figure compared with the baseline; 1 when one regressed, else 0."""
    checks = compare_perf(baseline, report, max_slowdown)
    regressed = [c for c in checks if c.regressed]
    for check in checks:
        print(check.message())
    print(
        f"perf gate against {source}: {len(regressed)} of {len(checks)} ratio figures more than "
        f"{100 * max_slowdown:g} % slower"
    )
    return 1 if regressed else 0


def _run(args: argparse.Namespace) -> int:
    baseline = _read_baseline(args.baseline) if args.baseline is not None else None
    if baseline is not None and bool(baseline.get("quick", False)) != bool(args.quick):
        raise UserError(f"--baseline {args.baseline} and this run differ in --quick: nothing to compare")
    known = stages()
    if args.stage == "all":
        chosen = list(known.values())
    elif args.stage in known:
        chosen = [known[args.stage]]
    else:
        raise UserError(f"--stage {args.stage!r} is unknown; allowed: all, {', '.join(sorted(known))}")
    figures: dict[str, float] = {}
    descriptions: dict[str, str] = {}
    ratios: dict[str, str] = {}
    for stage in chosen:
        figures.update(stage.measure(bool(args.quick)))
        descriptions.update(stage.describe)
        ratios.update(stage.ratios)
    from benchmarks.provenance import code_version

    report = {
        "machine": {
            "platform": platform.platform(),
            "processor": platform.processor(),
            "cpus": os.cpu_count(),
        },
        "quick": bool(args.quick),
        "command": "msvdd-bench " + " ".join(sys.argv[1:]),
        "code_version": code_version(),
        "descriptions": {k: descriptions[k] for k in figures if k in descriptions},
        "ratios": {k: ratios[k] for k in figures if k in ratios},
        **figures,
    }
    target: Path = args.json
    with atomic_file(target, "w") as handle:
        json.dump(report, handle, indent=2)
    width = max((len(k) for k in figures), default=10)
    print(f"{'figure':<{width}}  {'value':>12}  meaning")
    for key, value in figures.items():
        print(f"{key:<{width}}  {value:>12.4g}  {descriptions.get(key, '')}")
    print(f"wrote {target}")
    if baseline is None:
        return 0
    return gate(baseline, report, args.max_slowdown, args.baseline)


COMMAND = Command(
    name="perf",
    help="measure each stage's speed (real-time factors, ratios) and write them to JSON",
    add_arguments=_add_arguments,
    run=_run,
    example=(
        "msvdd-bench perf --stage all --json runs/perf.json\n"
        "msvdd-bench perf --stage sim --quick --json /tmp/perf.json\n"
        "msvdd-bench perf --stage all --json runs/new.json --baseline runs/perf.json  # exit 1: 20 % slower"
    ),
)
