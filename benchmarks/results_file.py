"""A run's `results.json` read back into what its report was written from (`benchmarks.report`): the run's
`RunInfo`, every method's per-seed `MethodMetrics` and the run's `RunIntervals`.

`benchmarks.report.markdown` of what `read_results` returns is the run's own `results.md`, so every page
written from a results file (`msvdd-bench docs`) formats its numbers with the report's code.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from benchmarks.errors import InputNotFoundError, UserError
from benchmarks.metrics import MethodMetrics
from benchmarks.report import MethodIntervals, NaiveComparison, RunInfo, RunIntervals
from benchmarks.uncertainty import Interval

RESULTS_FILE = "results.json"
"""The file `msvdd-bench run` and `evaluate` write into a run folder."""


class ResultsFileError(UserError):
    """A file that is not a `results.json` of this code (the message names the file and what is wrong)."""


@dataclass(frozen=True)
class RunResults:
    """One run's results file, read back."""

    path: Path
    """The results file."""
    info: RunInfo
    """Where the numbers come from: preset, seeds, command, machine, code, datasets, fit times."""
    per_method: dict[str, list[MethodMetrics]]
    """Every method's metrics, one entry per training seed, in the run's order."""
    intervals: RunIntervals | None
    """The episode-cluster intervals (None: the run wrote none)."""


def results_path(path: Path) -> Path:
    """`path` itself if it is a file, else the `results.json` in the run folder `path`."""
    return path if path.is_file() else path / RESULTS_FILE


def _number(value: Any) -> float:
    """A JSON number, or NaN for null (the report writes NaN as null)."""
    return math.nan if value is None else float(value)


def _interval(doc: dict[str, Any]) -> Interval:
    return Interval(_number(doc.get("value")), _number(doc.get("low")), _number(doc.get("high")))


def _metrics(doc: dict[str, Any]) -> MethodMetrics:
    """One seed's `MethodMetrics` from its `to_dict`."""
    kwargs: dict[str, Any] = {}
    for f in fields(MethodMetrics):
        if f.name not in doc:
            continue
        value = doc[f.name]
        if f.name == "auc_by_sub_kind":
            kwargs[f.name] = {k: _number(v) for k, v in value.items()}
        elif f.type in ("int", int):
            kwargs[f.name] = int(value)
        else:
            kwargs[f.name] = _number(value)
    return MethodMetrics(**kwargs)


def _intervals(doc: dict[str, Any]) -> RunIntervals | None:
    """The run's intervals from `uncertainty`, each method's `auc_ci95` and `auc_diff_vs_reference`."""
    meta = doc.get("uncertainty")
    if meta is None:
        return None
    by_method: dict[str, MethodIntervals] = {}
    for name, entry in doc["methods"].items():
        if "auc_ci95" not in entry:
            continue
        by_method[name] = MethodIntervals(
            auc={k: _interval(v) for k, v in entry["auc_ci95"].items()},
            vs_reference={k: _interval(v) for k, v in entry.get("auc_diff_vs_reference", {}).items()},
            reference_seeds=tuple(entry.get("auc_diff_reference_seeds", ())),
        )
    pair = doc.get("naive_vs_best")
    return RunIntervals(
        methods=by_method,
        reference=meta["reference"],
        normal_episodes=int(meta["normal_episodes"]),
        anomalous_episodes=int(meta["anomalous_episodes"]),
        replicates=int(meta["replicates"]),
        seed=int(meta["seed"]),
        naive_vs_best=None
        if pair is None
        else NaiveComparison(pair["naive"], pair["best"], _interval(pair["difference"])),
    )


def read_results(path: Path) -> RunResults:
    """The results file of the run folder (or file) `path`.

    Raises:
        InputNotFoundError: no such file.
        ResultsFileError: not JSON, or a field the report writes is missing or malformed.
    """
    file = results_path(Path(path))
    if not file.is_file():
        raise InputNotFoundError(f"{file} does not exist (a run folder of `msvdd-bench run` or `evaluate`)")
    try:
        doc = json.loads(file.read_text(encoding="utf-8"))
        per_method = {
            name: [_metrics(seed) for seed in entry["per_seed"]] for name, entry in doc["methods"].items()
        }
        if not per_method:
            raise ResultsFileError(f"{file} holds no method")
        train_seconds = {
            name: float(entry["train_seconds"])
            for name, entry in doc["methods"].items()
            if entry.get("train_seconds") is not None
        }
        info = RunInfo(
            preset=str(doc["preset"]),
            dataset_seed=int(doc["seed"]),
            dataset=str(doc["dataset"]),
            command=str(doc["command"]),
            machine=str(doc["machine"]),
            date=str(doc["date"]),
            train_seconds=train_seconds,
            dev=str(doc.get("dev") or ""),
            dataset_fingerprint=str(doc.get("dataset_sha256") or ""),
            code_version=str(doc.get("code_version") or ""),
        )
        return RunResults(file, info, per_method, _intervals(doc))
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        if isinstance(exc, ResultsFileError):
            raise
        raise ResultsFileError(
            f"{file} is not a results file of this code ({type(exc).__name__}: {exc}); write it again with "
            "`msvdd-bench run` or `evaluate`"
        ) from exc
