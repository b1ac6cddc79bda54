"""The regression gate behind `msvdd-bench compare`: did a change make a detector worse, beyond noise?

Two run folders (`results.json`, `scores.csv`) scored on the same dataset (the same `dataset_sha256`
fingerprint, `benchmarks.dataset.dataset_fingerprint`) are paired window by window (`window_id`). For each
compared method and metric (AUC, pAUC at FPR <= 0.1, AUC on collisions, AUC on faults) the difference
candidate - baseline gets its episode-cluster bootstrap 95 % interval from `benchmarks.uncertainty`: the same
episode draws, with the same seed, as the run reports use, for both runs. A method's figure is the mean over
its training seeds of the per-seed figure, in the data and inside each replicate (as in `results.json`);
the two runs may have different seeds.

A gated metric is a **regression** when both hold: the candidate is more than `max_drop` points (percent of
AUC) below the baseline, and the interval of the difference lies wholly below zero. A large drop the data
cannot tell from noise, or a real but small one, is not.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.errors import UserError
from benchmarks.uncertainty import (
    BOOTSTRAP_REPLICATES,
    BOOTSTRAP_SEED,
    CONFIDENCE,
    PAUC_MAX_FPR,
    BootstrapAuc,
    Interval,
    bootstrap_mean_auc,
    bootstrap_mean_pauc,
    episode_draws,
)

METRICS: dict[str, str] = {
    "auc": "AUC",
    "pauc": f"pAUC (FPR <= {PAUC_MAX_FPR:g})",
    "auc_collision": "AUC collisions",
    "auc_mechanical": "AUC faults",
}
"""Every metric compared, by key (the keys of `results.json`), with its label."""

DEFAULT_GATE: tuple[str, ...] = ("auc", "pauc")
"""Metrics whose regression fails the gate unless `--gate` says otherwise."""

DEFAULT_MAX_DROP = 1.0
"""Tolerated drop, in points (percent of AUC), unless `--max-drop` says otherwise."""

SCORE_COLUMNS: tuple[str, ...] = ("window_id", "method", "score", "label", "kind", "seed", "episode")
"""Columns of `scores.csv` the comparison reads."""


class CompareError(UserError):
    """Two runs cannot be compared (missing or malformed files, other datasets, no common method)."""


@dataclass(frozen=True)
class GateConfig:
    """What counts as a regression."""

    max_drop: float = DEFAULT_MAX_DROP
    """Tolerated drop of a gated metric, points (percent of AUC); must be >= 0."""
    gate: tuple[str, ...] = DEFAULT_GATE
    """Metric keys (of `METRICS`) that decide the exit code; the others are reported only."""
    replicates: int = BOOTSTRAP_REPLICATES
    """Bootstrap replicates (the run reports' number)."""
    seed: int = BOOTSTRAP_SEED
    """Seed of the episode draws (the run reports' seed)."""

    def __post_init__(self) -> None:
        """Refuse a negative or non-finite tolerance, an unknown or empty gate, too few replicates."""
        if not (math.isfinite(self.max_drop) and self.max_drop >= 0):
            raise CompareError(f"--max-drop must be a number of points >= 0, got {self.max_drop}")
        unknown = [k for k in self.gate if k not in METRICS]
        if unknown or not self.gate:
            raise CompareError(f"--gate {' '.join(self.gate)}: allowed metrics are {', '.join(METRICS)}")
        if self.replicates < 100:
            raise CompareError(f"bootstrap replicates must be >= 100, got {self.replicates}")


@dataclass(frozen=True)
class RunScores:
    """A run folder read back: its dataset's identity and every method's per-window scores."""

    path: Path
    """The run folder."""
    fingerprint: str
    """`dataset_sha256` of `results.json`."""
    preset: str
    """Dataset preset of the run."""
    dataset_seed: int
    """Dataset seed of the run."""
    window_ids: np.ndarray
    """(n,) scored test window ids, ascending."""
    positive: np.ndarray
    """(n,) bool, the anomalous windows."""
    kinds: np.ndarray
    """(n,) window kinds (`normal`, `collision`, `mechanical`)."""
    episodes: np.ndarray
    """(n,) episode of each window (the bootstrap's clusters)."""
    scores: dict[str, np.ndarray]
    """Method -> (S, n) scores of its S training seeds, in `window_ids` order."""
    seeds: dict[str, tuple[int, ...]]
    """Method -> its training seeds, in the order of the rows of `scores`."""


def read_run(path: Path) -> RunScores:
    """Read a run folder written by `run` or `evaluate`; CompareError naming the file if it cannot be used."""
    path = Path(path)
    results, scores_path = path / "results.json", path / "scores.csv"
    for file in (results, scores_path):
        if not file.is_file():
            raise CompareError(f"{path} is not a run folder: {file.name} is missing")
    try:
        doc = json.loads(results.read_text())
    except json.JSONDecodeError as exc:
        raise CompareError(f"{results} is not valid JSON: {exc}") from exc
    fingerprint = doc.get("dataset_sha256") if isinstance(doc, dict) else None
    if not fingerprint:
        raise CompareError(
            f"{results} records no dataset fingerprint (dataset_sha256): the run was written by an older "
            "version; run it again (or `msvdd-bench evaluate` its models) with this version"
        )
    windows: dict[int, tuple[bool, str, str]] = {}
    table: dict[str, dict[int, dict[int, float]]] = {}
    with open(scores_path, newline="") as handle:
        reader = csv.DictReader(handle)
        missing = [c for c in SCORE_COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            raise CompareError(f"{scores_path} lacks the column(s) {', '.join(missing)}")
        for line, row in enumerate(reader, start=2):
            try:
                window, seed, score = int(row["window_id"]), int(row["seed"]), float(row["score"])
            except (TypeError, ValueError) as exc:
                raise CompareError(f"{scores_path}, line {line}: {exc}") from exc
            info = (row["label"] == "1", row["kind"], row["episode"])
            if windows.setdefault(window, info) != info:
                raise CompareError(f"{scores_path}, line {line}: window {window} changes label or episode")
            per_seed = table.setdefault(row["method"], {}).setdefault(seed, {})
            if window in per_seed:
                raise CompareError(f"{scores_path}, line {line}: window {window} scored twice")
            per_seed[window] = score
    if not table:
        raise CompareError(f"{scores_path} holds no scores")
    ids = np.array(sorted(windows), dtype=np.int64)
    scores: dict[str, np.ndarray] = {}
    seeds: dict[str, tuple[int, ...]] = {}
    for method, by_seed in table.items():
        for seed, per in by_seed.items():
            if len(per) != ids.size:
                raise CompareError(
                    f"{scores_path}: {method} seed {seed} scores {len(per)} of the {ids.size} windows"
                )
        seeds[method] = tuple(sorted(by_seed))
        scores[method] = np.array([[by_seed[s][i] for i in ids] for s in seeds[method]], dtype=np.float64)
    return RunScores(
        path=path,
        fingerprint=str(fingerprint),
        preset=str(doc.get("preset")),
        dataset_seed=int(doc.get("seed", -1)),
        window_ids=ids,
        positive=np.array([windows[i][0] for i in ids], dtype=bool),
        kinds=np.array([windows[i][1] for i in ids]).astype(str),
        episodes=np.array([windows[i][2] for i in ids]).astype(str),
        scores=scores,
        seeds=seeds,
    )


def check_same_dataset(baseline: RunScores, candidate: RunScores) -> None:
    """Refuse runs scored on different datasets (fingerprints) or on different windows of one."""
    if baseline.fingerprint != candidate.fingerprint:
        raise CompareError(
            "the runs were scored on different datasets: baseline "
            f"{baseline.path} on {baseline.fingerprint} (preset {baseline.preset}, seed "
            f"{baseline.dataset_seed}), candidate {candidate.path} on {candidate.fingerprint} (preset "
            f"{candidate.preset}, seed {candidate.dataset_seed}); run both on one dataset "
            "(the same --data or --cache)"
        )
    same = (
        np.array_equal(baseline.window_ids, candidate.window_ids)
        and np.array_equal(baseline.positive, candidate.positive)
        and np.array_equal(baseline.kinds, candidate.kinds)
        and np.array_equal(baseline.episodes, candidate.episodes)
    )
    if not same:
        raise CompareError(
            f"{baseline.path} and {candidate.path} name the same dataset but scored other windows "
            "(edited scores.csv?)"
        )


def pair_methods(
    baseline: RunScores,
    candidate: RunScores,
    methods: Sequence[str] | None = None,
    baseline_method: str | None = None,
) -> list[tuple[str, str]]:
    """(candidate method, baseline method) pairs: the given ones, or every method both runs have."""
    if baseline_method is not None and (methods is None or len(methods) != 1):
        raise CompareError("--baseline-method needs exactly one --method (the candidate's)")
    if not methods:
        pairs = [(m, m) for m in candidate.scores if m in baseline.scores]
        if not pairs:
            raise CompareError(
                f"no method is in both runs: baseline has {', '.join(baseline.scores)}; candidate has "
                f"{', '.join(candidate.scores)}"
            )
        return pairs
    pairs = []
    for method in methods:
        base = baseline_method or method
        if method not in candidate.scores:
            raise CompareError(
                f"--method {method}: not in the candidate run {candidate.path} "
                f"(it has {', '.join(candidate.scores)})"
            )
        if base not in baseline.scores:
            raise CompareError(
                f"method {base}: not in the baseline run {baseline.path} "
                f"(it has {', '.join(baseline.scores)})"
            )
        pairs.append((method, base))
    return pairs


@dataclass(frozen=True)
class MetricComparison:
    """One metric of one method pair."""

    key: str
    """Metric key (of `METRICS`)."""
    baseline: float
    """The baseline's seed-mean value."""
    candidate: float
    """The candidate's seed-mean value."""
    difference: Interval
    """Candidate - baseline with its paired 95 % interval (NaN ends: too few episodes)."""
    gated: bool
    """Whether this metric decides the exit code."""
    regression: bool
    """Gated, more than `max_drop` points down, and the interval wholly below zero."""

    @property
    def verdict(self) -> str:
        """`REGRESSION`, `worse, within --max-drop`, `within noise`, `better`, `identical` or `n/a`."""
        d = self.difference
        if not (math.isfinite(d.low) and math.isfinite(d.high)):
            return "n/a"
        if d.value == d.low == d.high == 0.0:
            return "identical"
        if self.regression:
            return "REGRESSION"
        if d.high < 0:
            return "worse, within --max-drop" if self.gated else "worse"
        return "better" if d.low > 0 else "within noise"


@dataclass(frozen=True)
class MethodComparison:
    """The comparison of one method of the candidate run with one of the baseline run."""

    method: str
    """The candidate's method."""
    baseline_method: str
    """The baseline's method (usually the same name)."""
    baseline_seeds: tuple[int, ...]
    """Training seeds of the baseline."""
    candidate_seeds: tuple[int, ...]
    """Training seeds of the candidate."""
    metrics: tuple[MetricComparison, ...]
    """Every metric of `METRICS`."""

    @property
    def regression(self) -> bool:
        """Whether any gated metric regressed."""
        return any(m.regression for m in self.metrics)


@dataclass(frozen=True)
class Comparison:
    """Everything `compare` reports."""

    baseline: RunScores
    """The baseline run."""
    candidate: RunScores
    """The candidate run."""
    config: GateConfig
    """The gate."""
    methods: tuple[MethodComparison, ...]
    """One entry per compared method pair."""

    @property
    def regression(self) -> bool:
        """Whether any compared method regressed."""
        return any(m.regression for m in self.methods)

    @property
    def exit_code(self) -> int:
        """1 on a regression, else 0."""
        return 1 if self.regression else 0


def _subsets(run: RunScores) -> dict[str, np.ndarray]:
    normal = run.kinds == "normal"
    every = np.ones(run.kinds.size, dtype=bool)
    return {
        "auc": every,
        "pauc": every,
        "auc_collision": normal | (run.kinds == "collision"),
        "auc_mechanical": normal | (run.kinds == "mechanical"),
    }


def compare_runs(
    baseline: RunScores, candidate: RunScores, pairs: Sequence[tuple[str, str]], config: GateConfig
) -> Comparison:
    """Paired differences of every metric of every (candidate, baseline) method pair, and the verdicts.

    Raises:
        CompareError: other datasets or windows, or a gated metric without an interval (too few episodes).
    """
    check_same_dataset(baseline, candidate)
    found: dict[tuple[str, str], list[MetricComparison]] = {pair: [] for pair in pairs}
    for key, keep in _subsets(candidate).items():
        positive, clusters = candidate.positive[keep], candidate.episodes[keep]
        weights = episode_draws(clusters, positive, config.replicates, config.seed)
        for method, base in pairs:
            b = _bootstrap(key, baseline.scores[base][:, keep], positive, clusters, weights)
            c = _bootstrap(key, candidate.scores[method][:, keep], positive, clusters, weights)
            diff = c.minus(b)
            gated = key in config.gate
            if gated and not (math.isfinite(diff.low) and math.isfinite(diff.high)):
                raise CompareError(
                    f"{METRICS[key]} of {method} has no interval: the test set needs at least two normal and "
                    f"two anomalous episodes for it; leave {key} out of --gate or use a larger preset"
                )
            regression = gated and diff.value < -config.max_drop / 100.0 and diff.high < 0.0
            found[(method, base)].append(MetricComparison(key, b.value, c.value, diff, gated, regression))
    return Comparison(
        baseline=baseline,
        candidate=candidate,
        config=config,
        methods=tuple(
            MethodComparison(m, b, baseline.seeds[b], candidate.seeds[m], tuple(found[(m, b)]))
            for m, b in pairs
        ),
    )


def _bootstrap(
    key: str, scores: np.ndarray, positive: np.ndarray, clusters: np.ndarray, weights: np.ndarray
) -> BootstrapAuc:
    if key == "pauc":
        return bootstrap_mean_pauc(scores, positive, clusters, weights, PAUC_MAX_FPR)
    return bootstrap_mean_auc(scores, positive, clusters, weights)


def _pct(v: float, signed: bool = False) -> str:
    if not math.isfinite(v):
        return "n/a"
    return f"{100.0 * v:+.1f}" if signed else f"{100.0 * v:.1f}"


def summary(comparison: Comparison) -> str:
    """One line: the verdict and what decided it."""
    cfg = comparison.config
    bad = [
        f"{mc.method} {METRICS[m.key]} {_pct(m.difference.value, True)} points "
        f"[{_pct(m.difference.low, True)}, {_pct(m.difference.high, True)}]"
        for mc in comparison.methods
        for m in mc.metrics
        if m.regression
    ]
    if bad:
        return (
            f"REGRESSION (exit 1): {'; '.join(bad)}: more than {cfg.max_drop:g} points down and the "
            f"{100 * CONFIDENCE:.0f} % interval of the difference excludes zero"
        )
    return (
        f"no regression (exit 0): no gated metric ({', '.join(cfg.gate)}) of "
        f"{len(comparison.methods)} method(s) is more than {cfg.max_drop:g} points down with an interval "
        "that excludes zero"
    )


def markdown_table(comparison: Comparison) -> str:
    """The comparison as a markdown table with a header and the verdict."""
    b, c, cfg = comparison.baseline, comparison.candidate, comparison.config
    normal = b.kinds == "normal"
    lines = [
        f"Baseline `{b.path}`, candidate `{c.path}`; dataset preset {c.preset}, seed {c.dataset_seed}, "
        f"fingerprint {c.fingerprint[:16]}; {c.window_ids.size} test windows from "
        f"{len(set(c.episodes[normal]))} normal and {len(set(c.episodes[~normal]))} anomalous episodes.",
        "Δ = candidate - baseline in points, with its paired episode-cluster bootstrap "
        f"{100 * CONFIDENCE:.0f} % interval ({cfg.replicates} replicates). Gate: {', '.join(cfg.gate)}; "
        f"a regression is more than {cfg.max_drop:g} points down with an interval wholly below zero.",
        "",
        "| Method | Metric | Baseline (%) | Candidate (%) | Δ (points) | Gated | Verdict |",
        "|---|---|---|---|---|---|---|",
    ]
    for mc in comparison.methods:
        name = mc.method if mc.method == mc.baseline_method else f"{mc.method} vs {mc.baseline_method}"
        for m in mc.metrics:
            d = m.difference
            cells = [
                f"`{name}`",
                METRICS[m.key],
                _pct(m.baseline),
                _pct(m.candidate),
                f"{_pct(d.value, True)} [{_pct(d.low, True)}, {_pct(d.high, True)}]",
                "yes" if m.gated else "no",
                f"**{m.verdict}**" if m.regression else m.verdict,
            ]
            lines.append("| " + " | ".join(cells) + " |")
    differing = [mc.method for mc in comparison.methods if mc.baseline_seeds != mc.candidate_seeds]
    if differing:
        lines += ["", f"Training seeds differ for {', '.join(differing)}: each side is its own seed mean."]
    only_b = sorted(set(b.scores) - {mc.baseline_method for mc in comparison.methods})
    only_c = sorted(set(c.scores) - {mc.method for mc in comparison.methods})
    if only_b or only_c:
        lines += ["", f"Not compared: baseline only {only_b or '-'}; candidate only {only_c or '-'}."]
    return "\n".join([*lines, "", summary(comparison), ""])


def to_json(comparison: Comparison) -> dict[str, Any]:
    """The comparison as a JSON-ready dict (what `--json` writes)."""
    b, c, cfg = comparison.baseline, comparison.candidate, comparison.config

    def run(r: RunScores) -> dict[str, Any]:
        return {"run": str(r.path), "preset": r.preset, "seed": r.dataset_seed, "methods": list(r.scores)}

    return {
        "baseline": run(b),
        "candidate": run(c),
        "dataset_sha256": c.fingerprint,
        "windows": int(c.window_ids.size),
        "rule": "a gated metric regresses when candidate - baseline is below -max_drop_points/100 and the "
        "interval of the difference lies wholly below zero; exit 1 if any does",
        "max_drop_points": cfg.max_drop,
        "gate": list(cfg.gate),
        "bootstrap": {
            "method": "episode-cluster bootstrap, the run reports' draws; paired (the same draws for both "
            "runs); each side the mean over its training seeds",
            "replicates": cfg.replicates,
            "seed": cfg.seed,
            "confidence": CONFIDENCE,
            "pauc_max_fpr": PAUC_MAX_FPR,
        },
        "methods": [
            {
                "method": mc.method,
                "baseline_method": mc.baseline_method,
                "baseline_seeds": list(mc.baseline_seeds),
                "candidate_seeds": list(mc.candidate_seeds),
                "regression": mc.regression,
                "metrics": {
                    m.key: {
                        "baseline": _clean(m.baseline),
                        "candidate": _clean(m.candidate),
                        "difference": m.difference.to_dict(),
                        "gated": m.gated,
                        "regression": m.regression,
                        "verdict": m.verdict,
                    }
                    for m in mc.metrics
                },
            }
            for mc in comparison.methods
        ],
        "regression": comparison.regression,
        "exit_code": comparison.exit_code,
        "summary": summary(comparison),
    }


def _clean(v: float) -> float | None:
    return v if math.isfinite(v) else None
