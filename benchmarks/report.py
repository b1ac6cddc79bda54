"""Outputs of a run: `results.json`, `scores.csv`, `results.md` (tables shaped like the paper's), ROC PNGs.

Every AUC comes with its episode-cluster bootstrap 95 % interval (`benchmarks.uncertainty`), and every method
with its paired AUC difference against M-SVDD on the same episode draws.
"""

from __future__ import annotations

import csv
import itertools
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks import methods
from benchmarks.dataset import WindowRow
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

COMPARISON: tuple[tuple[str, str], ...] = (
    ("iforest", "IF"),
    ("ocsvm", "OCSVM"),
    ("svdd", "SVDD †"),
    ("deep-if", "DeepForest"),
    ("dagmm", "DAGMM"),
    ("dae", "DAE"),
    ("dcase-ae", "DCASE AE (log-mel)"),
    ("vae-svdd", "VAE-SVDD"),
    ("dsvdd", "DSVDD"),
    ("msvdd-paper", "M-SVDD (the paper's configuration)"),
    ("msvdd-mixture", "M-SVDD, residual frames on their own (an earlier `msvdd`)"),
    ("msvdd-context", "M-SVDD, residual frames given their neighbours (the previous `msvdd`)"),
    ("msvdd", "**M-SVDD (ours)**"),
)
"""Table I rows: registry name (shallow ones get -early/-late) and the paper's label (DCASE AE is ours)."""

SVDD_NOTE = (
    "† The SVDD rows equal the OCSVM rows by construction: with an RBF kernel the SVDD and one-class SVM"
    " duals coincide (Tax & Duin 2004; Schölkopf et al. 2001), so `svdd-*` is fitted as the same"
    " one-class SVM as `ocsvm-*`."
)
"""Footnote under Table I whenever it has an SVDD row."""

MODULE_ABLATION: tuple[tuple[str, str], ...] = (
    ("msvdd-imu-only", "w/o audio"),
    ("msvdd-audio-only", "w/o IMU"),
    ("msvdd-no-rec", "w/o reconstruction"),
    ("msvdd-euclidean", "w/o M-SVDD (Euclidean)"),
    ("msvdd", "full model"),
)
FUSION_ABLATION: tuple[tuple[str, str], ...] = (
    ("msvdd-fusion-concat", "Concatenate"),
    ("msvdd-fusion-sum", "Element-wise sum"),
    ("msvdd-fusion-product", "Element-wise product"),
    ("msvdd", "Cross-attention"),
)
LATENT_SWEEP: tuple[tuple[str, str], ...] = (
    ("msvdd-s2", "s = 2"),
    ("msvdd-s4", "s = 4"),
    ("msvdd-s8", "s = 8"),
    ("msvdd-s16", "s = 16"),
    ("msvdd", "s = 32"),
    ("msvdd-s64", "s = 64"),
)
NAIVE: tuple[tuple[str, str], ...] = (("audio-rms", "audio RMS"), ("imu-kurtosis", "IMU kurtosis"))
REFERENCE: tuple[tuple[str, str], ...] = (
    ("gaussian-early", "Gaussian, log-mel + IMU statistics"),
    ("gaussian-audio", "Gaussian, log-mel statistics"),
    ("gaussian-imu", "Gaussian, IMU statistics"),
    ("gaussian-frames", "Gaussian, log-mel and IMU frames (largest frame distance)"),
    ("mixture-frames", "Gaussian mixture, log-mel and IMU frames (largest frame distance)"),
    ("context-frames", "Gaussian mixtures, log-mel and IMU frames given their neighbours"),
    ("context-net-frames", "the same, the log-mel frames' density learned (mixture density network)"),
)
"""The reference detectors (densities of the inputs, no M-SVDD network): the audit's
Ledoit-Wolf Gaussian on fixed window statistics, the frame-wise Gaussian of M-SVDD's input frames
(`rec_score="mahalanobis"` without the network), the frame-wise Gaussian mixture (`msvdd`'s reconstruction
term, `rec_score="mixture"`, without the network; `benchmarks.methods.frames`), the frame-wise mixtures given
each frame's neighbours (`context-frames`), and the same with the log-mel frames' conditional density learned
by a small network (`context-net-frames`)."""

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
    return RunIntervals(
        methods={m: MethodIntervals(auc[m], diff[m], paired.get(m, ())) for m in by_method},
        reference=reference if reference in by_method else None,
        normal_episodes=len(set(episodes[normal])),
        anomalous_episodes=len(set(episodes[~normal])),
        replicates=replicates,
        seed=seed,
    )


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


def _resolve(name: str, available: Mapping[str, object]) -> list[str]:
    """A table row's method(s): the name itself, or its early and late fusion variants."""
    if name in available:
        return [name]
    return [n for n in (f"{name}-early", f"{name}-late") if n in available]


def _row_label(name: str, label: str, method: str) -> str:
    """A table row's label for `method`: the row's own, or with the fusion of its -early/-late variant."""
    return label if method == name else f"{label} ({method.rsplit('-', 1)[1]} fusion)"


def _table(
    rows: Sequence[tuple[str, str]],
    per_method: Mapping[str, Sequence[MethodMetrics]],
    columns: Sequence[tuple[str, str, bool]],
    intervals: RunIntervals | None = None,
) -> list[str]:
    with_diff = intervals is not None and intervals.reference is not None
    headers = [c[1] for c in columns] + (list(_DIFF_HEADERS) if with_diff else [])
    lines = ["| Method | " + " | ".join(headers) + " |"]
    lines.append("|---|" + "---|" * len(headers))
    for name, label in rows:
        for method in _resolve(name, per_method):
            agg = aggregate(per_method[method])
            shown = _row_label(name, label, method)
            cells = [
                _auc_cell(intervals, method, key) or _fmt(*agg.get(key, (math.nan, 0.0)), pct=pct)
                for key, _, pct in columns
            ]
            if with_diff:
                assert intervals is not None
                cells += _diff_cells(intervals, method, "auc")
            lines.append(f"| {shown} | " + " | ".join(cells) + " |")
    return lines


_TABLES: tuple[tuple[tuple[str, str], ...], ...] = (
    COMPARISON, MODULE_ABLATION, FUSION_ABLATION, LATENT_SWEEP, REFERENCE, NAIVE
)  # fmt: skip
"""Every fixed table of `results.md`; a method in none of them gets the "other methods" table."""

PAPER_TABLES: tuple[tuple[str, tuple[tuple[str, str], ...]], ...] = (
    ("Table I", COMPARISON),
    ("Table II", MODULE_ABLATION),
    ("Table III", FUSION_ABLATION),
    ("latent-s figure", LATENT_SWEEP),
)
"""The paper's tables (and its latent-dimension figure) that `results.md` reproduces, with their rows."""


def paper_rows(method: str) -> list[str]:
    """Where `method` appears in the paper, e.g. `["Table I: IF (early fusion)"]`; empty if nowhere."""
    return [
        f"{table}: {_row_label(name, label, method).replace('*', '')}"
        for table, rows in PAPER_TABLES
        for name, label in rows
        if _resolve(name, {method: None}) == [method]
    ]


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


_MAIN_COLUMNS: tuple[tuple[str, str, bool], ...] = (
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
_SHORT_COLUMNS: tuple[tuple[str, str, bool], ...] = (
    ("recall", "Recall (%)", True),
    ("precision", "Precision (%)", True),
    ("f1", "F1 (%)", True),
    ("f1_oracle", "F1 oracle (%)", True),
    ("auc", "AUC (%)", True),
)


def naive_verdict(per_method: Mapping[str, Sequence[MethodMetrics]]) -> str:
    """One sentence on whether the naive energy/kurtosis baselines solve the benchmark."""
    found = {n: aggregate(per_method[n])["auc"][0] for n, _ in NAIVE if n in per_method}
    if not found:
        return "The naive sanity baselines were not run."
    best = max(found, key=lambda n: found[n])
    text = ", ".join(f"{n} AUC {100 * v:.1f}%" for n, v in found.items())
    if found[best] >= TOO_EASY_AUC:
        return (
            f"WARNING: a naive baseline scores well ({text}): on this data the benchmark is too easy, "
            "since window energy or kurtosis alone finds the anomalies."
        )
    return (
        f"The naive baselines stay low ({text}), so energy or kurtosis alone does not solve this benchmark."
    )


def _interval_notes(intervals: RunIntervals | None, n_seeds: int) -> list[str]:
    """The header lines that say what the cells and intervals mean."""
    if intervals is None:
        return [f"- Training seeds per method: {n_seeds} (mean ± std over seeds)"]
    lines = [
        f"- Training seeds per method: {n_seeds}. AUC cells are the mean over seeds with its "
        f"{100 * CONFIDENCE:.0f} % interval, `84.0 [81.2, 86.5]`; other cells are mean ± std over seeds.",
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


def markdown(
    info: RunInfo, per_method: Mapping[str, Sequence[MethodMetrics]], intervals: RunIntervals | None = None
) -> str:
    """`results.md`: the paper's tables from this run's data (AUCs with intervals when given)."""
    any_runs = next(iter(per_method.values()))
    first = any_runs[0]
    n_seeds = max(len(v) for v in per_method.values())
    differences: list[str] = []
    if intervals is not None and intervals.reference is not None:
        differences = [
            "## Paired AUC differences against M-SVDD (every method of the run)",
            "",
            *_difference_table(per_method, intervals),
            "",
        ]
    out = [
        f"# Results: preset `{info.preset}`, dataset seed {info.dataset_seed}",
        "",
        f"- Command: `{info.command}`",
        f"- Date: {info.date}; machine: {info.machine}",
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
        "",
        "## Comparison (paper Table I)",
        "",
        *_table(COMPARISON, per_method, _MAIN_COLUMNS, intervals),
        "",
        *([SVDD_NOTE, ""] if _resolve("svdd", per_method) else []),
        "## Module ablation (paper Table II)",
        "",
        *_table(MODULE_ABLATION, per_method, _SHORT_COLUMNS, intervals),
        "",
        "## Fusion ablation (paper Table III)",
        "",
        *_table(FUSION_ABLATION, per_method, _SHORT_COLUMNS, intervals),
        "",
        "## Latent dimension s",
        "",
        *_table(LATENT_SWEEP, per_method, _SHORT_COLUMNS, intervals),
        "",
        "## Reference detectors (densities of the inputs, no M-SVDD network: Gaussians on fixed window"
        " statistics, the audit's; Gaussians and mixtures on the input frames, alone or given their"
        " neighbours; the last row learns the log-mel frames' density given their neighbours)",
        "",
        *_table(REFERENCE, per_method, _MAIN_COLUMNS, intervals),
        "",
        "## Naive sanity baselines",
        "",
        *_table(NAIVE, per_method, _MAIN_COLUMNS, intervals),
        "",
        *_other_methods(per_method, intervals),
        naive_verdict(per_method),
        "",
        *differences,
        "## AUC (%) by anomaly sub-kind (comparison methods; every method's are in results.json)",
        "",
        *_sub_kind_table(per_method, intervals),
        "",
        *_severity_table(per_method, intervals),
        *_severity_by_kind_table(intervals),
        "## Fit time",
        "",
        "| Method | Fit (s) |",
        "|---|---|",
        *[f"| {m} | {s:.1f} |" for m, s in info.train_seconds.items()],
        "",
        "ROC curves: `figures/roc_all.png`, `figures/roc_collision.png`, `figures/roc_mechanical.png`.",
        "",
    ]
    return "\n".join(out)


def _other_methods(
    per_method: Mapping[str, Sequence[MethodMetrics]], intervals: RunIntervals | None
) -> list[str]:
    """A table of the methods no other table shows (detectors from outside the project), if any."""
    shown = {m for rows in _TABLES for name, _ in rows for m in _resolve(name, per_method)}
    others = [m for m in per_method if m not in shown]
    if not others:
        return []
    return [
        "## Other methods (detectors from outside the project and unlisted registry methods)",
        "",
        *_table([(m, f"`{m}`") for m in others], per_method, _MAIN_COLUMNS, intervals),
        "",
    ]


def _breakdown_methods(per_method: Mapping[str, Sequence[MethodMetrics]]) -> list[str]:
    """The comparison, reference and naive methods of the run, in table order: the columns of the
    sub-kind and severity tables."""
    return [m for name, _ in (*COMPARISON, *REFERENCE, *NAIVE) for m in _resolve(name, per_method)]


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


def _severity_table(
    per_method: Mapping[str, Sequence[MethodMetrics]], intervals: RunIntervals | None
) -> list[str]:
    """Rows per fault-severity bin (every fault kind together), columns for the comparison, reference and
    naive methods; nothing when the run has no severities (a dataset of recordings) or no intervals."""
    if intervals is None:
        return []
    names = _breakdown_methods(per_method)
    names = [n for n in names if n in intervals.methods]
    labels = [
        b for b, _, _ in severity_bins() if any(severity_key(b) in intervals.methods[n].auc for n in names)
    ]
    if not labels:
        return []
    lines = [
        "## Fault AUC (%) by fault severity (normal windows against the fault windows of episodes whose fault"
        " severity is in the bin; every method's per fault kind in results.json)",
        "",
        "| Severity | " + " | ".join(names) + " |",
        "|---|" + "---|" * len(names),
    ]
    for label in labels:
        cells = [_auc_cell(intervals, n, severity_key(label)) or "n/a" for n in names]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return [*lines, ""]


def _severity_by_kind_table(intervals: RunIntervals | None) -> list[str]:
    """The paired-difference reference's fault AUC per fault kind (rows) and severity bin (columns), for
    the bins and kinds that hold fault windows; nothing without severities, intervals or reference."""
    reference = intervals.reference if intervals is not None else None
    if intervals is None or reference is None or reference not in intervals.methods:
        return []
    auc = intervals.methods[reference].auc
    labels = [b for b, _, _ in severity_bins() if severity_key(b) in auc]
    subs = {key.removeprefix("auc_") for key in auc if key.startswith("auc_")} - {"mechanical"}
    kinds = sorted(k for k in subs if any(severity_key(b, k) in auc for b in labels))
    if not kinds:
        return []
    lines = [
        f"## Fault AUC (%) of `{reference}` by fault kind and severity",
        "",
        "| Fault kind | " + " | ".join(labels) + " |",
        "|---|" + "---|" * len(labels),
    ]
    for kind in kinds:
        cells = [_auc_cell(intervals, reference, severity_key(b, kind)) or "n/a" for b in labels]
        lines.append(f"| {kind} | " + " | ".join(cells) + " |")
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
    doc["naive_verdict"] = naive_verdict(per_method)
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
