"""Outputs of a run: `results.json`, `scores.csv`, `results.md` (tables shaped like the paper's), ROC PNGs."""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks import methods
from benchmarks.dataset import WindowRow
from benchmarks.metrics import MethodMetrics, aggregate, roc_curve
from benchmarks.pipeline import MethodScores

COMPARISON: tuple[tuple[str, str], ...] = (
    ("iforest", "IF"),
    ("ocsvm", "OCSVM"),
    ("svdd", "SVDD"),
    ("deep-if", "DeepForest"),
    ("dagmm", "DAGMM"),
    ("dae", "DAE"),
    ("vae-svdd", "VAE-SVDD"),
    ("dsvdd", "DSVDD"),
    ("msvdd", "**M-SVDD (ours)**"),
)
"""Table I rows: registry name (shallow ones get -early/-late) and the paper's label."""

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

TOO_EASY_AUC = 0.9
"""A naive baseline at or above this AUC means the benchmark is too easy, and the report says so."""


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


def _fmt(mean: float, std: float, pct: bool = True, with_std: bool = True) -> str:
    if not math.isfinite(mean):
        return "n/a"
    scale = 100.0 if pct else 1.0
    text = f"{mean * scale:.1f}"
    if with_std and std > 0:
        text += f" ± {std * scale:.1f}"
    return text


def _resolve(name: str, available: Mapping[str, object]) -> list[str]:
    """A table row's method(s): the name itself, or its early and late fusion variants."""
    if name in available:
        return [name]
    return [n for n in (f"{name}-early", f"{name}-late") if n in available]


def _table(
    rows: Sequence[tuple[str, str]],
    per_method: Mapping[str, Sequence[MethodMetrics]],
    columns: Sequence[tuple[str, str, bool]],
) -> list[str]:
    lines = ["| Method | " + " | ".join(c[1] for c in columns) + " |"]
    lines.append("|---|" + "---|" * len(columns))
    for name, label in rows:
        for method in _resolve(name, per_method):
            agg = aggregate(per_method[method])
            shown = label if method == name else f"{label} ({method.rsplit('-', 1)[1]} fusion)"
            cells = [_fmt(*agg.get(key, (math.nan, 0.0)), pct=pct) for key, _, pct in columns]
            lines.append(f"| {shown} | " + " | ".join(cells) + " |")
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


def markdown(info: RunInfo, per_method: Mapping[str, Sequence[MethodMetrics]]) -> str:
    """`results.md`: the paper's tables from this run's data."""
    any_runs = next(iter(per_method.values()))
    first = any_runs[0]
    n_seeds = max(len(v) for v in per_method.values())
    out = [
        f"# Results: preset `{info.preset}`, dataset seed {info.dataset_seed}",
        "",
        f"- Command: `{info.command}`",
        f"- Date: {info.date}; machine: {info.machine}",
        f"- Test windows: {first.n_normal} normal, {first.n_collision} collision, "
        f"{first.n_mechanical} mechanical",
        f"- Training seeds per method: {n_seeds} (mean ± std over seeds)",
        "- Precision, recall and F1 use each method's threshold from its training scores only"
        " (95th percentile).",
        "  **F1 oracle** is the best F1 over the test precision-recall curve, the paper's protocol:"
        " it sees the test labels and is reported for comparison only.",
        "",
        "## Comparison (paper Table I)",
        "",
        *_table(COMPARISON, per_method, _MAIN_COLUMNS),
        "",
        "## Module ablation (paper Table II)",
        "",
        *_table(MODULE_ABLATION, per_method, _SHORT_COLUMNS),
        "",
        "## Fusion ablation (paper Table III)",
        "",
        *_table(FUSION_ABLATION, per_method, _SHORT_COLUMNS),
        "",
        "## Latent dimension s",
        "",
        *_table(LATENT_SWEEP, per_method, _SHORT_COLUMNS),
        "",
        "## Naive sanity baselines",
        "",
        *_table(NAIVE, per_method, _MAIN_COLUMNS),
        "",
        naive_verdict(per_method),
        "",
        "## AUC (%) by anomaly sub-kind (comparison methods; every method's are in results.json)",
        "",
        *_sub_kind_table(per_method),
        "",
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


def _sub_kind_table(per_method: Mapping[str, Sequence[MethodMetrics]]) -> list[str]:
    """Rows per anomaly sub-kind, columns for the comparison and naive methods (ablations stay in JSON)."""
    subs = sorted({s for runs in per_method.values() for r in runs for s in r.auc_by_sub_kind})
    names = [m for name, _ in (*COMPARISON, *NAIVE) for m in _resolve(name, per_method)]
    lines = ["| Sub-kind | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
    for sub in subs:
        cells = [
            _fmt(*aggregate(per_method[n]).get(f"auc_{sub}", (math.nan, 0.0)), with_std=False) for n in names
        ]
        lines.append(f"| {sub} | " + " | ".join(cells) + " |")
    return lines


def results_json(info: RunInfo, per_method: Mapping[str, Sequence[MethodMetrics]]) -> dict[str, Any]:
    """`results.json`: every metric of every method (mean, std and per seed)."""
    doc: dict[str, Any] = {
        "preset": info.preset,
        "seed": info.dataset_seed,
        "dataset": info.dataset,
        "command": info.command,
        "machine": info.machine,
        "date": info.date,
        "oracle_note": "f1_oracle and threshold_oracle are chosen on test labels (oracle); every other "
        "thresholded metric uses the training threshold",
        "methods": {},
    }
    for name, runs in per_method.items():
        agg = aggregate(runs)
        entry: dict[str, Any] = {k: (None if not math.isfinite(v[0]) else v[0]) for k, v in agg.items()}
        entry["std"] = {k: (None if not math.isfinite(v[1]) else v[1]) for k, v in agg.items()}
        entry["family"] = methods.spec(name).family
        entry["per_seed"] = [r.to_dict() for r in runs]
        entry["train_seconds"] = info.train_seconds.get(name)
        doc["methods"][name] = entry
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
) -> None:
    """Write every output of a run into `directory`."""
    directory.mkdir(parents=True, exist_ok=True)
    (directory / "results.json").write_text(json.dumps(results_json(info, per_method), indent=2) + "\n")
    write_scores_csv(directory / "scores.csv", rows, scores)
    (directory / "results.md").write_text(markdown(info, per_method))
    write_roc_figures(directory / "figures", rows, scores)
