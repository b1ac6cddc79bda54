"""Outputs of `msvdd-bench robustness`: robustness.md, .json and .png, written atomically into one folder."""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from benchmarks.errors import OutputExistsError
from benchmarks.robustness.perturb import KINDS
from benchmarks.robustness.run import ConditionResult, RobustnessResult
from benchmarks.uncertainty import CONFIDENCE, excludes_zero, format_interval

MARKDOWN_FILE = "robustness.md"
"""The tables."""
JSON_FILE = "robustness.json"
"""Every number."""
PLOT_FILE = "robustness.png"
"""AUC ratio against severity, one panel per perturbation kind."""


@dataclass(frozen=True)
class RunContext:
    """Where the numbers come from."""

    dataset: str
    """Dataset folder."""
    preset: str
    """Dataset preset."""
    dataset_seed: int
    """Dataset seed."""
    fingerprint: str
    """`benchmarks.dataset.dataset_fingerprint` of the dataset."""
    command: str
    """The command line."""
    date: str
    """UTC date."""


def _num(v: float) -> float | None:
    return v if math.isfinite(v) else None


def _result_dict(r: ConditionResult) -> dict[str, Any]:
    unit = KINDS[r.kind].unit if r.kind in KINDS else ""
    return {
        "method": r.method,
        "perturbation": r.kind,
        "severity": r.severity,
        "unit": unit,
        "auc": r.auc.to_dict(),
        "ratio_to_clean": r.ratio.to_dict(),
        "delta_vs_clean": {**r.delta.to_dict(), "excludes_zero": excludes_zero(r.delta)},
        "auc_collision": _num(r.auc_collision),
        "auc_mechanical": _num(r.auc_mechanical),
        "nonfinite_scores": r.nonfinite_scores,
        "mirrored_windows": r.mirrored_windows,
    }


def to_json(result: RobustnessResult, context: RunContext) -> dict[str, Any]:
    """`robustness.json`: the run's identity, the perturbation definitions and every result."""
    config = result.config
    used = dict.fromkeys(p.kind for p in config.perturbations)
    return {
        "dataset": context.dataset,
        "preset": context.preset,
        "dataset_seed": context.dataset_seed,
        "dataset_sha256": context.fingerprint,
        "command": context.command,
        "date": context.date,
        "perturbation_seed": config.seed,
        "seeding": "each perturbation of each episode draws from numpy default_rng(SeedSequence([seed, "
        "crc32(kind), float64 bits of severity, episode index in manifest.json]))",
        "perturbations": {
            k: {
                "unit": KINDS[k].unit,
                "modality": KINDS[k].modality,
                "definition": KINDS[k].description,
                "severities": [p.severity for p in config.perturbations if p.kind == k],
            }
            for k in used
        },
        "uncertainty": {
            "method": "episode-cluster bootstrap: whole test episodes resampled with replacement, normal and "
            "anomalous separately; the same draws for every method and perturbation; ratio and delta are "
            "taken replicate by replicate against the clean AUC",
            "confidence": CONFIDENCE,
            "replicates": config.replicates,
            "seed": config.bootstrap_seed,
            "normal_episodes": result.normal_episodes,
            "anomalous_episodes": result.anomalous_episodes,
        },
        "test_windows": result.windows,
        "models": {m: [str(p) for p in paths] for m, paths in result.methods.items()},
        "results": [_result_dict(r) for r in result.results],
    }


def _conditions(result: RobustnessResult) -> list[tuple[str, float]]:
    return list(dict.fromkeys((r.kind, r.severity) for r in result.results if r.kind != "clean"))


def markdown(result: RobustnessResult, context: RunContext) -> str:
    """`robustness.md`: clean AUCs, then the ratio and AUC of every method under every perturbation."""
    names = list(result.methods)
    by = {(r.method, r.kind, r.severity): r for r in result.results}
    seeds = ", ".join(f"{m} {len(p)}" for m, p in result.methods.items())
    lines = [
        f"# Robustness: preset `{context.preset}`, dataset seed {context.dataset_seed}",
        "",
        f"- Command: `{context.command}`",
        f"- Dataset: `{context.dataset}` (fingerprint `{context.fingerprint}`); date {context.date}",
        f"- Test windows: {', '.join(f'{n} {k}' for k, n in result.windows.items())}; "
        f"{result.normal_episodes} normal and {result.anomalous_episodes} anomalous episodes",
        f"- Training seeds per method: {seeds}; an AUC is the mean over a method's seeds",
        f"- Intervals: {100 * CONFIDENCE:.0f} % episode-cluster bootstrap ({result.config.replicates} "
        "replicates, the same episode draws for every method and perturbation); the ratio "
        "AUC(perturbed) / AUC(clean) is taken replicate by replicate. `[n/a]`: fewer than 2 normal or "
        "anomalous episodes.",
        f"- Perturbations are applied to each test episode's streams and the windows cut again at the same "
        f"starts; seed {result.config.seed}, each draw keyed by (seed, kind, severity, episode index).",
        "",
        "## Clean AUC (%)",
        "",
        "| Method | AUC (%) |",
        "|---|---|",
        *(f"| {m} | {format_interval(result.clean(m).auc)} |" for m in names),
        "",
        "## AUC ratio, perturbed / clean (1 = unaffected)",
        "",
        "| Perturbation | Severity | " + " | ".join(names) + " |",
        "|---|---|" + "---|" * len(names),
    ]
    conditions = _conditions(result)
    for kind, severity in conditions:
        cells = [format_interval(by[(m, kind, severity)].ratio, percent=False, digits=3) for m in names]
        lines.append(f"| {kind} | {severity:g} {KINDS[kind].unit} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "## AUC (%) under each perturbation",
        "",
        "| Perturbation | Severity | " + " | ".join(names) + " |",
        "|---|---|" + "---|" * len(names),
    ]
    for kind, severity in conditions:
        cells = [format_interval(by[(m, kind, severity)].auc) for m in names]
        lines.append(f"| {kind} | {severity:g} {KINDS[kind].unit} | " + " | ".join(cells) + " |")
    nonfinite = [r for r in result.results if r.nonfinite_scores]
    first = names[0]
    mirrored = [(r.kind, r.severity, r.mirrored_windows) for r in result.results
                if r.method == first and r.mirrored_windows]  # fmt: skip
    lines += ["", "## Perturbations", ""]
    lines += [
        f"- **{k}** ({KINDS[k].unit}): {KINDS[k].description}"
        for k in dict.fromkeys(c[0] for c in conditions)
    ]
    if mirrored:
        total = sum(result.windows.values())
        lines += [
            "",
            "IMU samples a shift or drift needs from past an episode's ends are its recording mirrored about "
            f"the end sample; test windows holding such samples (of {total}): "
            + ", ".join(f"{k} {s:g} {KINDS[k].unit}: {n}" for k, s, n in mirrored)
            + ".",
        ]
    if nonfinite:
        lines += ["", "## Non-finite scores", ""]
        lines += [
            f"- {r.method}, {r.kind} {r.severity:g}: {r.nonfinite_scores} NaN/inf scores (NaN ranked least "
            "anomalous)"
            for r in nonfinite
        ]
    return "\n".join(lines) + "\n"


def write_plot(path: Path, result: RobustnessResult) -> None:
    """One panel per kind: the AUC ratio (with its interval) of every method against severity, clean at 0."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    kinds = list(dict.fromkeys(k for k, _ in _conditions(result)))
    cols = min(4, len(kinds))
    rows = math.ceil(len(kinds) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.4 * rows), squeeze=False)
    for ax, kind in zip(axes.flat, kinds, strict=False):
        severities = sorted({0.0, *(s for k, s in _conditions(result) if k == kind)})
        x = list(range(len(severities)))
        for method in result.methods:
            found = {r.severity: r for r in result.results if r.method == method and r.kind == kind}
            clean = result.clean(method)
            points = [clean if s == 0 and s not in found else found[s] for s in severities]
            values = [1.0 if p.kind == "clean" else p.ratio.value for p in points]
            low = [
                v - (p.ratio.low if math.isfinite(p.ratio.low) else v)
                for v, p in zip(values, points, strict=True)
            ]
            high = [
                (p.ratio.high if math.isfinite(p.ratio.high) else v) - v
                for v, p in zip(values, points, strict=True)
            ]
            ax.errorbar(x, values, yerr=[low, high], marker="o", ms=3, lw=2.0 if method == "msvdd" else 1.0,
                        capsize=2, label=method)  # fmt: skip
        ax.axhline(1.0, color="k", lw=0.6, ls=":")
        ax.set_xticks(x, [f"{s:g}" for s in severities], fontsize=7)
        ax.set(title=kind, xlabel=f"severity ({KINDS[kind].unit})", ylabel="AUC / clean AUC")
    spare = list(axes.flat)[len(kinds) :]
    for ax in spare:
        ax.axis("off")
    handles, labels = axes.flat[0].get_legend_handles_labels()
    if spare:  # the legend in the first empty panel
        spare[0].legend(handles, labels, loc="center", fontsize=8, title="method")
        fig.tight_layout()
    else:
        fig.legend(handles, labels, loc="lower center", ncol=min(5, len(labels)), fontsize=7)
        fig.tight_layout(rect=(0, 0.06 + 0.02 * math.ceil(len(labels) / 5), 1, 1))
    fig.savefig(path, dpi=120)
    plt.close(fig)


def write_outputs(out: Path, result: RobustnessResult, context: RunContext) -> Path:
    """Write the three outputs into `out` (which must not exist) through a temporary sibling folder."""
    out = Path(out)
    if out.exists():
        raise OutputExistsError(
            f"--out {out}: the folder exists already; allowed: a path that does not exist"
        )
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=out.parent))
    try:
        (tmp / JSON_FILE).write_text(json.dumps(to_json(result, context), indent=2) + "\n")
        (tmp / MARKDOWN_FILE).write_text(markdown(result, context))
        write_plot(tmp / PLOT_FILE, result)
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out
