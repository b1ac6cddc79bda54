"""`msvdd-bench robustness`: AUC of saved models on test windows cut from perturbed episode streams."""

from __future__ import annotations

import argparse
import contextlib
import datetime
import sys
from pathlib import Path

from benchmarks.command import Command, add_executor_arguments, add_progress_argument

KIND_NAMES = ("offset", "drift", "jitter", "imu-drop", "audio-gap", "audio-missing", "imu-missing")
"""`benchmarks.robustness.perturb.KINDS`, kept here so that building the parser imports no numpy (a test
checks that they agree)."""

DESCRIPTION = (
    "Perturb every test episode's streams at scoring time, cut the test windows again at their starts, and "
    "report per method, perturbation and severity the AUC, its episode-cluster bootstrap 95 % interval, and "
    "AUC(perturbed) / AUC(clean) with a paired interval (same episode draws). Kinds and default severities: "
    "offset -200 -50 -10 10 50 200 ms (IMU delayed relative to audio); drift 100 500 2000 ppm (IMU time "
    "stretched about the episode start); jitter 0.1 0.5 2 ms rms (IMU time stamps, resampled to the grid); "
    "imu-drop 1 5 20 % (last sample held); audio-gap 10 50 200 ms per s (zeroed); audio-missing, imu-missing "
    "100 % (zeroed stream). The clean windows and each perturbation are scored as independent tasks on "
    "local worker processes or Ray (--executor); a task's draws are keyed by (seed, kind, severity, episode "
    "index) and it scores on one thread, so the results do not depend on the executor. Writes "
    "robustness.md, robustness.json and robustness.png into --out."
)


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--data", type=Path, required=True, help="dataset folder (from `generate`)")
    p.add_argument(
        "--models",
        type=Path,
        nargs="+",
        required=True,
        help="model folders (from `train`) or run folders (from `run`: every models/* folder)",
    )
    p.add_argument("--out", type=Path, required=True, help="output folder to create (must not exist)")
    p.add_argument(
        "--perturbations",
        nargs="+",
        default=list(KIND_NAMES),
        metavar="KIND[=S1,S2,...]",
        help="kinds to apply, each at its default severities or at the ones given after '='",
    )
    p.add_argument("--perturbation-seed", type=int, default=0, help="seed of the perturbations' random draws")
    add_executor_arguments(
        p,
        what="the conditions are scored (one task per perturbation and severity, and the clean windows)",
        same="the results are the same bit for bit with either and any --workers",
        shared="the dataset and model folders, at the same paths",
    )
    add_progress_argument(p)


def _run(args: argparse.Namespace) -> int:
    from benchmarks.dataset import open_dataset
    from benchmarks.errors import OutputExistsError
    from benchmarks.executor import make_executor
    from benchmarks.pipeline import test_rows
    from benchmarks.robustness.report import MARKDOWN_FILE, RunContext, write_outputs
    from benchmarks.robustness.run import (
        RobustnessConfig,
        load_models,
        model_folders,
        parse_perturbations,
        run_robustness,
    )

    progress = not args.no_progress
    if args.out.exists():
        raise OutputExistsError(
            f"--out {args.out}: the folder exists already; allowed: a path that does not exist"
        )
    config = RobustnessConfig(
        perturbations=parse_perturbations(args.perturbations), seed=args.perturbation_seed
    )
    executor = make_executor(args.executor, workers=args.workers, address=args.address)  # checks the flags
    with contextlib.closing(executor):
        folders = model_folders(args.models)
        dataset = open_dataset(args.data, progress=progress)
        models = load_models(folders, progress=progress)
        rows = test_rows(dataset)
        result = run_robustness(dataset, models, config, rows, progress=progress, executor=executor)
    context = RunContext(
        dataset=str(args.data),
        preset=str(dataset.preset.name),
        dataset_seed=dataset.seed,
        fingerprint=dataset.fingerprint,
        command="msvdd-bench " + " ".join(sys.argv[1:]),
        date=datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d"),
    )
    write_outputs(args.out, result, context)
    print((args.out / MARKDOWN_FILE).read_text())
    return 0


COMMAND = Command(
    name="robustness",
    help="AUC of saved models under audio-IMU offset, drift, jitter, IMU drops, audio gaps, a lost modality",
    add_arguments=_add_arguments,
    run=_run,
    description=DESCRIPTION,
    example=(
        "msvdd-bench robustness --data runs/demo/dataset --models runs/demo --out runs/demo-robustness\n"
        "msvdd-bench robustness --data runs/demo/dataset --models runs/demo/models/msvdd-seed0 "
        "--out runs/demo-offsets --perturbations offset=-20,-5,5,20 imu-missing --workers 4"
    ),
)
