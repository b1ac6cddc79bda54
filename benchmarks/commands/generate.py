"""`msvdd-bench generate`: simulate and render a dataset from a preset."""

from __future__ import annotations

import argparse
import contextlib
from pathlib import Path

from benchmarks.command import Command, add_dataset_arguments, add_executor_arguments, add_progress_argument


def _add_arguments(p: argparse.ArgumentParser) -> None:
    add_dataset_arguments(p, "quick")
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument("--out", type=Path, help="dataset folder to create (must not exist)")
    where.add_argument(
        "--cache",
        type=Path,
        help="cache folder: generate into DIR/<preset>-seed<seed>-<key> unless a verified copy is there; "
        "prints the dataset folder's absolute path on the last line",
    )
    add_executor_arguments(p)
    add_progress_argument(p)


def _run(args: argparse.Namespace) -> int:
    from benchmarks.cache import cached_dataset
    from benchmarks.dataset import generate, open_dataset
    from benchmarks.executor import make_executor

    progress = not args.no_progress
    with contextlib.closing(make_executor(args.executor, workers=args.workers, address=args.address)) as ex:
        if args.cache is not None:
            path, reused = cached_dataset(args.cache, args.preset, args.seed, progress=progress, executor=ex)
            if reused:
                print(f"reusing cached dataset (verified)\n{path.absolute()}")
                return 0
        else:
            path = generate(args.preset, args.seed, args.out, progress=progress, executor=ex)
    dataset = open_dataset(path, verify=False)
    counts: dict[tuple[str, str], int] = {}
    for row in dataset.windows:
        counts[(row.split, row.kind)] = counts.get((row.split, row.kind), 0) + 1
    print(f"wrote {path}: {len(dataset.episode_ids)} episodes, {len(dataset.windows)} windows")
    for (split, kind), n in sorted(counts.items()):
        print(f"  {split:<5} {kind:<10} {n:>6}")
    if args.cache is not None:
        print(path.absolute())
    return 0


COMMAND = Command(
    name="generate",
    help="simulate and render a dataset (episodes, windows.csv, manifest.json) from a preset",
    add_arguments=_add_arguments,
    run=_run,
    example=(
        "msvdd-bench generate --preset quick --seed 0 --out runs/quick-seed0\n"
        "msvdd-bench generate --preset paper --seed 1 --out /shared/paper-dev --executor ray --address auto"
    ),
)
