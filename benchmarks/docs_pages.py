"""The generated parts of the documentation: `docs/results.md`, the README's headline table, the method
list of `docs/detectors.md` and the severity curves of `docs/sweeps.md` (`msvdd-bench docs`, `make docs`).

Every figure comes from a results file (`results.json` of `msvdd-bench run` or `evaluate`, the JSON of
`msvdd-bench perf`) and is formatted by the report's code (`benchmarks.report`); the method list comes from
the methods' descriptors (`benchmarks.methods.spec.MethodSpec`). A generated block inside a hand-written page
sits between `<!-- NAME:begin -->` and `<!-- NAME:end -->` and is replaced whole; the text around it is kept.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from benchmarks import methods
from benchmarks.errors import InputNotFoundError, UserError
from benchmarks.methods.spec import PAPER_TABLES
from benchmarks.report import (
    AUC_COLUMNS,
    family_table,
    fit_time_table,
    method_table,
    naive_verdict,
    paper_table,
    provenance_lines,
    ranking_note,
    result_tables,
)
from benchmarks.results_file import RunResults
from benchmarks.sweeps.report import AUC_TITLES, auc_table, reported_keys
from benchmarks.sweeps.run import KIND_KEYS, SweepResult
from msvdd.atomic import write_text_atomic

GENERATED_NOTE = "<!-- Written by `msvdd-bench docs` (`make docs`) from results files; do not edit. -->"
"""The first line of the results page and of the README's block."""
METHODS_NOTE = "<!-- Written by `msvdd-bench docs` from the methods' descriptors; do not edit. -->"
"""The first line of the method list."""
RESULTS_BLOCK = "results"
"""Name of the README's headline block."""
METHODS_BLOCK = "methods"
"""Name of the method list's block in docs/detectors.md."""
SWEEP_BLOCK = "severity"
"""Name of the severity curves' block in docs/sweeps.md."""


@dataclass(frozen=True)
class PerfResults:
    """The JSON of `msvdd-bench perf`, read back."""

    path: Path
    """The JSON file."""
    command: str
    """The command that wrote it (empty: not recorded)."""
    code_version: str
    """The code that measured it (empty: not recorded)."""
    machine: str
    """Platform, processor and core count."""
    quick: bool
    """Whether it was a `--quick` run (tiny workloads: the figures mean nothing)."""
    figures: dict[str, float]
    """Figure name -> value."""
    descriptions: dict[str, str]
    """Figure name -> what it measures (empty where not recorded)."""


_PERF_META: tuple[str, ...] = ("machine", "quick", "command", "code_version", "descriptions", "ratios")
"""The keys of a perf JSON that are not figures."""


def read_perf(path: Path) -> PerfResults:
    """The perf JSON at `path`; InputNotFoundError or UserError (naming the file) when unreadable."""
    if not path.is_file():
        raise InputNotFoundError(f"{path} does not exist (write it with `msvdd-bench perf --json {path}`)")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        machine = doc.get("machine", {})
        figures = {k: float(v) for k, v in doc.items() if k not in _PERF_META}
    except (ValueError, TypeError, AttributeError) as exc:
        raise UserError(f"{path} is not the JSON of `msvdd-bench perf` ({exc})") from exc
    return PerfResults(
        path=path,
        command=str(doc.get("command") or ""),
        code_version=str(doc.get("code_version") or ""),
        machine=", ".join(f"{k} {v}" for k, v in machine.items() if v not in ("", None))
        if isinstance(machine, dict)
        else "",
        quick=bool(doc.get("quick", False)),
        figures=figures,
        descriptions={str(k): str(v) for k, v in doc.get("descriptions", {}).items()},
    )


def run_title(run: RunResults) -> str:
    """A run's heading: its preset and dataset seed, and what it holds."""
    names = list(run.per_method)
    ablations = [m for t in PAPER_TABLES[1:] for m, _ in paper_table(t, names) if m != "msvdd"]
    what = "ablations" if len(ablations) * 2 >= len(names) else "benchmark"
    return f"Preset `{run.info.preset}`, dataset seed {run.info.dataset_seed}: {what} ({len(names)} methods)"


def _run_section(run: RunResults, path_shown: str) -> list[str]:
    """One run's section of docs/results.md."""
    return [
        f"## {run_title(run)}",
        "",
        f"- Results file: `{path_shown}`",
        *provenance_lines(run.info, run.per_method, run.intervals),
        "",
        *result_tables(run.per_method, run.intervals, level=3),
        "### Fit time",
        "",
        *fit_time_table(run.info.train_seconds),
        "",
    ]


def _value(value: float) -> str:
    """A speed figure as `msvdd-bench perf` prints it."""
    return f"{value:.4g}" if math.isfinite(value) else "n/a"


def _perf_section(perf: PerfResults, path_shown: str) -> list[str]:
    """The speed section of docs/results.md."""
    lines = [
        "## Speed (`msvdd-bench perf`)",
        "",
        f"- Results file: `{path_shown}`",
        f"- Command: `{perf.command or 'not recorded'}`; code: {perf.code_version or 'not recorded'}",
        f"- Machine: {perf.machine or 'not recorded'}",
    ]
    if perf.quick:
        lines.append("- **A `--quick` run: tiny workloads, so these figures say nothing about speed.**")
    lines += ["", "| Figure | Value | Meaning |", "|---|---|---|"]
    lines += [f"| `{k}` | {_value(v)} | {perf.descriptions.get(k, '')} |" for k, v in perf.figures.items()]
    return [*lines, ""]


def results_page(
    runs: Sequence[RunResults], perf: PerfResults | None, shown: dict[Path, str] | None = None
) -> str:
    """docs/results.md: every run's tables with their provenance, then the speed figures.

    `shown` maps a results file to the path the page names it by (default: the path as given)."""
    names = shown or {}
    out = [
        GENERATED_NOTE,
        "",
        "# Results",
        "",
        "Every figure on this page is read from the results files named in each section, written by the",
        "commands they name; `msvdd-bench docs` (`make docs`) formats them with the report's code. How to",
        "read the intervals and paired differences: [metrics and protocol](metrics.md).",
        "",
    ]
    for run in runs:
        out += _run_section(run, names.get(run.path, str(run.path)))
    if perf is not None:
        out += _perf_section(perf, names.get(perf.path, str(perf.path)))
    if not runs and perf is None:
        out += ["No results file was given.", ""]
    return "\n".join(out).rstrip("\n") + "\n"


def subcommand(command: str) -> str:
    """The program and subcommand of a command line (`msvdd-bench run`): what the README names, without the
    paths of one machine's folders, which docs/results.md gives with the whole command."""
    return " ".join(command.split()[:2]) or "not recorded"


def headline_block(run: RunResults) -> str:
    """The README's headline table: the comparison, reference and naive methods' AUCs with their intervals
    and paired differences, the ranking note as its first line and the naive verdict under it."""
    names = list(run.per_method)
    rows = (*paper_table("Table I", names), *family_table("reference", names), *family_table("naive", names))
    seeds = max(len(v) for v in run.per_method.values())
    trained = "one training seed" if seeds == 1 else f"{seeds} training seeds"
    return "\n".join(
        [
            GENERATED_NOTE,
            f"Preset `{run.info.preset}`, dataset seed {run.info.dataset_seed}, {trained} per method, "
            f"written by `{subcommand(run.info.command)}`; its whole command, code version, machine, dataset "
            "fingerprints and every table: [docs/results.md](docs/results.md).",
            "",
            ranking_note(run.intervals),
            "",
            *method_table(rows, run.per_method, AUC_COLUMNS, run.intervals),
            "",
            naive_verdict(run.per_method, run.intervals),
        ]
    )


def methods_block() -> str:
    """docs/detectors.md's method list: every registered method's descriptor."""
    lines = [
        METHODS_NOTE,
        "| Method | Family | Reads | Paper rows | What it is | Configuration |",
        "|---|---|---|---|---|---|",
    ]
    for name in methods.names():
        spec = methods.spec(name)
        paper = "; ".join(spec.paper_rows()) or "-"
        config = f"`{spec.config}`" if spec.config else "-"
        lines.append(
            f"| `{name}` | {spec.family} | {spec.modality} | {paper} | {spec.description} | {config} |"
        )
    return "\n".join(lines)


def sweep_block(sweep: SweepResult, shown: str) -> str:
    """docs/sweeps.md's severity curves: per fault kind, the AUC of each method (and of the oracle, where the
    sweep ran it) at each point, from a finished sweep folder."""
    spec = sweep.spec
    overrides = ", ".join(f"{k} = {v!r}" for k, v in spec.overrides) or "none"
    lines = [
        GENERATED_NOTE,
        f"Written by `{sweep.command}` (base preset `{spec.base}`, overrides: {overrides}; dataset seeds "
        f"{', '.join(map(str, spec.seeds))}; {sweep.machine}); the sweep folder `{shown}` has the figures. "
        "Cells: AUC (%) of that kind's windows against the normal ones, with its 95 % episode-cluster "
        "interval.",
    ]
    for key in reported_keys(sweep):
        if key in KIND_KEYS:
            lines += ["", f"**{AUC_TITLES[key]}**", "", *auc_table(sweep, key)]
    return "\n".join(lines)


def replace_block(text: str, name: str, block: str, where: str) -> str:
    """`text` with what lies between `<!-- name:begin -->` and `<!-- name:end -->` replaced by `block`.

    Raises:
        UserError: the markers are missing, repeated or out of order (the message names `where`).
    """
    begin, end = f"<!-- {name}:begin -->", f"<!-- {name}:end -->"
    if text.count(begin) != 1 or text.count(end) != 1 or text.index(begin) > text.index(end):
        raise UserError(f"{where} needs one {begin} line and one {end} line after it")
    head, rest = text.split(begin, 1)
    _, tail = rest.split(end, 1)
    return f"{head}{begin}\n{block}\n{end}{tail}"


@dataclass(frozen=True)
class DocsTargets:
    """Where `write_docs` writes."""

    results: Path
    """docs/results.md (written whole)."""
    readme: Path | None
    """README.md, whose results block gets the first run's headline table (None: left alone)."""
    detectors: Path | None
    """docs/detectors.md, whose methods block gets the method list (None: left alone)."""
    sweeps: Path | None = None
    """docs/sweeps.md, whose severity block gets a sweep's curves per fault kind (None: left alone)."""


def render(
    runs: Sequence[RunResults],
    perf: PerfResults | None,
    targets: DocsTargets,
    root: Path | None = None,
    sweep: SweepResult | None = None,
) -> dict[Path, str]:
    """Every target's new text (files not given in `targets` are left out; docs/sweeps.md only with a
    `sweep`). Paths in the pages are shown relative to `root` when they lie under it."""

    def shown(path: Path) -> str:
        if root is not None and path.resolve().is_relative_to(root.resolve()):
            return str(path.resolve().relative_to(root.resolve()))
        return str(path)

    files = [r.path for r in runs] + ([perf.path] if perf is not None else [])
    out = {targets.results: results_page(runs, perf, {p: shown(p) for p in files})}
    if targets.readme is not None and runs:
        text = targets.readme.read_text(encoding="utf-8")
        out[targets.readme] = replace_block(text, RESULTS_BLOCK, headline_block(runs[0]), str(targets.readme))
    if targets.detectors is not None:
        text = targets.detectors.read_text(encoding="utf-8")
        out[targets.detectors] = replace_block(text, METHODS_BLOCK, methods_block(), str(targets.detectors))
    if targets.sweeps is not None and sweep is not None:
        text = targets.sweeps.read_text(encoding="utf-8")
        block = sweep_block(sweep, shown(sweep.out))
        out[targets.sweeps] = replace_block(text, SWEEP_BLOCK, block, str(targets.sweeps))
    return out


def changed(pages: dict[Path, str]) -> list[Path]:
    """The pages whose file does not hold that text yet."""
    return [p for p, text in pages.items() if not p.is_file() or p.read_text(encoding="utf-8") != text]


def write_pages(pages: dict[Path, str]) -> list[Path]:
    """Write the pages that changed (each through a temporary file renamed into place); the written paths."""
    written = changed(pages)
    for path in written:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(path, pages[path])
    return written
