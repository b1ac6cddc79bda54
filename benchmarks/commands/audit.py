"""`msvdd-bench audit`: check a dataset for shortcuts and write audit.json and audit.md."""

from __future__ import annotations

import argparse
from pathlib import Path

from benchmarks.command import Command, add_progress_argument


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("dataset", type=Path, help="dataset folder written by `msvdd-bench generate`")
    p.add_argument(
        "--out", type=Path, default=None, help="folder for audit.json and audit.md (default: DATASET-audit)"
    )
    p.add_argument(
        "--reuse",
        action="store_true",
        help="print the audit stored in --out instead of running it again if it is of this dataset (same "
        "fingerprint) with this code and these package versions",
    )
    add_progress_argument(p)


def _run(args: argparse.Namespace) -> int:
    from benchmarks.audit import markdown, run_audit, stored_audit, write

    dataset = Path(args.dataset)
    out = args.out if args.out is not None else dataset.parent / f"{dataset.name}-audit"
    stored = stored_audit(dataset, out) if args.reuse else None
    if stored is not None:
        print(markdown(stored))
        print(f"reused {out / 'audit.json'}: same dataset, code and package versions (key {stored.key[:16]})")
        return 1 if stored.failed else 0
    result = run_audit(dataset, progress=not args.no_progress)
    json_path, md_path = write(result, out)
    print(markdown(result))
    print(f"wrote {json_path} and {md_path}")
    return 1 if result.failed else 0


COMMAND = Command(
    name="audit",
    help="check a dataset for shortcuts (behaviour, naive levels, deleted sound, leaks, clipping)",
    description=(
        "Score the dataset's test windows with shortcut probes and a reference detector and compare each "
        "figure with its limit. Exit status: 0 every probe passes, 1 a probe is over its limit, 2 bad input."
    ),
    example="msvdd-bench audit runs/paper-eval --out runs/paper-eval-audit --reuse",
    add_arguments=_add_arguments,
    run=_run,
)
