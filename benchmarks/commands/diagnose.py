"""`msvdd-bench diagnose`: a rerunnable diagnosis of a trained M-SVDD model (see `benchmarks.diagnose`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from benchmarks.command import Command, add_progress_argument


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("model", type=Path, help="M-SVDD model folder (from `train` or `run`)")
    p.add_argument("--data", type=Path, required=True, help="dataset folder (from `generate`)")
    p.add_argument(
        "--out", type=Path, default=None, help="folder for diagnosis.json and .md (default: MODEL/diagnosis)"
    )
    p.add_argument(
        "--max-windows", type=int, default=3000, help="windows read per split (seeded, stratified subsample)"
    )
    p.add_argument("--subsample-seed", type=int, default=0, help="seed of the subsampling of windows")
    p.add_argument("--verify", action="store_true", help="check every dataset file's sha256 first")
    add_progress_argument(p)


def _run(args: argparse.Namespace) -> int:
    from benchmarks.diagnose import check_output, diagnose, diagnosis_markdown, write_diagnosis

    out = args.out if args.out is not None else args.model / "diagnosis"
    check_output(out)  # before the work, not after it
    result = diagnose(
        args.model,
        args.data,
        args.max_windows,
        args.subsample_seed,
        verify=args.verify,
        progress=not args.no_progress,
    )
    write_diagnosis(result, out)
    print(diagnosis_markdown(result))
    return 0


COMMAND = Command(
    name="diagnose",
    help="diagnose a trained M-SVDD model: R history, Sigma spectrum, z spread, score terms, what z encodes",
    add_arguments=_add_arguments,
    run=_run,
    description=(
        "Diagnose a trained M-SVDD model on a dataset: the radius R over training (collapse?), the "
        "eigen-spectrum of Sigma, the spread of the embeddings z, the D and Rec terms of the score per test "
        "kind and sub-kind (with their AUCs), and how much of z window loudness and motion explain. Writes "
        "diagnosis.json and diagnosis.md into --out and prints the markdown."
    ),
    example="msvdd-bench diagnose runs/demo/models/msvdd-seed0 --data runs/demo/dataset",
)
