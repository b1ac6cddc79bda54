"""Outputs of a run: `results.json`, `scores.csv`, `results.md` (tables shaped like the paper's), ROC PNGs.

Every AUC comes with its episode-cluster bootstrap 95 % interval (`benchmarks.uncertainty`), and every method
with its paired AUC difference against M-SVDD on the same episode draws.
"""

from __future__ import annotations

import csv
import itertools
import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks import methods
from benchmarks.dataset import WindowRow
from benchmarks.methods.spec import PAPER_TABLES
from benchmarks.metrics import MethodMetrics, aggregate, roc_curve
from benchmarks.pipeline import MethodScores
from benchmarks.uncertainty import (
    BOOTSTRAP_REPLICATES,
    BOOTSTRAP_SEED,
    CONFIDENCE,
    MIN_EPISODES_PER_CLASS,
    BootstrapAuc,
    Interval,
    bootstrap_mean_auc,
    episode_draws,
    excludes_zero,
    format_interval,
)
from msvdd.contract import MIN_HELD_OUT, THRESHOLD_QUANTILE

SVDD_NOTE = (
    "† The SVDD rows equal the OCSVM rows by construction: with an RBF kernel the SVDD and one-class SVM"
    " duals coincide (Tax & Duin 2004; Schölkopf et al. 2001), so `svdd-*` is fitted as the same"
    " one-class SVM as `ocsvm-*`."
)
"""Footnote under Table I whenever it has an SVDD row."""

Rows = tuple[tuple[str, str], ...]
"""A table's rows: (method, label)."""


def paper_table(table: str, available: Iterable[str] | None = None) -> Rows:
    """The rows of one of the paper's tables (`benchmarks.methods.spec.PAPER_TABLES`) from the methods'
    descriptors, in the paper's order, optionally only the `available` methods."""
    keep = None if available is None else set(available)
    found = [
        (row.position, index, name, row.label)
        for index, name in enumerate(methods.names())
        for row in methods.spec(name).paper
        if row.table == table and (keep is None or name in keep)
    ]
    return tuple((name, label) for _, _, name, label in sorted(found))


def family_table(family: str, available: Iterable[str] | None = None) -> Rows:
    """The rows of one family's methods (reference, naive), labelled by their descriptors."""
    keep = None if available is None else set(available)
    return tuple(
        (name, methods.spec(name).row_label())
        for name in methods.names(family)
        if keep is None or name in keep
    )


TOO_EASY_AUC = 0.9
"""A naive baseline at or above this AUC means the benchmark is too easy, and the report says so."""

REFERENCE_METHOD = "msvdd"
"""The method every other one is compared with (paired AUC difference), when it is in the run."""

THRESHOLD_RULE = (
    f"the {THRESHOLD_QUANTILE:.0%} quantile of its scores on the held-out nominal windows"
    f" (the dataset's `val` split), or on its training windows when `val` has fewer than {MIN_HELD_OUT}"
    " windows (`msvdd.contract.Detector`)"
)
"""The threshold rule every method follows, as the report states it."""


@dataclass(frozen=True)
class MethodIntervals:
    """One method's AUCs with their intervals, and its paired differences against the reference method."""

    auc: dict[str, Interval]
    """By key (`auc`, `auc_collision`, `auc_mechanical`, `auc_<sub-kind>`): the seed-mean AUC and interval."""
    vs_reference: dict[str, Interval] = field(default_factory=dict)
    """The same keys: this method's AUC minus the reference's, same draws (empty without the reference)."""
    reference_seeds: tuple[int, ...] = ()
    """The reference's training seeds in `vs_reference` (`paired_reference_seeds`; empty without it)."""


@dataclass(frozen=True)
class NaiveComparison:
    """The best naive baseline of a run against its best other detector, on every anomaly."""

    naive: str
    """The naive baseline (family `naive`) with the highest AUC."""
    best: str
    """The method of any other family with the highest AUC."""
    difference: Interval
    """`naive`'s AUC minus `best`'s, on the same episode draws (seed means)."""


@dataclass(frozen=True)
class RunIntervals:
    """The episode-cluster bootstrap intervals of a run."""

    methods: dict[str, MethodIntervals]
    """By method name."""
    reference: str | None
    """The method of the paired differences (None when it was not run)."""
    normal_episodes: int
    """Test episodes with normal windows (the normal clusters)."""
    anomalous_episodes: int
    """Test episodes with anomalous windows (the anomalous clusters)."""
    replicates: int
    """Bootstrap replicates."""
    seed: int
    """Seed of the episode draws."""
    naive_vs_best: NaiveComparison | None = None
    """The best naive baseline against the best other detector (None: either is missing)."""


SEVERITY_BINS: tuple[float, ...] = (0.0, 0.25, 0.5, 0.75, 1.0)
"""Edges of the fault-severity bins of the AUCs by severity: [lo, hi), the last one closed at 1."""


def severity_bins() -> list[tuple[str, float, float]]:
    """(label "lo-hi", lo, hi) of each fault-severity bin."""
    return [(f"{lo:.2f}-{hi:.2f}", lo, hi) for lo, hi in itertools.pairwise(SEVERITY_BINS)]


def severity_key(label: str, sub_kind: str = "mechanical") -> str:
    """The AUC key of one severity bin: all fault windows (`mechanical`) or one fault sub-kind's."""
    return f"auc_{sub_kind}_severity_{label}"


def _severity_subsets(
    kinds: np.ndarray, sub_kinds: np.ndarray, episodes: np.ndarray, severity: Mapping[str, float]
) -> dict[str, np.ndarray]:
    """Every normal window against the fault windows of one severity bin (all faults, then each fault
    sub-kind), for the bins that hold any; a fault window of an episode `severity` does not name is left
    out of every bin."""
    normal = kinds == "normal"
    faulty = kinds == "mechanical"
    sev = np.array([severity.get(e, math.nan) for e in episodes], dtype=np.float64)  # NaN: in no bin
    out: dict[str, np.ndarray] = {}
    for label, lo, hi in severity_bins():
        below_top = (sev <= hi) if hi == SEVERITY_BINS[-1] else (sev < hi)
        in_bin = faulty & (sev >= lo) & below_top
        if not in_bin.any():
            continue
        out[severity_key(label)] = normal | in_bin
        for sub in sorted(set(sub_kinds[in_bin])):
            out[severity_key(label, sub)] = normal | (in_bin & (sub_kinds == sub))
    return out


def paired_reference_seeds(method_seeds: Sequence[int], reference_seeds: Sequence[int]) -> tuple[int, ...]:
    """The reference's seeds a method is compared with: its own seeds when the reference was trained with
    every one of them and more (an ablation trained once against a three-seed reference is paired with the
    reference's model of the same seed, so the difference is the ablated part, not the reference's seed
    spread), else every seed of the reference."""
    own, ref = set(method_seeds), set(reference_seeds)
    return tuple(sorted(own if own < ref else ref))


def _seed_mean_auc(
    runs: Sequence[tuple[int, np.ndarray]],
    keep: np.ndarray,
    positive: np.ndarray,
    episodes: np.ndarray,
    weights: np.ndarray,
) -> BootstrapAuc:
    """`bootstrap_mean_auc` of the (seed, scores) `runs` on the windows `keep`."""
    return bootstrap_mean_auc(np.stack([s[keep] for _, s in runs]), positive, episodes[keep], weights)


def auc_intervals(
    rows: Sequence[WindowRow],
    scores: Sequence[MethodScores],
    reference: str = REFERENCE_METHOD,
    replicates: int = BOOTSTRAP_REPLICATES,
    seed: int = BOOTSTRAP_SEED,
    severity: Mapping[str, float] | None = None,
) -> RunIntervals:
    """Every method's AUCs (overall, collision, mechanical, per sub-kind; with `severity`, the fault
    episodes' severities by episode id, also per severity bin) with episode-cluster intervals.

    The clusters are the test windows' episodes. Each AUC subset (every normal window against one group of
    anomalous windows) gets one set of episode draws, applied to every seed of every method: a method's AUC
    is the mean over its seeds, in the data and inside each replicate, and its difference against
    `reference` (the reference's mean over `paired_reference_seeds`) is taken replicate by replicate
    (exactly 0 for the reference itself).
    """
    kinds = np.array([r.kind for r in rows]).astype(str)
    sub_kinds = np.array([r.sub_kind for r in rows]).astype(str)
    episodes = np.array([r.episode for r in rows]).astype(str)
    normal = kinds == "normal"
    by_method: dict[str, list[tuple[int, np.ndarray]]] = {}
    for ms in scores:
        by_method.setdefault(ms.method, []).append((ms.seed, np.asarray(ms.scores, dtype=np.float64)))
    paired: dict[str, tuple[int, ...]] = {}
    if reference in by_method:
        ref_seeds = [seed for seed, _ in by_method[reference]]
        paired = {
            m: paired_reference_seeds([seed for seed, _ in runs], ref_seeds) for m, runs in by_method.items()
        }
    subsets = {
        "auc": np.ones(kinds.size, dtype=bool),
        "auc_collision": normal | (kinds == "collision"),
        "auc_mechanical": normal | (kinds == "mechanical"),
    }
    for sub in sorted(set(sub_kinds[~normal])):
        subsets[f"auc_{sub}"] = normal | (sub_kinds == sub)
    subsets.update(_severity_subsets(kinds, sub_kinds, episodes, severity or {}))
    auc: dict[str, dict[str, Interval]] = {m: {} for m in by_method}
    diff: dict[str, dict[str, Interval]] = {m: {} for m in by_method}
    naive_vs_best: NaiveComparison | None = None
    for key, keep in subsets.items():
        positive = ~normal[keep]
        weights = episode_draws(episodes[keep], positive, replicates, seed)
        boots = {m: _seed_mean_auc(runs, keep, positive, episodes, weights) for m, runs in by_method.items()}
        ref_boots = {  # the reference with every seed is boots[reference]; only seed subsets are new
            seeds: boots[reference]
            if seeds == paired[reference]
            else _seed_mean_auc(
                [r for r in by_method[reference] if r[0] in seeds], keep, positive, episodes, weights
            )
            for seeds in set(paired.values())
        }
        for m, b in boots.items():
            auc[m][key] = b.interval()
            if m in paired:
                diff[m][key] = b.minus(ref_boots[paired[m]])
        if key == "auc":
            naive_vs_best = _naive_vs_best(boots)
    return RunIntervals(
        methods={m: MethodIntervals(auc[m], diff[m], paired.get(m, ())) for m in by_method},
        reference=reference if reference in by_method else None,
        normal_episodes=len(set(episodes[normal])),
        anomalous_episodes=len(set(episodes[~normal])),
        replicates=replicates,
        seed=seed,
        naive_vs_best=naive_vs_best,
    )


def _naive_vs_best(boots: Mapping[str, BootstrapAuc]) -> NaiveComparison | None:
    """The naive baseline with the highest AUC against the other method with the highest AUC."""
    naive = [m for m in boots if methods.spec(m).family == "naive"]
    others = [m for m in boots if m not in naive]
    if not naive or not others:
        return None

    def top(names: list[str]) -> str:
        return max(names, key=lambda m: boots[m].value if math.isfinite(boots[m].value) else -math.inf)

    low, high = top(naive), top(others)
    return NaiveComparison(low, high, boots[low].minus(boots[high]))


@dataclass(frozen=True)
class RunInfo:
    """What the report says about where its numbers come from."""

    preset: str
    """Dataset preset."""
    dataset_seed: int
    """Dataset seed."""
    dataset: str
    """Dataset folder."""
    command: str
    """The command line that produced the run."""
    machine: str
    """Machine description."""
    date: str
    """UTC date of the run."""
    train_seconds: dict[str, float]
    """Mean fit time per method, s."""
    dev: str = ""
    """The dev dataset every choice of the methods was made on (`describe_dev`); empty: none given."""
    dataset_fingerprint: str = ""
    """`benchmarks.dataset.dataset_fingerprint` of the evaluated dataset (what `compare` pairs runs by)."""
    code_version: str = ""
    """The code that made the run (`benchmarks.provenance.code_version`); empty: not recorded."""


def _fmt(mean: float, std: float, pct: bool = True, with_std: bool = True) -> str:
    if not math.isfinite(mean):
        return "n/a"
    scale = 100.0 if pct else 1.0
    text = f"{mean * scale:.1f}"
    if with_std and std > 0:
        text += f" ± {std * scale:.1f}"
    return text


def _diff_cells(intervals: RunIntervals, method: str, key: str) -> list[str]:
    """The paired-difference cell and its excludes-zero cell of one method and AUC key."""
    if method == intervals.reference:
        return ["reference", "-"]
    found = intervals.methods.get(method)
    iv = found.vs_reference.get(key) if found is not None else None
    if iv is None:
        return ["n/a", "n/a"]
    excludes = excludes_zero(iv)
    return [format_interval(iv, signed=True), "n/a" if excludes is None else ("yes" if excludes else "no")]


def _auc_cell(intervals: RunIntervals | None, method: str, key: str) -> str | None:
    """An AUC cell with its interval, or None when the run has no interval for it."""
    found = intervals.methods.get(method) if intervals is not None else None
    iv = found.auc.get(key) if found is not None else None
    return None if iv is None else format_interval(iv)


def method_table(
    rows: Rows,
    per_method: Mapping[str, Sequence[MethodMetrics]],
    columns: Sequence[tuple[str, str, bool]],
    intervals: RunIntervals | None = None,
) -> list[str]:
    """A Markdown table of the `rows` the run has: one column per (key, header, percent) of `columns`, AUCs
    with their intervals, and the paired difference against M-SVDD when the run has it (M-SVDD in bold)."""
    with_diff = intervals is not None and intervals.reference is not None
    headers = [c[1] for c in columns] + (list(_DIFF_HEADERS) if with_diff else [])
    lines = ["| Method | " + " | ".join(headers) + " |"]
    lines.append("|---|" + "---|" * len(headers))
    for method, label in rows:
        if method not in per_method:
            continue
        agg = aggregate(per_method[method])
        shown = f"**{label}**" if method == REFERENCE_METHOD else label
        cells = [
            _auc_cell(intervals, method, key) or _fmt(*agg.get(key, (math.nan, 0.0)), pct=pct)
            for key, _, pct in columns
        ]
        if with_diff:
            assert intervals is not None
            cells += _diff_cells(intervals, method, "auc")
        lines.append(f"| {shown} | " + " | ".join(cells) + " |")
    return lines


def _shown_in_tables(available: Iterable[str]) -> list[str]:
    """The methods of `available` that a fixed table of `results.md` shows (a paper table, the reference or
    the naive table); the rest get the "other methods" table."""
    names = list(available)
    shown = {m for table in PAPER_TABLES for m, _ in paper_table(table, names)}
    shown |= {m for family in ("reference", "naive") for m, _ in family_table(family, names)}
    return [m for m in names if m in shown]


_DIFF_HEADERS: tuple[str, str] = ("ΔAUC vs M-SVDD (%)", "Δ interval excludes 0")
"""Headers of the paired-difference columns every table gets when M-SVDD is in the run."""


def _difference_table(
    per_method: Mapping[str, Sequence[MethodMetrics]], intervals: RunIntervals
) -> list[str]:
    """Every method's paired AUC differences against the reference: overall, collisions, faults."""
    keys = (("auc", "ΔAUC"), ("auc_collision", "ΔAUC coll"), ("auc_mechanical", "ΔAUC mech"))
    headers = [h for _, label in keys for h in (f"{label} (%)", "excludes 0")]
    lines = ["| Method | " + " | ".join(headers) + " |", "|---|" + "---|" * len(headers)]
    for method in per_method:
        if method != intervals.reference:
            cells = [c for key, _ in keys for c in _diff_cells(intervals, method, key)]
            lines.append(f"| {method} | " + " | ".join(cells) + " |")
    return lines


MAIN_COLUMNS: tuple[tuple[str, str, bool], ...] = (
    ("recall", "Recall (%)", True),
    ("precision", "Precision (%)", True),
    ("f1", "F1 (%)", True),
    ("f1_oracle", "F1 oracle (%)", True),
    ("auc", "AUC (%)", True),
    ("auc_collision", "AUC coll (%)", True),
    ("auc_mechanical", "AUC mech (%)", True),
    ("pauc", "pAUC (%)", True),
    ("delay_mean_s", "Delay (s)", False),
)
SHORT_COLUMNS: tuple[tuple[str, str, bool], ...] = (
    ("recall", "Recall (%)", True),
    ("precision", "Precision (%)", True),
    ("f1", "F1 (%)", True),
    ("f1_oracle", "F1 oracle (%)", True),
    ("auc", "AUC (%)", True),
)
AUC_COLUMNS: tuple[tuple[str, str, bool], ...] = (
    ("auc", "AUC (%)", True),
    ("auc_collision", "AUC coll (%)", True),
    ("auc_mechanical", "AUC mech (%)", True),
)
"""Table columns: (metric key, header, shown in percent); AUC cells get their interval when the run has
one."""


def _auc_text(intervals: RunIntervals | None, method: str, value: float) -> str:
    """`method`'s overall AUC in percent, with its interval when the run has one."""
    return _auc_cell(intervals, method, "auc") or f"{100 * value:.1f}"


def naive_verdict(
    per_method: Mapping[str, Sequence[MethodMetrics]], intervals: RunIntervals | None = None
) -> str:
    """One sentence on whether the naive energy/kurtosis baselines solve the benchmark: the best of them
    against the best other detector of the run, by the interval of their paired AUC difference ("level"
    when it contains 0)."""
    found = {n: aggregate(per_method[n])["auc"][0] for n, _ in family_table("naive", per_method)}
    if not found:
        return "The naive sanity baselines were not run."
    text = ", ".join(f"{n} AUC {_auc_text(intervals, n, v)}" for n, v in found.items())
    if max(found.values()) >= TOO_EASY_AUC:
        return (
            f"WARNING: a naive baseline scores well ({text}): on this data the benchmark is too easy, "
            "since window energy or kurtosis alone finds the anomalies."
        )
    pair = intervals.naive_vs_best if intervals is not None else None
    if pair is None:
        return (
            f"The naive baselines reach {text}; no other detector of this run has an interval to compare "
            "them with, so the run does not say whether energy or kurtosis alone solves this benchmark."
        )
    best = aggregate(per_method[pair.best])["auc"][0]
    both = f"{text}; best detector {pair.best} AUC {_auc_text(intervals, pair.best, best)}"
    diff = f"{pair.naive} minus {pair.best}: {format_interval(pair.difference, signed=True)}"
    excludes = excludes_zero(pair.difference)
    if excludes is None:
        return (
            f"The naive baselines reach {text} ({both}); with this few test episodes the paired difference "
            "has no interval, so the run does not say whether energy or kurtosis alone solves this benchmark."
        )
    if not excludes:
        return (
            f"The best naive baseline is level with the best detector of this run ({both}; {diff}, an "
            "interval that contains 0): this test set does not tell window energy or kurtosis apart from "
            "the best detector."
        )
    if pair.difference.value < 0:
        return (
            f"The naive baselines stay below the best detector of this run ({both}; {diff}), so energy or "
            "kurtosis alone does not solve this benchmark."
        )
    return (
        f"WARNING: a naive baseline is ahead of every other detector of this run ({both}; {diff}): on this "
        "data window energy or kurtosis alone beats the detectors."
    )


def ranking_note(intervals: RunIntervals | None) -> str:
    """One line on whether this test set ranks the methods against M-SVDD: how many paired differences
    contain 0 (or have no interval), out of how many."""
    if intervals is None or intervals.reference is None:
        return (
            "**Ranking**: M-SVDD is not in this run, so there are no paired differences; AUCs whose "
            "intervals overlap are not a ranking."
        )
    ref = intervals.reference
    diffs = {m: mi.vs_reference.get("auc") for m, mi in intervals.methods.items() if m != ref}
    unranked = [m for m, iv in diffs.items() if iv is None or excludes_zero(iv) is not True]
    episodes = (
        f"{intervals.normal_episodes} normal and {intervals.anomalous_episodes} anomalous test episodes"
    )
    ref_auc = _auc_cell(intervals, ref, "auc") or "n/a"
    if not diffs:
        return f"**Ranking**: only M-SVDD was run ({episodes}; AUC {ref_auc}): nothing to rank."
    if unranked:
        return (
            f"**This test set cannot rank {len(unranked)} of the {len(diffs)} other methods against M-SVDD**"
            f" ({episodes}; M-SVDD's AUC {ref_auc}): their paired difference's interval contains 0 or is "
            "undefined, so only a row whose *excludes 0* says yes is ranked."
        )
    return (
        f"**Ranking**: every one of the {len(diffs)} other methods' paired difference against M-SVDD "
        f"excludes 0 on this test set ({episodes}; M-SVDD's AUC {ref_auc})."
    )


def _interval_notes(intervals: RunIntervals | None, n_seeds: int) -> list[str]:
    """The header lines that say what the cells and intervals mean."""
    if intervals is None:
        return [f"- Training seeds per method: {n_seeds} (mean ± std over seeds)"]
    lines = [
        f"- Training seeds per method: {n_seeds}. AUC cells are the mean over seeds with its "
        f"{100 * CONFIDENCE:.0f} % interval, `AUC [low, high]`; other cells are mean ± std over seeds.",
        f"- Intervals: episode-cluster bootstrap ({intervals.replicates} replicates resampling whole test "
        f"episodes, {intervals.normal_episodes} normal and {intervals.anomalous_episodes} anomalous, each "
        "class separately; the same draws for every seed and every method; `benchmarks.uncertainty`)."
        f" `[n/a]`: fewer than {MIN_EPISODES_PER_CLASS} normal or anomalous episodes, so no interval.",
    ]
    if intervals.reference is not None:
        lines += [
            "- ΔAUC vs M-SVDD: the method's AUC minus M-SVDD's on the same episode draws, with its interval;"
            " *excludes 0* says whether that interval lies wholly on one side of zero.",
            "  **A difference inside the interval is not a ranking**: when the interval of a difference"
            " contains zero, this test set does not tell the two methods apart, whatever their AUCs.",
        ]
        all_seeds = intervals.methods[intervals.reference].reference_seeds
        fewer = {
            m: mi.reference_seeds for m, mi in intervals.methods.items() if mi.reference_seeds != all_seeds
        }
        if fewer:
            names = ", ".join(
                f"{m} (seeds {', '.join(map(str, seeds))})" for m, seeds in sorted(fewer.items())
            )
            lines.append(
                "- Trained with fewer seeds than M-SVDD, and so compared with M-SVDD's models of the same"
                f" training seeds (the ablated part, not M-SVDD's seed spread): {names}."
            )
    else:
        lines.append(
            "  A difference between two AUCs that lies inside their intervals is not a ranking"
            " (M-SVDD was not run, so no paired differences are given)."
        )
    return lines


_PAPER_SECTIONS: tuple[tuple[str, str, tuple[tuple[str, str, bool], ...]], ...] = (
    ("Table II", "Module ablation (paper Table II)", SHORT_COLUMNS),
    ("Table III", "Fusion ablation (paper Table III)", SHORT_COLUMNS),
    ("latent-s figure", "Latent dimension s", SHORT_COLUMNS),
)
"""The ablation tables: paper table, heading, columns (each shown when the run has one of its ablations)."""


def provenance_lines(
    info: RunInfo, per_method: Mapping[str, Sequence[MethodMetrics]], intervals: RunIntervals | None
) -> list[str]:
    """The bullets under a run's title: command, machine, datasets, test windows, what the cells mean."""
    first = next(iter(per_method.values()))[0]
    n_seeds = max(len(v) for v in per_method.values())
    return [
        f"- Command: `{info.command}`",
        f"- Date: {info.date}; machine: {info.machine}"
        + (f"; code: {info.code_version}" if info.code_version else ""),
        f"- Eval dataset: `{info.dataset}` (reported; fingerprint `{info.dataset_fingerprint or 'n/a'}`)."
        " Dev dataset: "
        + (f"{info.dev} (every choice a method makes)" if info.dev else "none given (built-in settings)"),
        f"- Test windows: {first.n_normal} normal, {first.n_collision} collision, "
        f"{first.n_mechanical} mechanical",
        *_interval_notes(intervals, n_seeds),
        "- Precision, recall and F1 use each method's threshold, fixed from nominal data only:"
        f" {THRESHOLD_RULE}.",
        "  **F1 oracle** is the best F1 over the test precision-recall curve, the paper's protocol:"
        " it sees the test labels and is reported for comparison only.",
    ]


def result_tables(
    per_method: Mapping[str, Sequence[MethodMetrics]], intervals: RunIntervals | None, level: int = 2
) -> list[str]:
    """A run's tables, each under a heading of `level` (`results.md`; the docs generator nests them): the
    comparison (its first line says whether the test set ranks), the ablations the run has, the reference
    and naive detectors with the naive verdict, paired differences, AUCs by sub-kind and by severity."""
    h = "#" * level
    names = list(per_method)
    out = [
        f"{h} Comparison (paper Table I)",
        "",
        ranking_note(intervals),
        "",
        *method_table(paper_table("Table I", names), per_method, MAIN_COLUMNS, intervals),
        "",
        *([SVDD_NOTE, ""] if any(m.startswith("svdd-") for m in names) else []),
    ]
    for table, heading, columns in _PAPER_SECTIONS:
        rows = paper_table(table, names)
        if any(m != REFERENCE_METHOD for m, _ in rows):
            out += [f"{h} {heading}", "", *method_table(rows, per_method, columns, intervals), ""]
    reference = family_table("reference", names)
    if reference:
        out += [
            f"{h} Reference detectors (densities of the inputs, no M-SVDD network)",
            "",
            *method_table(reference, per_method, MAIN_COLUMNS, intervals),
            "",
        ]
    naive = family_table("naive", names)
    if naive:
        out += [
            f"{h} Naive sanity baselines",
            "",
            *method_table(naive, per_method, MAIN_COLUMNS, intervals),
            "",
        ]
    out += [*_other_methods(per_method, intervals, h), naive_verdict(per_method, intervals), ""]
    if intervals is not None and intervals.reference is not None:
        out += [
            f"{h} Paired AUC differences against M-SVDD (every method of the run)",
            "",
            *_difference_table(per_method, intervals),
            "",
            *_ablation_fault_table(per_method, intervals, h),
        ]
    return [
        *out,
        f"{h} AUC (%) by anomaly sub-kind (comparison methods; every method's are in results.json)",
        "",
        *_sub_kind_table(per_method, intervals),
        "",
        *_severity_table(per_method, intervals, h),
        *_severity_by_kind_table(intervals, h),
        *_top_severity_by_kind_table(per_method, intervals, h),
    ]


def markdown(
    info: RunInfo, per_method: Mapping[str, Sequence[MethodMetrics]], intervals: RunIntervals | None = None
) -> str:
    """`results.md`: the paper's tables from this run's data (AUCs with intervals when given)."""
    out = [
        f"# Results: preset `{info.preset}`, dataset seed {info.dataset_seed}",
        "",
        *provenance_lines(info, per_method, intervals),
        "",
        *result_tables(per_method, intervals),
        "## Fit time",
        "",
        *fit_time_table(info.train_seconds),
        "",
        "ROC curves: `figures/roc_all.png`, `figures/roc_collision.png`, `figures/roc_mechanical.png`.",
        "",
    ]
    return "\n".join(out)


def fit_time_table(train_seconds: Mapping[str, float]) -> list[str]:
    """Mean fit time per method, s."""
    return ["| Method | Fit (s) |", "|---|---|", *[f"| {m} | {s:.1f} |" for m, s in train_seconds.items()]]


def _other_methods(
    per_method: Mapping[str, Sequence[MethodMetrics]], intervals: RunIntervals | None, h: str = "##"
) -> list[str]:
    """A table of the methods no other table shows (detectors from outside the project), if any."""
    shown = set(_shown_in_tables(per_method))
    others = [m for m in per_method if m not in shown]
    if not others:
        return []
    return [
        f"{h} Other methods (detectors from outside the project and unlisted registry methods)",
        "",
        *method_table(tuple((m, f"`{m}`") for m in others), per_method, MAIN_COLUMNS, intervals),
        "",
    ]


def _breakdown_methods(per_method: Mapping[str, Sequence[MethodMetrics]]) -> list[str]:
    """The comparison, reference and naive methods of the run, in table order: the columns of the
    sub-kind and severity tables."""
    names = list(per_method)
    rows = (*paper_table("Table I", names), *family_table("reference", names), *family_table("naive", names))
    return [m for m, _ in rows]


def _sub_kind_table(
    per_method: Mapping[str, Sequence[MethodMetrics]], intervals: RunIntervals | None = None
) -> list[str]:
    """Rows per anomaly sub-kind, columns for the comparison and naive methods (ablations stay in JSON)."""
    subs = sorted({s for runs in per_method.values() for r in runs for s in r.auc_by_sub_kind})
    names = _breakdown_methods(per_method)
    lines = ["| Sub-kind | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
    for sub in subs:
        cells = [
            _auc_cell(intervals, n, f"auc_{sub}")
            or _fmt(*aggregate(per_method[n]).get(f"auc_{sub}", (math.nan, 0.0)), with_std=False)
            for n in names
        ]
        lines.append(f"| {sub} | " + " | ".join(cells) + " |")
    return lines


def _severity_columns(
    per_method: Mapping[str, Sequence[MethodMetrics]], intervals: RunIntervals
) -> tuple[list[str], list[str]]:
    """The comparison, reference and naive methods with intervals, and the severity bins that hold fault
    windows for any of them."""
    names = [n for n in _breakdown_methods(per_method) if n in intervals.methods]
    labels = [
        b for b, _, _ in severity_bins() if any(severity_key(b) in intervals.methods[n].auc for n in names)
    ]
    return names, labels


def _method_columns_head(title: str, first: str, names: Sequence[str]) -> list[str]:
    """A table's heading, blank line, header row (`first`, then one column per method) and separator."""
    return [title, "", f"| {first} | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]


def _severity_table(
    per_method: Mapping[str, Sequence[MethodMetrics]], intervals: RunIntervals | None, h: str = "##"
) -> list[str]:
    """Rows per fault-severity bin (every fault kind together), columns for the comparison, reference and
    naive methods; nothing when the run has no severities (a dataset of recordings) or no intervals."""
    if intervals is None:
        return []
    names, labels = _severity_columns(per_method, intervals)
    if not labels:
        return []
    lines = _method_columns_head(
        f"{h} Fault AUC (%) by fault severity (normal windows against the fault windows of episodes whose"
        " fault severity is in the bin; every method's per fault kind in results.json)",
        "Severity",
        names,
    )
    for label in labels:
        cells = [_auc_cell(intervals, n, severity_key(label)) or "n/a" for n in names]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return [*lines, ""]


def _fault_bins_and_kinds(auc: Mapping[str, Interval]) -> tuple[list[str], list[str]]:
    """The severity bins that hold fault windows and the fault kinds with an AUC in any of them, of one
    method's AUC intervals."""
    labels = [b for b, _, _ in severity_bins() if severity_key(b) in auc]
    subs = {key.removeprefix("auc_") for key in auc if key.startswith("auc_")} - {"mechanical"}
    return labels, sorted(k for k in subs if any(severity_key(b, k) in auc for b in labels))


def _severity_by_kind_table(intervals: RunIntervals | None, h: str = "##") -> list[str]:
    """The paired-difference reference's fault AUC per fault kind (rows) and severity bin (columns), for
    the bins and kinds that hold fault windows; nothing without severities, intervals or reference."""
    reference = intervals.reference if intervals is not None else None
    if intervals is None or reference is None or reference not in intervals.methods:
        return []
    auc = intervals.methods[reference].auc
    labels, kinds = _fault_bins_and_kinds(auc)
    if not kinds:
        return []
    lines = [
        f"{h} Fault AUC (%) of `{reference}` by fault kind and severity",
        "",
        "| Fault kind | " + " | ".join(labels) + " |",
        "|---|" + "---|" * len(labels),
    ]
    for kind in kinds:
        cells = [_auc_cell(intervals, reference, severity_key(b, kind)) or "n/a" for b in labels]
        lines.append(f"| {kind} | " + " | ".join(cells) + " |")
    return [*lines, ""]


ABLATION_TABLES: tuple[str, ...] = ("Table II", "Table III", "latent-s figure")
"""The paper's tables whose rows are ablations of M-SVDD (one switch each)."""


def _ablation_fault_table(
    per_method: Mapping[str, Sequence[MethodMetrics]], intervals: RunIntervals | None, h: str = "##"
) -> list[str]:
    """Each ablation's paired fault AUC difference against M-SVDD by fault kind (all faults first) and
    severity bin (all severities first), a difference whose interval excludes 0 in bold; nothing without
    ablations, intervals or the reference."""
    if intervals is None or intervals.reference is None or intervals.reference not in intervals.methods:
        return []
    names = list(per_method)
    ablations = list(
        dict.fromkeys(
            m
            for table in ABLATION_TABLES
            for m, _ in paper_table(table, names)
            if m != intervals.reference and m in intervals.methods
        )
    )
    auc = intervals.methods[intervals.reference].auc
    labels, kinds = _fault_bins_and_kinds(auc)
    if not ablations or not kinds:
        return []

    def cell(method: str, key: str) -> str:
        iv = intervals.methods[method].vs_reference.get(key)
        if iv is None:
            return "n/a"
        text = format_interval(iv, signed=True)
        return f"**{text}**" if excludes_zero(iv) else text

    columns = ["all severities", *labels]
    lines = [
        f"{h} Paired fault AUC differences (%) of the ablations against M-SVDD by fault kind and severity"
        " (an interval that excludes 0 in bold)",
        "",
        "| Ablation | Fault kind | " + " | ".join(columns) + " |",
        "|---|---|" + "---|" * len(columns),
    ]
    for method in ablations:
        for kind in ("mechanical", *kinds):
            keys = [f"auc_{kind}", *(severity_key(b, kind) for b in labels)]
            shown = "all faults" if kind == "mechanical" else kind
            lines.append(f"| `{method}` | {shown} | " + " | ".join(cell(method, k) for k in keys) + " |")
    return [*lines, ""]


def _top_severity_by_kind_table(
    per_method: Mapping[str, Sequence[MethodMetrics]], intervals: RunIntervals | None, h: str = "##"
) -> list[str]:
    """Every comparison, reference and naive method's fault AUC per fault kind (rows) in the highest severity
    bin that holds fault windows, the highest point estimate of each row in bold; nothing without
    severities or intervals."""
    if intervals is None:
        return []
    names, held = _severity_columns(per_method, intervals)
    if not held:
        return []
    top = held[-1]
    kinds = sorted(
        {
            key.removeprefix("auc_").removesuffix(f"_severity_{top}")
            for n in names
            for key in intervals.methods[n].auc
            if key.endswith(f"_severity_{top}") and key != severity_key(top)
        }
    )
    if not kinds:
        return []
    lines = _method_columns_head(
        f"{h} Fault AUC (%) at severity {top} by fault kind (comparison, reference and naive methods; the"
        " highest point estimate of a row in bold, which is not a ranking where the intervals overlap)",
        "Fault kind",
        names,
    )
    for kind in kinds:
        key = severity_key(top, kind)
        values = {n: iv.value for n in names if (iv := intervals.methods[n].auc.get(key)) is not None}
        best = max((v for v in values.values() if math.isfinite(v)), default=math.nan)
        cells = [_auc_cell(intervals, n, key) or "n/a" for n in names]
        bold = [f"**{c}**" if values.get(n) == best else c for n, c in zip(names, cells, strict=True)]
        lines.append(f"| {kind} | " + " | ".join(bold) + " |")
    return [*lines, ""]


def results_json(
    info: RunInfo, per_method: Mapping[str, Sequence[MethodMetrics]], intervals: RunIntervals | None = None
) -> dict[str, Any]:
    """`results.json`: every metric of every method (mean, std and per seed), AUC intervals if given.

    With `intervals`, each method gets `auc_ci95` (per AUC key: value, low, high) and
    `auc_diff_vs_reference` (the same keys: paired difference against `uncertainty.reference`, with
    `excludes_zero`; the reference's seeds in it: `auc_diff_reference_seeds`).
    """
    doc: dict[str, Any] = {
        "preset": info.preset,
        "seed": info.dataset_seed,
        "dataset": info.dataset,
        "command": info.command,
        "machine": info.machine,
        "date": info.date,
        "code_version": info.code_version or None,
        "dev": info.dev or None,
        "dataset_sha256": info.dataset_fingerprint or None,
        "oracle_note": "f1_oracle and threshold_oracle are chosen on test labels (oracle); every other "
        "thresholded metric uses the method's own threshold (threshold_rule)",
        "threshold_rule": THRESHOLD_RULE,
        "methods": {},
    }
    for name, runs in per_method.items():
        agg = aggregate(runs)
        entry: dict[str, Any] = {k: (None if not math.isfinite(v[0]) else v[0]) for k, v in agg.items()}
        entry["std"] = {k: (None if not math.isfinite(v[1]) else v[1]) for k, v in agg.items()}
        entry["family"] = methods.spec(name).family
        entry["per_seed"] = [r.to_dict() for r in runs]
        entry["train_seconds"] = info.train_seconds.get(name)
        found = intervals.methods.get(name) if intervals is not None else None
        if found is not None:
            entry["auc_ci95"] = {k: iv.to_dict() for k, iv in found.auc.items()}
            entry["auc_diff_vs_reference"] = {
                k: {**iv.to_dict(), "excludes_zero": excludes_zero(iv)}
                for k, iv in found.vs_reference.items()
            }
            entry["auc_diff_reference_seeds"] = list(found.reference_seeds)
        doc["methods"][name] = entry
    if intervals is not None:
        doc["uncertainty"] = {
            "method": "episode-cluster bootstrap: whole test episodes resampled with replacement, normal and "
            "anomalous separately; the same draws for every seed and method; a seed-mean AUC is averaged "
            "over seeds inside each replicate",
            "confidence": CONFIDENCE,
            "replicates": intervals.replicates,
            "seed": intervals.seed,
            "normal_episodes": intervals.normal_episodes,
            "anomalous_episodes": intervals.anomalous_episodes,
            "reference": intervals.reference,
            "note": "a difference whose interval contains zero is not a ranking",
        }
    if intervals is not None and intervals.naive_vs_best is not None:
        pair = intervals.naive_vs_best
        doc["naive_vs_best"] = {
            "naive": pair.naive,
            "best": pair.best,
            "difference": {**pair.difference.to_dict(), "excludes_zero": excludes_zero(pair.difference)},
        }
    doc["naive_verdict"] = naive_verdict(per_method, intervals)
    return doc


def write_scores_csv(path: Path, rows: Sequence[WindowRow], scores: Sequence[MethodScores]) -> None:
    """`scores.csv`: window_id, method, score, label (1 = anomalous), kind, then seed, sub_kind, flagged."""
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(
            [
                "window_id",
                "method",
                "score",
                "label",
                "kind",
                "seed",
                "sub_kind",
                "episode",
                "start_s",
                "flagged",
            ]
        )
        for ms in scores:
            for row, score in zip(rows, ms.scores, strict=True):
                anomalous = int(row.kind != "normal")
                flagged = int(score > ms.threshold)
                writer.writerow(
                    [row.window_id, ms.method, repr(float(score)), anomalous, row.kind, ms.seed,
                     row.sub_kind, row.episode, row.start_s, flagged]
                )  # fmt: skip


def write_roc_figures(
    directory: Path, rows: Sequence[WindowRow], scores: Sequence[MethodScores]
) -> list[Path]:
    """ROC curves of every method (first seed), overall and per anomaly kind, as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    directory.mkdir(parents=True, exist_ok=True)
    kinds = np.array([r.kind for r in rows])
    first: dict[str, MethodScores] = {}
    for ms in scores:
        first.setdefault(ms.method, ms)
    written = []
    for subset, title in (
        ("all", "all anomalies"),
        ("collision", "collisions"),
        ("mechanical", "wheel faults"),
    ):
        keep = (kinds == "normal") | (kinds == subset) if subset != "all" else np.ones(len(kinds), bool)
        labels = (kinds[keep] != "normal").astype(int)
        if labels.sum() == 0 or labels.sum() == labels.size:
            continue
        fig, ax = plt.subplots(figsize=(6, 6))
        for name, ms in first.items():
            fpr, tpr = roc_curve(labels, ms.scores[keep])
            area = float(np.trapezoid(tpr, fpr))
            ax.plot(fpr, tpr, lw=2.2 if name == "msvdd" else 1.1, label=f"{name} ({100 * area:.1f})")
        ax.plot([0, 1], [0, 1], "k:", lw=0.8)
        ax.set(xlabel="False positive rate", ylabel="True positive rate", title=f"ROC, {title} (AUC %)")
        ax.legend(fontsize=7, loc="lower right")
        path = directory / f"roc_{subset}.png"
        fig.tight_layout()
        fig.savefig(path, dpi=120)
        plt.close(fig)
        written.append(path)
    return written


def write_report(
    directory: Path,
    info: RunInfo,
    rows: Sequence[WindowRow],
    scores: Sequence[MethodScores],
    per_method: Mapping[str, Sequence[MethodMetrics]],
    severity: Mapping[str, float] | None = None,
) -> None:
    """Write every output of a run into `directory` (`severity`: fault severity by episode id, for the AUCs
    by severity; `benchmarks.dataset.Dataset.fault_severities`)."""
    directory.mkdir(parents=True, exist_ok=True)
    intervals = auc_intervals(rows, scores, severity=severity)
    doc = results_json(info, per_method, intervals)
    (directory / "results.json").write_text(json.dumps(doc, indent=2) + "\n")
    write_scores_csv(directory / "scores.csv", rows, scores)
    (directory / "results.md").write_text(markdown(info, per_method, intervals))
    write_roc_figures(directory / "figures", rows, scores)
