"""`msvdd-bench sweep`: difficulty curves, AUC against one swept dataset property, one line per method."""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

from benchmarks.command import Command, add_device_argument, add_executor_arguments, add_progress_argument


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "spec",
        metavar="SPEC",
        help="a sweep spec TOML file, or the name of one in assets/sweeps/ (e.g. severity)",
    )
    p.add_argument(
        "--out", type=Path, required=True, help="sweep folder to create (must not exist, unless --resume)"
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="finish a sweep folder made by the same spec: finished points are reused, the rest run",
    )
    add_executor_arguments(p, what="the sweep's tasks run (one per point and dataset seed)")
    add_device_argument(p)
    add_progress_argument(p)


def _run(args: argparse.Namespace) -> int:
    from benchmarks.executor import make_executor
    from benchmarks.sweeps.report import write_outputs
    from benchmarks.sweeps.run import run_sweep
    from benchmarks.sweeps.spec import load_spec

    spec = load_spec(args.spec)
    with contextlib.closing(make_executor(args.executor, workers=args.workers, address=args.address)) as ex:
        result = run_sweep(
            spec,
            args.out,
            ex,
            command="msvdd-bench " + " ".join(sys.argv[1:]),
            progress=not args.no_progress,
            device=args.device,
            resume=args.resume,
        )
    write_outputs(result)
    print((result.out / "sweep.md").read_text())
    print(f"wrote {result.out}")
    return 0


COMMAND = Command(
    name="sweep",
    help="difficulty curves: generate, train and score every point of a swept axis (severity, SNR, speed, "
    "unseen units, surfaces, environments)",
    description="Difficulty curves. A spec (TOML) names a base preset, dataset seeds, methods and one axis "
    "with its values; each point is the base preset with that field changed, generated, trained and scored "
    "as a whole `msvdd-bench run` in DIR/points/. Writes sweep.md, sweep.json and figures/*.png: AUC with "
    "episode-cluster bootstrap 95 % intervals, one line per method. Shipped specs: assets/sweeps/.",
    add_arguments=_add_arguments,
    run=_run,
    example=(
        "msvdd-bench sweep severity --out runs/sweep-severity\n"
        "msvdd-bench sweep assets/sweeps/unseen_surfaces.toml --out /shared/sweep-surf --executor ray "
        "--address auto"
    ),
)
