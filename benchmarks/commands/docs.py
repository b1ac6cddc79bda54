"""`msvdd-bench docs`: write docs/results.md, the README's headline table and the method list of
docs/detectors.md from results files (`benchmarks.docs_pages`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from benchmarks.command import Command


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "runs",
        type=Path,
        nargs="*",
        metavar="RUN",
        help="run folders (or their results.json) of `msvdd-bench run` or `evaluate`; the first one gives "
        "the README's headline table",
    )
    p.add_argument("--perf", type=Path, default=None, help="the JSON of `msvdd-bench perf` to add")
    p.add_argument(
        "--sweep",
        type=Path,
        default=None,
        help="a finished `msvdd-bench sweep` folder (the severity spec) whose curves per fault kind go into "
        "docs/sweeps.md",
    )
    p.add_argument(
        "--docs", type=Path, default=Path("docs"), help="the docs folder (results.md, detectors.md)"
    )
    p.add_argument(
        "--readme", type=Path, default=Path("README.md"), help="the README whose results block is replaced"
    )
    p.add_argument(
        "--check",
        action="store_true",
        help="write nothing; exit 1 if a page would change (the pages are not those of these files)",
    )


def _run(args: argparse.Namespace) -> int:
    from benchmarks.docs_pages import DocsTargets, changed, read_perf, render, write_pages
    from benchmarks.results_file import read_results
    from benchmarks.sweeps.run import read_sweep

    runs = [read_results(path) for path in args.runs]
    perf = read_perf(args.perf) if args.perf is not None else None
    sweep = read_sweep(args.sweep) if args.sweep is not None else None
    detectors: Path = args.docs / "detectors.md"
    targets = DocsTargets(
        results=args.docs / "results.md",
        readme=args.readme if args.readme.is_file() else None,
        detectors=detectors if detectors.is_file() else None,
        sweeps=args.docs / "sweeps.md" if sweep is not None else None,
    )
    pages = render(runs, perf, targets, root=Path.cwd(), sweep=sweep)
    if args.check:
        stale = changed(pages)
        for path in stale:
            print(f"{path} is not what `msvdd-bench docs` writes from these results files")
        return 1 if stale else 0
    written = write_pages(pages)
    for path in pages:
        print(f"{'wrote' if path in written else 'unchanged'} {path}")
    return 0


COMMAND = Command(
    name="docs",
    help="write docs/results.md, the README's headline table and the method list from results files",
    add_arguments=_add_arguments,
    run=_run,
    description=(
        "Write the generated parts of the documentation: docs/results.md (every run's tables with their "
        "intervals, dataset fingerprints, command, code version and machine, then the speed figures), the "
        "README's headline table (between its <!-- results:begin --> and <!-- results:end --> lines, from "
        "the first run) and the method list of docs/detectors.md (between <!-- methods:begin --> and "
        "<!-- methods:end -->, from the methods' descriptors). Every figure comes from the files given."
    ),
    example=(
        "msvdd-bench docs runs/paper runs/paper-ablations --perf runs/perf.json\n"
        "msvdd-bench docs runs/demo --check"
    ),
)
