"""The audit's verdict: one row per probe with its figure, its limit and PASS, FAIL or REPORT (or SKIP: a
probe that could not run on this dataset, with the reason).

The limits are those of the `paper` preset (issue 10 of the project): they are what a benchmark whose
anomalies must be heard or felt, not guessed from context, has to satisfy. On smaller presets the same
probes run and the same limits are shown, but a few episodes cannot meet an interval limit.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from msvdd.atomic import write_text_atomic

PASS, FAIL, REPORT, SKIP = "PASS", "FAIL", "REPORT", "SKIP"

BEHAVIOUR_LIMIT = 0.65
"""Most a behaviour probe (reversing, turning in place, yaw rate) may separate collisions, two-sided AUC."""
NAIVE_OVERALL_LIMIT = 0.72
"""Most a naive audio scalar may separate all anomalies from normal windows, two-sided AUC."""
NAIVE_SUB_KIND_LIMIT = 0.90
"""Most a naive audio scalar may separate any one anomaly sub-kind, two-sided AUC."""
DELETED_LIMIT = 0.60
"""Most the audio-only reference may find anomalies whose own sound was deleted, AUC."""
LEAK_LIMIT = 0.58
"""Most the reference may tell the normal stretches of anomaly episodes from nominal driving, AUC."""
CLIPPING_LIMIT = 0.005
"""Largest share of any class's windows whose peak is within 1 dB of full scale."""
REFERENCE_HALF_WIDTH_LIMIT = 0.03
"""Largest half-width of the reference detector's 95 % episode-cluster bootstrap AUC interval."""
REPETITION_LIMIT = 0.2
"""Largest autocorrelation of an ambience bed at lags beyond 1 s."""
CONTEXT_LIMIT = 0.65
"""Most an episode's context (arena size) may separate anomaly windows from normal ones, two-sided AUC."""


@dataclass(frozen=True)
class ProbeRow:
    """One line of the audit."""

    group: str
    """Family: behaviour, naive, deleted, level, leak, clipping, reference, ambience, context, oracle."""
    probe: str
    """What is measured (a scalar's name, a detector)."""
    target: str
    """Which windows: overall, collision, mechanical, a sub-kind, or a class."""
    figure: float
    """The measured figure (AUC, two-sided AUC, share or half-width; see `unit`)."""
    limit: float | None
    """The largest figure allowed, or None (only reported, or bounded by `floor` alone)."""
    unit: str
    """What `figure` is: `auc`, `auc2` (max(AUC, 1 - AUC)), `share`, `half-width`, `acf`, `dB`, `evidence`
    (a difference of the oracle's scores: summed -log10 tail probabilities)."""
    detail: str = ""
    """Context for a reader: the raw AUC, counts, an interval."""
    skipped: str = ""
    """Why the probe did not run (e.g. imported data has no simulator trace); empty when it ran."""
    floor: float | None = None
    """The smallest figure allowed (a probe that must find something: the fault oracle), or None."""

    @property
    def status(self) -> str:
        """PASS or FAIL against the limit and the floor; REPORT without either (or without data: NaN); SKIP if
        not run."""
        if self.skipped:
            return SKIP
        if (self.limit is None and self.floor is None) or not math.isfinite(self.figure):
            return REPORT
        over = self.limit is not None and self.figure > self.limit
        under = self.floor is not None and self.figure < self.floor
        return FAIL if over or under else PASS

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready, with the status."""
        doc = asdict(self)
        doc["figure"] = self.figure if math.isfinite(self.figure) else None
        doc["status"] = self.status
        return doc


@dataclass(frozen=True)
class AuditResult:
    """Every probe row plus what was audited."""

    dataset: str
    """The dataset folder."""
    preset: str
    """Its preset."""
    seed: int
    """Its seed."""
    rows: tuple[ProbeRow, ...]
    """The probes."""
    seconds: float
    """Wall time of the audit, s."""
    key: str = ""
    """`benchmarks.audit.core.audit_key` of what was audited: `--reuse` reruns the audit unless it matches."""

    @property
    def failed(self) -> list[ProbeRow]:
        """Rows over their limit."""
        return [r for r in self.rows if r.status == FAIL]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {
            "dataset": self.dataset,
            "preset": self.preset,
            "seed": self.seed,
            "seconds": round(self.seconds, 1),
            "key": self.key,
            "passed": not self.failed,
            "probes": [r.to_dict() for r in self.rows],
        }

    @classmethod
    def from_dict(cls, doc: dict[str, Any]) -> AuditResult:
        """The result `to_dict` wrote (statuses are recomputed from figures and limits)."""
        fields = ("group", "probe", "target", "figure", "limit", "unit", "detail", "skipped")
        rows = []
        for probe in doc["probes"]:
            row = {name: probe[name] for name in fields}
            row["floor"] = probe.get("floor")
            row["figure"] = math.nan if row["figure"] is None else float(row["figure"])
            rows.append(ProbeRow(**row))
        seed, seconds = int(doc["seed"]), float(doc["seconds"])
        return cls(doc["dataset"], doc["preset"], seed, tuple(rows), seconds, str(doc["key"]))


def _fmt(x: float | None, unit: str) -> str:
    if x is None or not math.isfinite(x):
        return "n/a"
    if unit == "share":
        return f"{100 * x:.2f} %"
    if unit == "dB":
        return f"{x:+.1f}"
    return f"{x:.3f}"


def _skipped_lines(result: AuditResult) -> list[str]:
    skipped = [r for r in result.rows if r.status == SKIP]
    if not skipped:
        return []
    return ["", f"{len(skipped)} probe(s) skipped, each with its reason in the table:"] + [
        f"- {r.group} / {r.probe}: {r.skipped}" for r in skipped
    ]


def markdown(result: AuditResult) -> str:
    """The audit as a Markdown table, failures listed first in a summary line."""
    lines = [
        f"# Audit of `{result.dataset}` (preset {result.preset}, seed {result.seed})",
        "",
        f"{len(result.rows)} probes, {len(result.failed)} over their limit; {result.seconds:.0f} s.",
        *_skipped_lines(result),
        "",
        "`auc2` is max(AUC, 1 - AUC): a fixed scalar separates in either direction. Limits are the `paper`",
        "preset's.",
        "",
        "| group | probe | windows | figure | unit | limit | status | detail |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in result.rows:
        limit = "-" if r.limit is None else _fmt(r.limit, r.unit)
        if r.floor is not None:
            limit = f">= {_fmt(r.floor, r.unit)}" if r.limit is None else f"{_fmt(r.floor, r.unit)}..{limit}"
        lines.append(
            f"| {r.group} | {r.probe} | {r.target} | {_fmt(r.figure, r.unit)} | {r.unit} | {limit} | "
            f"{r.status} | {r.skipped or r.detail} |"
        )
    return "\n".join(lines) + "\n"


def read(out: Path) -> AuditResult | None:
    """The audit `write` left in `out`, or None if there is none or it cannot be read (then it is rerun)."""
    try:
        return AuditResult.from_dict(json.loads((out / "audit.json").read_text()))
    except (OSError, ValueError, KeyError, TypeError):
        return None


def write(result: AuditResult, out: Path) -> tuple[Path, Path]:
    """Write `audit.json` and `audit.md` into `out` (created if needed), each atomically."""
    out.mkdir(parents=True, exist_ok=True)
    json_path, md_path = out / "audit.json", out / "audit.md"
    write_text_atomic(json_path, json.dumps(result.to_dict(), indent=2) + "\n")
    write_text_atomic(md_path, markdown(result))
    return json_path, md_path
