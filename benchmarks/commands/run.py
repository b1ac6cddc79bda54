"""`msvdd-bench run`: generate, train every method, evaluate and report, in one command."""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

from benchmarks.command import (
    Command,
    add_dataset_arguments,
    add_device_argument,
    add_executor_arguments,
    add_progress_argument,
    add_scale_argument,
)


def add_run_arguments(p: argparse.ArgumentParser) -> None:
    """Options shared by `run` and `demo`."""
    add_dataset_arguments(p, None)
    p.add_argument("--out", type=Path, required=True, help="run folder to create (must not exist)")
    p.add_argument(
        "--resume",
        action="store_true",
        help="reuse the models an interrupted run with the same --out finished (kept in .OUT.partial beside "
        "it), where method, seed, scale, device, dataset and code are the same; train the rest",
    )
    p.add_argument(
        "--methods",
        nargs="+",
        default=None,
        help="methods to train, or groups: table1, ablations, all, or module:Class for a detector of your "
        "own (importable; see docs/detectors.md) (default: the preset's list)",
    )
    p.add_argument("--data", type=Path, default=None, help="reuse this dataset instead of generating one")
    p.add_argument(
        "--cache",
        type=Path,
        default=None,
        help="take the preset's dataset from this cache folder, generating it there once (keyed by preset, "
        "seed and the generating code; reused while its manifest verifies); not with --data",
    )
    p.add_argument(
        "--dev",
        type=Path,
        default=None,
        help="the dev dataset (same preset, another seed) every choice of the methods was made on; "
        "recorded in the report",
    )
    add_executor_arguments(p, what="the episodes of a generated dataset are built")
    add_scale_argument(p, None, "training budget", "default: the dataset preset's")
    p.add_argument(
        "--train-seeds",
        type=int,
        nargs="+",
        default=None,
        help="training seeds of every method (default: the preset's)",
    )
    add_device_argument(p)
    add_progress_argument(p)


def run_from_args(args: argparse.Namespace) -> Path:
    """Run the benchmark as the parsed options say."""
    from benchmarks.executor import make_executor
    from benchmarks.runner import run_benchmark

    with contextlib.closing(make_executor(args.executor, workers=args.workers, address=args.address)) as ex:
        return run_benchmark(
            args.out,
            preset_name=args.preset,
            seed=args.seed,
            method_names=args.methods,
            data=args.data,
            workers=None,
            scale=args.scale,
            seeds=args.train_seeds,
            command="msvdd-bench " + " ".join(sys.argv[1:]),
            progress=not args.no_progress,
            dev=args.dev,
            cache=args.cache,
            device=args.device,
            executor=ex,
            resume=args.resume,
        )


def _run(args: argparse.Namespace) -> int:
    out = run_from_args(args)
    print((out / "results.md").read_text())
    print(f"wrote {out}")
    return 0


COMMAND = Command(
    name="run",
    help="generate a dataset, train every method, evaluate and report, in one command",
    add_arguments=add_run_arguments,
    run=_run,
    example=(
        "msvdd-bench run --preset quick --seed 0 --out runs/quick\n"
        "msvdd-bench run --preset paper --data runs/paper-eval --dev runs/paper-dev --out runs/paper\n"
        "msvdd-bench run --preset paper --data runs/paper-eval --dev runs/paper-dev --out runs/paper --resume"
    ),
)
