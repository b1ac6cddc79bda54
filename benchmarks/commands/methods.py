"""`msvdd-bench methods`: every registered method with its family, modality and row in the paper."""

from __future__ import annotations

import argparse
import json
from typing import Any

from benchmarks.command import Command


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--family", default=None, help="only the methods of this family (msvdd, deep, ...)")
    p.add_argument("--json", action="store_true", help="print a JSON list instead of a table")


def _run(args: argparse.Namespace) -> int:
    from benchmarks import methods

    entries: list[dict[str, Any]] = [
        {
            "name": spec.name,
            "family": spec.family,
            "modality": spec.modality,
            "paper": spec.paper_rows(),
            "description": spec.description,
            "config": spec.config,
        }
        for spec in map(methods.spec, methods.names(args.family))  # specs only: nothing is built
    ]
    if args.json:
        print(json.dumps(entries, indent=2))
        return 0
    columns = ("name", "family", "modality")
    widths = {k: max(len(k), *(len(e[k]) for e in entries)) for k in columns}
    print("  ".join(f"{k:<{widths[k]}}" for k in columns) + "  paper row\n    description")
    for e in entries:
        row = "  ".join(f"{e[k]:<{widths[k]}}" for k in columns)
        print(f"{row}  {'; '.join(e['paper']) or '-'}\n    {e['description']}")
    print("Groups for `run --methods`: table1, ablations, all; or module:Class for a detector of your own.")
    return 0


COMMAND = Command(
    name="methods",
    help="list every method: name, family, modality, its row in the paper's tables, description",
    add_arguments=_add_arguments,
    run=_run,
    description=(
        "List every registered method (nothing is built or trained): its name for --method and --methods, "
        "its family, the sensors it reads, where it appears in the paper's tables (as results.md shows "
        "it), a one-line description and (--json) its configuration."
    ),
    example="msvdd-bench methods\nmsvdd-bench methods --family msvdd --json",
)
