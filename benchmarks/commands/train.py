"""`msvdd-bench train`: fit one method on a dataset's nominal training windows."""

from __future__ import annotations

import argparse
from pathlib import Path

from benchmarks.command import Command, add_device_argument, add_progress_argument, add_scale_argument
from benchmarks.errors import OutputExistsError, check_seed


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--data", type=Path, required=True, help="dataset folder (from `generate`)")
    p.add_argument(
        "--method",
        required=True,
        help="method name (see `msvdd-bench methods`), or module:Class for a detector of your own",
    )
    p.add_argument("--out", type=Path, required=True, help="model folder to write")
    p.add_argument(
        "--train-seed",
        type=int,
        default=0,
        help="training seed (initial weights, batches), not the dataset's",
    )
    add_scale_argument(p, None, "training budget", "default: the dataset preset's")
    add_device_argument(p)
    add_progress_argument(p)


def _run(args: argparse.Namespace) -> int:
    from benchmarks import methods
    from benchmarks.dataset import open_dataset
    from benchmarks.pipeline import train_method
    from benchmarks.resume import code_digest, record_training, training_key

    progress = not args.no_progress
    methods.spec(args.method)
    seed = check_seed(args.train_seed, "--train-seed")
    code = code_digest(args.method)  # taken before training, as `run` does: the code this process loaded
    if args.out.exists() and any(args.out.iterdir()):
        raise OutputExistsError(f"model folder exists and is not empty: {args.out}")
    dataset = open_dataset(args.data, progress=progress)
    scale = args.scale or dataset.preset.method_scale
    model = train_method(
        dataset,
        args.method,
        seed,
        scale,
        args.out,
        device=args.device,
        progress=progress,
    )
    key = training_key(args.method, seed, scale, args.device, dataset.fingerprint, code)
    record_training(model.path, key, model.train_seconds)
    print(
        f"trained {args.method} (seed {args.train_seed}, scale {scale}) in {model.train_seconds:.1f} s; "
        f"threshold {model.detector.threshold_:.6g}; saved to {model.path}"
    )
    return 0


COMMAND = Command(
    name="train",
    help="fit one method on a dataset's nominal training windows and save it",
    add_arguments=_add_arguments,
    run=_run,
    example=(
        "msvdd-bench train --data runs/demo/dataset --method msvdd --out runs/m/msvdd-s1 --train-seed 1\n"
        "msvdd-bench train --data runs/demo/dataset --method iforest-early --out runs/models/iforest"
    ),
)
