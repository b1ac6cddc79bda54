"""`msvdd-bench terms`: the fusion ablation of the frame-density references (see `benchmarks.terms`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from benchmarks.command import Command, add_progress_argument


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "models",
        type=Path,
        nargs="+",
        metavar="MODEL",
        help="model folder(s) of a frame-density method (context-net-frames), one per training seed",
    )
    p.add_argument("--data", type=Path, required=True, help="dataset folder whose test split is scored")
    p.add_argument("--json", type=Path, default=None, help="also write the report to this JSON file")
    p.add_argument("--md", type=Path, default=None, help="also write the printed markdown to this file")
    p.add_argument("--verify", action="store_true", help="check every dataset file's sha256 first")
    add_progress_argument(p)


def _run(args: argparse.Namespace) -> int:
    from benchmarks.terms import modality_terms, terms_json, terms_markdown
    from msvdd.atomic import write_text_atomic

    report = modality_terms(args.models, args.data, verify=args.verify, progress=not args.no_progress)
    markdown = terms_markdown(report)
    if args.json is not None:
        write_text_atomic(args.json, terms_json(report))
    if args.md is not None:
        write_text_atomic(args.md, markdown)
    print(markdown, end="")
    return 0


COMMAND = Command(
    name="terms",
    help="fusion ablation of a frame-density reference: audio term alone, IMU term alone, their sum",
    add_arguments=_add_arguments,
    run=_run,
    description=(
        "Score a dataset's test split with saved models of one frame-density reference (one per training "
        "seed) and report, over all anomalies, per kind and per sub-kind, the seed-mean AUC of the log-mel "
        "term alone, of the IMU term alone and of their sum (the model's score), each with its "
        "episode-cluster bootstrap interval, and the paired differences sum - term. Each term is fitted on "
        "its own modality only, so a term alone is that reference's single-modality detector: the fusion "
        "ablation without training anything. Prints markdown; --md also writes it to a file, --json as JSON."
    ),
    example=(
        "msvdd-bench terms runs/paper/models/context-net-frames-seed0 "
        "runs/paper/models/context-net-frames-seed1 --data runs/paper-eval"
    ),
)
