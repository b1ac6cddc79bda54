"""`msvdd-bench compare`: the regression gate between a baseline run and a candidate run on one dataset."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from benchmarks.command import Command
from benchmarks.regression import (  # numpy only: light enough for building the parser
    DEFAULT_GATE,
    DEFAULT_MAX_DROP,
    METRICS,
    GateConfig,
    compare_runs,
    markdown_table,
    pair_methods,
    read_run,
    to_json,
)

DESCRIPTION = (
    "Pair two run folders window by window (both scored on the same dataset: equal dataset fingerprints) and "
    "give every compared method's AUC, pAUC, collision and fault AUC differences (candidate - baseline) with "
    "their paired episode-cluster bootstrap 95 % intervals. Exit 0: no regression; 1: a gated metric is more "
    "than --max-drop points down AND the interval of its difference lies wholly below zero; 2: bad input "
    "(a missing or malformed run, runs on different datasets, an unknown method)."
)


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("baseline", type=Path, help="baseline run folder (results.json, scores.csv)")
    p.add_argument("candidate", type=Path, help="candidate run folder, scored on the same dataset")
    p.add_argument(
        "--method",
        nargs="+",
        default=None,
        help="the candidate's method(s) to compare, by name or module:Class (default: every method both "
        "runs have)",
    )
    p.add_argument(
        "--baseline-method",
        default=None,
        help="the baseline's method to compare one --method with, when its name differs",
    )
    p.add_argument(
        "--max-drop",
        type=float,
        default=DEFAULT_MAX_DROP,
        help="tolerated drop of a gated metric, in points (percent of AUC)",
    )
    p.add_argument(
        "--gate",
        nargs="+",
        default=list(DEFAULT_GATE),
        choices=list(METRICS),
        help="metrics that decide the exit code (all are reported)",
    )
    p.add_argument("--json", type=Path, default=None, help="also write the comparison to this JSON file")


def _run(args: argparse.Namespace) -> int:
    config = GateConfig(max_drop=args.max_drop, gate=tuple(dict.fromkeys(args.gate)))
    baseline, candidate = read_run(args.baseline), read_run(args.candidate)
    pairs = pair_methods(baseline, candidate, args.method, args.baseline_method)
    comparison = compare_runs(baseline, candidate, pairs, config)
    print(markdown_table(comparison))
    if args.json is not None:
        from msvdd.atomic import write_text_atomic

        write_text_atomic(args.json, json.dumps(to_json(comparison), indent=2) + "\n")
    return comparison.exit_code


COMMAND = Command(
    name="compare",
    help="regression gate: paired AUC/pAUC differences of two runs on one dataset; exit 1 on a regression",
    add_arguments=_add_arguments,
    run=_run,
    description=DESCRIPTION,
    example="msvdd-bench compare runs/baseline runs/candidate --json runs/compare.json",
)
