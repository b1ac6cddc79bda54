"""A sweep's outputs: `sweep.json`, `sweep.md` and one PNG curve per AUC, each written atomically.

The AUCs are those of every anomaly, of collisions and of mechanical faults against normal windows, then of
each fault kind that the sweep's datasets hold (with the audit's oracle where the spec asks for it: it scores
faults per kind only).

Every cell is a seed-mean AUC with its 95 % episode-cluster bootstrap interval (`benchmarks.uncertainty`,
computed by each point's run). A plot has one line per method with the intervals as error bars; with several
dataset seeds the line is the mean over them and the bar spans the lowest to the highest end of their
intervals (an envelope, said so in the legend).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from pathlib import Path
from typing import Any

from benchmarks.sweeps.run import AUC_KEYS, KIND_KEYS, PointResult, SweepResult
from benchmarks.uncertainty import CONFIDENCE, Interval, format_interval
from msvdd.atomic import atomic_path, write_text_atomic

AUC_TITLES: dict[str, str] = {
    "auc": "AUC, every anomaly against normal",
    "auc_collision": "AUC, collisions against normal",
    "auc_mechanical": "AUC, mechanical faults against normal",
    **{key: f"AUC, {key.removeprefix('auc_')} faults against normal" for key in KIND_KEYS},
}
"""Heading of each AUC's table and plot."""


def reported_keys(result: SweepResult) -> list[str]:
    """`AUC_KEYS`, then each of `KIND_KEYS` that some method has a value for at some point."""
    found = [
        key
        for key in KIND_KEYS
        if any(math.isfinite(m.auc[key].value) for r in result.results for m in r.methods.values())
    ]
    return [*AUC_KEYS, *found]


def _has(result: SweepResult, method: str, key: str) -> bool:
    return any(
        method in r.methods and math.isfinite(r.methods[method].auc[key].value) for r in result.results
    )


def write_outputs(result: SweepResult) -> list[Path]:
    """Write `sweep.json`, `sweep.md` and `figures/<auc key>.png` into the sweep folder; their paths."""
    out = result.out
    (out / "figures").mkdir(parents=True, exist_ok=True)
    written = [write_text_atomic(out / "sweep.json", json.dumps(to_json(result), indent=2) + "\n")]
    for key in reported_keys(result):
        figure = out / "figures" / f"{key}.png"
        with atomic_path(figure, suffix=figure.suffix) as tmp:  # matplotlib picks the format by the suffix
            plot(result, key, tmp)
        written.append(figure)
    written.append(write_text_atomic(out / "sweep.md", markdown(result)))
    return written


def _methods(result: SweepResult) -> list[str]:
    found: list[str] = []
    for r in result.results:
        found += [m for m in r.methods if m not in found]
    return found


def _by_point(result: SweepResult) -> dict[int, list[PointResult]]:
    groups: dict[int, list[PointResult]] = {}
    for r in result.results:
        groups.setdefault(r.point, []).append(r)
    return groups


def combined(runs: list[PointResult], method: str, key: str) -> Interval:
    """One point's AUC over its dataset seeds: the interval itself for one seed; for several, the mean
    value and the envelope (lowest low, highest high) of their intervals."""
    ivs = [r.methods[method].auc[key] for r in runs if method in r.methods]
    if not ivs:
        return Interval(math.nan, math.nan, math.nan)
    if len(ivs) == 1:
        return ivs[0]
    lows = [iv.low for iv in ivs if math.isfinite(iv.low)]
    highs = [iv.high for iv in ivs if math.isfinite(iv.high)]
    value = float(sum(iv.value for iv in ivs) / len(ivs))
    return Interval(value, min(lows) if lows else math.nan, max(highs) if highs else math.nan)


def markdown(result: SweepResult) -> str:
    """`sweep.md`: the setting, then one table per AUC (rows: point and dataset seed; columns: methods)."""
    spec, axis = result.spec, result.spec.axis
    names = _methods(result)
    overrides = ", ".join(f"{k} = {v!r}" for k, v in spec.overrides) or "none"
    episodes = sorted({(r.normal_episodes, r.anomalous_episodes) for r in result.results})
    lines = [
        f"# Sweep: {spec.title}",
        "",
        f"- Axis: `{axis.name}` ({axis.label}); base preset `{spec.base}`; overrides: {overrides}.",
        f"- Dataset seeds: {', '.join(map(str, spec.seeds))}; methods: {', '.join(names)}.",
        f"- Command: `{result.command}`",
        f"- Executor: {result.executor}; wall time {result.seconds:.0f} s; {result.machine}; {result.date}.",
        f"- Cells: AUC (%) with its {100 * CONFIDENCE:.0f} % episode-cluster bootstrap interval, "
        "`AUC [low, high]` (whole test episodes resampled, normal and anomalous separately: "
        + "; ".join(f"{n} normal and {a} anomalous episodes" for n, a in episodes)
        + "); `[n/a]`: too few episodes for an interval.",
        "- Each point is a complete run folder (`points/pNN-seedS/`: dataset, models, results.md); its "
        "dataset comes from the preset recorded in `sweep.json`, so any point can be generated again alone.",
    ]
    for key in reported_keys(result):
        lines += ["", f"## {AUC_TITLES[key]}", "", f"![{key}](figures/{key}.png)", ""]
        lines += auc_table(result, key)
    lines += [
        "",
        "## Points",
        "",
        "| point | preset | folder | dataset sha256 |",
        "| --- | --- | --- | --- |",
    ]
    for r in result.results:
        point = result.points[r.point]
        folder = os.path.relpath(r.folder, result.out.absolute())
        lines.append(f"| {point.label} | `{point.preset.name}` | `{folder}` | `{r.dataset_sha256[:16]}` |")
    return "\n".join(lines) + "\n"


def auc_table(result: SweepResult, key: str) -> list[str]:
    """The markdown table of one AUC: a row per point and dataset seed, a column per method that has it."""
    names = [m for m in _methods(result) if _has(result, m, key)]
    label = {p.index: p.label for p in result.points}
    lines = [
        "| " + " | ".join([result.spec.axis.name, "dataset seed", *names]) + " |",
        "| " + " | ".join(["---"] * (2 + len(names))) + " |",
    ]
    for r in result.results:
        cells = [format_interval(r.methods[m].auc[key]) if m in r.methods else "" for m in names]
        lines.append("| " + " | ".join([label[r.point], str(r.seed), *cells]) + " |")
    return lines


def to_json(result: SweepResult) -> dict[str, Any]:
    """`sweep.json`: the spec, the setting, and every point's AUCs with intervals, per dataset seed."""
    spec = result.spec
    root = result.out.absolute()
    return {
        "title": spec.title,
        "spec": spec.to_dict(),
        "axis": {"name": spec.axis.name, "field": spec.axis.field, "label": spec.axis.label},
        "command": result.command,
        "executor": result.executor,
        "seconds": result.seconds,
        "machine": result.machine,
        "date": result.date,
        "uncertainty": f"AUC with its {100 * CONFIDENCE:.0f} % episode-cluster bootstrap interval "
        "(benchmarks.uncertainty), from each point's results.json",
        "points": [
            {
                "index": p.index,
                "label": p.label,
                "x": p.x,
                "value": list(p.value) if isinstance(p.value, tuple) else p.value,
                "preset": dataclasses.asdict(p.preset),
                "runs": [
                    {
                        "seed": r.seed,
                        "folder": os.path.relpath(r.folder, root),
                        "dataset_sha256": r.dataset_sha256,
                        "normal_episodes": r.normal_episodes,
                        "anomalous_episodes": r.anomalous_episodes,
                        "methods": {
                            name: {
                                **{
                                    key: m.auc[key].to_dict()
                                    for key in (*AUC_KEYS, *KIND_KEYS)
                                    if key in AUC_KEYS or math.isfinite(m.auc[key].value)
                                },
                                "train_seconds": m.train_seconds,
                            }
                            for name, m in r.methods.items()
                        },
                    }
                    for r in result.results
                    if r.point == p.index
                ],
            }
            for p in result.points
        ],
    }


def plot(result: SweepResult, key: str, path: Path) -> None:
    """One PNG: the AUC `key` against the axis, one line per method, intervals as error bars."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    spec, axis = result.spec, result.spec.axis
    groups = _by_point(result)
    points = [p for p in result.points if p.index in groups]
    several = len(spec.seeds) > 1
    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=110)
    try:
        names = [m for m in _methods(result) if _has(result, m, key)]
        width = (max(p.x for p in points) - min(p.x for p in points)) or 1.0
        for i, name in enumerate(names):
            ivs = [combined(groups[p.index], name, key) for p in points]
            shift = (i - (len(names) - 1) / 2) * 0.012 * width  # keep overlapping bars apart
            xs = [p.x + shift for p in points]
            ys = [100 * iv.value for iv in ivs]
            low = [100 * (iv.value - iv.low) if math.isfinite(iv.low) else 0.0 for iv in ivs]
            high = [100 * (iv.high - iv.value) if math.isfinite(iv.high) else 0.0 for iv in ivs]
            ax.errorbar(xs, ys, yerr=[low, high], marker="o", capsize=3, label=name)
        ax.axhline(50.0, color="0.6", linestyle="--", linewidth=1, label="chance")
        ax.set_ylim(0, 102)
        ax.set_ylabel("AUC (%)")
        ax.set_xlabel(axis.label)
        if not axis.numeric:
            ax.set_xticks([p.x for p in points], [p.label for p in points])
        band = "envelope of the per-seed 95 % intervals" if several else "95 % episode-bootstrap interval"
        ax.set_title(f"{spec.title}: {AUC_TITLES[key]}\nbars: {band}", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="lower left")
        fig.tight_layout()
        fig.savefig(path, format="png")
    finally:
        plt.close(fig)
