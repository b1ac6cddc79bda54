"""`msvdd-bench evaluate`: score saved models on a dataset's test windows and write the report."""

from __future__ import annotations

import argparse
import datetime
import os
import shutil
import sys
import tempfile
from pathlib import Path

from benchmarks.command import Command, add_progress_argument
from benchmarks.errors import OutputExistsError


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--data", type=Path, required=True, help="dataset folder (from `generate`)")
    p.add_argument("--model", type=Path, nargs="+", required=True, help="model folder(s) (from `train`)")
    p.add_argument("--out", type=Path, required=True, help="run folder to create (must not exist)")
    p.add_argument(
        "--dev",
        type=Path,
        default=None,
        help="the dev dataset (same preset, another seed) the models' choices were made on; recorded",
    )
    add_progress_argument(p)


def _run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from benchmarks import methods
    from benchmarks.dataset import check_dev, open_dataset
    from benchmarks.pipeline import TrainedModel, score_and_measure, test_windows
    from benchmarks.provenance import code_version
    from benchmarks.report import RunInfo, write_report
    from benchmarks.resume import recorded_train_seconds
    from benchmarks.runner import machine_description, mean_train_seconds

    progress = not args.no_progress
    if args.out.exists():
        raise OutputExistsError(f"run folder exists already: {args.out}")
    dataset = open_dataset(args.data, progress=progress)
    dev = check_dev(open_dataset(args.dev, verify=False), dataset) if args.dev is not None else ""
    models: list[TrainedModel] = []
    for folder in tqdm(args.model, desc="loading models", unit="model", disable=not progress):
        name, detector = methods.load_detector(folder)
        run_index = sum(1 for m in models if m.method == name)  # the "seed" column counts runs of a method
        seconds = recorded_train_seconds(Path(folder))  # written by `train` and `run`; NaN if absent
        fit = float("nan") if seconds is None else seconds
        models.append(TrainedModel(name, run_index, detector, Path(folder), fit))
    test = test_windows(dataset, progress=progress)
    scores, per_method, rows = score_and_measure(dataset, models, test=test, progress=progress)
    info = RunInfo(
        preset=str(dataset.preset.name),
        dataset_seed=dataset.seed,
        dataset=str(args.data),
        command="msvdd-bench " + " ".join(sys.argv[1:]),
        machine=machine_description(),
        date=datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d"),
        train_seconds=mean_train_seconds(models),
        dev=dev,
        dataset_fingerprint=dataset.fingerprint,
        code_version=code_version(),
    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{args.out.name}.partial-", dir=args.out.parent))
    try:
        if progress:
            print("writing the report (bootstrap intervals, ROC figures)", file=sys.stderr, flush=True)
        write_report(tmp, info, rows, scores, per_method, dataset.fault_severities())
        os.replace(tmp, args.out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    print((args.out / "results.md").read_text())
    return 0


COMMAND = Command(
    name="evaluate",
    help="score saved models on the test windows; write results.json, scores.csv, results.md, ROC figures",
    add_arguments=_add_arguments,
    run=_run,
    example=(
        "msvdd-bench evaluate --data runs/demo/dataset --model runs/demo/models/msvdd-seed0 "
        "--out runs/demo-eval"
    ),
)
