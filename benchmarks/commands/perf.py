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

from benchmarks import perf
from benchmarks.command import Command
from benchmarks.errors import UserError
from benchmarks.perf.base import PerfStage
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


def _run(args: argparse.Namespace) -> int:
    known = stages()
    if args.stage == "all":
        chosen = list(known.values())
    elif args.stage in known:
        chosen = [known[args.stage]]
    else:
        raise UserError(f"--stage {args.stage!r} is unknown; allowed: all, {', '.join(sorted(known))}")
    figures: dict[str, float] = {}
    descriptions: dict[str, str] = {}
    for stage in chosen:
        figures.update(stage.measure(bool(args.quick)))
        descriptions.update(stage.describe)
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
    return 0


COMMAND = Command(
    name="perf",
    help="measure each stage's speed (real-time factors, ratios) and write them to JSON",
    add_arguments=_add_arguments,
    run=_run,
    example=(
        "msvdd-bench perf --stage all --json runs/perf.json\n"
        "msvdd-bench perf --stage sim --quick --json /tmp/perf.json"
    ),
)
