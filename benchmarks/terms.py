"""The fusion ablation of the frame-density references, untrained: `msvdd-bench terms MODEL... --data DIR`.

`context-net-frames` scores a window by the sum of two terms, the log-mel frames' and the IMU frames'
(`ContextNetFrames.modality_scores`), each fitted on its own
modality only and divided by its own training mean. A term alone is therefore exactly that reference's
single-modality detector (the same fit; the scale does not change an AUC), and one scoring of the test split
gives audio alone, IMU alone and their fusion: each one's AUC with its episode-cluster bootstrap interval and
the paired differences fusion - audio and fusion - IMU on the same episode draws, over all anomalies, per test
kind and per anomaly sub-kind. Several models (training seeds of one method) give seed means, as
`msvdd-bench evaluate` does; the same models and dataset give the same report.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from benchmarks import methods
from benchmarks.dataset import open_dataset
from benchmarks.errors import UserError
from benchmarks.methods.frames import MODALITY_NAMES, ContextNetFrames
from benchmarks.modalities import require_modalities
from benchmarks.pipeline import test_windows
from benchmarks.uncertainty import (
    Interval,
    excludes_zero,
    format_interval,
    mean_auc_interval,
    paired_mean_auc_difference,
)

FUSION = "fusion"
"""Name of the summed score (the model's own) beside the `MODALITY_NAMES` terms."""
KINDS: tuple[str, ...] = ("collision", "mechanical")
"""Anomalous test kinds, in report order."""


@dataclass(frozen=True)
class GroupTerms:
    """The terms' AUCs on one group of anomalous windows against every normal test window."""

    group: str
    """"all anomalies", a test kind, or an anomaly sub-kind."""
    kind: str
    """The group's test kind ("all" for all anomalies)."""
    windows: int
    """Anomalous windows in the group."""
    episodes: int
    """Episodes they come from (the bootstrap's clusters)."""
    auc: dict[str, Interval]
    """Each modality's term and the fusion -> seed-mean AUC with its interval."""
    fusion_minus: dict[str, Interval]
    """Each modality -> paired seed-mean AUC difference, fusion minus that term alone."""


@dataclass(frozen=True)
class TermsReport:
    """Everything `msvdd-bench terms` reports."""

    method: str
    """Registry name of the models' method."""
    models: list[str]
    """Model folders (training seeds), in the order given."""
    dataset: str
    """Dataset folder."""
    fingerprint: str
    """The dataset's fingerprint."""
    normal_windows: int
    """Normal test windows (the negatives of every group)."""
    normal_episodes: int
    """Episodes they come from."""
    groups: list[GroupTerms]
    """All anomalies, then each kind and its sub-kinds."""


def frame_methods() -> list[str]:
    """Registered methods whose detectors score by modality terms (`ContextNetFrames`)."""
    return [n for n in methods.names() if issubclass(methods.spec(n).cls, ContextNetFrames)]


def load_references(model_dirs: Sequence[Path]) -> tuple[str, list[ContextNetFrames]]:
    """(method, detectors) of model folders of one frame-density method; UserError naming the folder else."""
    if not model_dirs:
        raise UserError("terms needs at least one model folder")
    name, detectors = "", []
    for folder in model_dirs:
        method, detector = methods.load_detector(folder)
        if not isinstance(detector, ContextNetFrames):
            raise UserError(
                f"{folder} holds method {method!r}, whose score is not a sum of modality terms; terms reads "
                f"the frame-density references only: {', '.join(frame_methods())} (for M-SVDD's own terms "
                "see `msvdd-bench diagnose`)"
            )
        if name and method != name:
            raise UserError(
                f"{folder} holds method {method!r} but {model_dirs[0]} holds {name!r}; give the training "
                "seeds of one method"
            )
        name = method
        detectors.append(detector)
    return name, detectors


def _group(
    name: str,
    kind: str,
    mask: np.ndarray,
    normal: np.ndarray,
    candidates: dict[str, np.ndarray],
    clusters: np.ndarray,
) -> GroupTerms:
    keep = mask | normal
    pos, cl = mask[keep], clusters[keep]
    auc = {key: mean_auc_interval(s[:, keep], pos, cl) for key, s in candidates.items()}
    minus = {
        key: paired_mean_auc_difference(candidates[FUSION][:, keep], candidates[key][:, keep], pos, cl)
        for key in MODALITY_NAMES
    }
    return GroupTerms(name, kind, int(mask.sum()), len(set(clusters[mask])), auc, minus)


def group_terms(
    terms: np.ndarray, kinds: np.ndarray, sub_kinds: np.ndarray, clusters: np.ndarray
) -> list[GroupTerms]:
    """The groups of a report from (S, n, modalities) terms of n test windows of the given kinds ("normal",
    `KINDS`), sub-kinds and episodes: all anomalies, then each kind present and its sub-kinds."""
    candidates = {key: terms[:, :, m] for m, key in enumerate(MODALITY_NAMES)}
    candidates[FUSION] = terms.sum(axis=2)
    normal = kinds == "normal"
    groups = [_group("all anomalies", "all", ~normal, normal, candidates, clusters)]
    for kind in KINDS:
        of_kind = kinds == kind
        if not of_kind.any():
            continue
        groups.append(_group(kind, kind, of_kind, normal, candidates, clusters))
        for sub in sorted(set(sub_kinds[of_kind])):
            groups.append(_group(sub, kind, of_kind & (sub_kinds == sub), normal, candidates, clusters))
    return groups


def modality_terms(
    model_dirs: Sequence[Path], data_dir: Path, verify: bool = False, progress: bool = False
) -> TermsReport:
    """Score the whole test split of `data_dir` by every model's modality terms and compare them with their
    sum.

    Raises:
        UserError: a model that is not a frame-density reference, models of two methods, or a dataset
            without the IMU or without both nominal and anomalous test windows.
    """
    name, detectors = load_references(model_dirs)
    dataset = open_dataset(data_dir, verify=verify, progress=progress)
    require_modalities(dataset.path, dataset.modalities, name)
    windows, rows = test_windows(dataset, progress=progress)
    terms = np.stack([d.modality_scores(windows) for d in detectors])  # (S, n, modalities)
    kinds = np.array([r.kind for r in rows], dtype=str)
    clusters = np.array([r.episode for r in rows], dtype=str)
    normal = kinds == "normal"
    groups = group_terms(terms, kinds, np.array([r.sub_kind for r in rows], dtype=str), clusters)
    return TermsReport(
        method=name,
        models=[str(p) for p in model_dirs],
        dataset=str(data_dir),
        fingerprint=dataset.fingerprint,
        normal_windows=int(normal.sum()),
        normal_episodes=len(set(clusters[normal])),
        groups=groups,
    )


def terms_json(report: TermsReport) -> str:
    """The report as JSON (AUCs as fractions; an undefined interval as null)."""
    doc = {
        "method": report.method,
        "models": report.models,
        "dataset": report.dataset,
        "fingerprint": report.fingerprint,
        "normal_windows": report.normal_windows,
        "normal_episodes": report.normal_episodes,
        "groups": [
            {
                "group": g.group,
                "kind": g.kind,
                "windows": g.windows,
                "episodes": g.episodes,
                "auc": {k: v.to_dict() for k, v in g.auc.items()},
                "fusion_minus": {k: v.to_dict() for k, v in g.fusion_minus.items()},
            }
            for g in report.groups
        ],
    }
    return json.dumps(doc, indent=2) + "\n"


def _difference(iv: Interval) -> str:
    text = format_interval(iv, signed=True)
    return f"**{text}**" if excludes_zero(iv) else text


def _verdict(report: TermsReport) -> str:
    overall = report.groups[0]
    shown = [k for k, iv in overall.fusion_minus.items() if math.isfinite(iv.low) and iv.low > 0]
    behind = [k for k, iv in overall.fusion_minus.items() if math.isfinite(iv.high) and iv.high < 0]
    parts = []
    if shown:
        parts.append("fusion is ahead of " + " and of ".join(shown) + " alone (interval above 0)")
    if behind:
        parts.append("fusion is behind " + " and ".join(behind) + " alone (interval below 0)")
    rest = [k for k in MODALITY_NAMES if k not in shown and k not in behind]
    if rest:
        parts.append("against " + " and ".join(rest) + " alone the difference is inside its interval")
    return "Over all anomalies " + "; ".join(parts) + "."


def terms_markdown(report: TermsReport) -> str:
    """The report as markdown (ends with a newline)."""
    names = [*MODALITY_NAMES, FUSION]
    lines = [
        f"# Modality terms of `{report.method}` ({len(report.models)} model(s))",
        "",
        f"Dataset `{report.dataset}` (fingerprint `{report.fingerprint[:8]}...`); every group's anomalous "
        f"windows against the {report.normal_windows} normal test windows ({report.normal_episodes} "
        "episodes). AUC % with its episode-cluster bootstrap 95 % interval, the mean over the models; "
        "differences are paired (the same episode draws), bold where the interval excludes 0. `audio`: "
        "the log-mel frames' term alone; `imu`: the IMU frames' term alone; `fusion`: their sum, the "
        "model's score.",
        "",
        "| group | windows (episodes) | "
        + " | ".join(names)
        + " | "
        + " | ".join(f"{FUSION} - {m}" for m in MODALITY_NAMES)
        + " |",
        "|---|---:|" + "---|" * (len(names) + len(MODALITY_NAMES)),
    ]
    for g in report.groups:
        label = g.group if g.group in ("all anomalies", *KINDS) else f"- {g.group}"
        lines.append(
            f"| {label} | {g.windows} ({g.episodes}) | "
            + " | ".join(format_interval(g.auc[k]) for k in names)
            + " | "
            + " | ".join(_difference(g.fusion_minus[k]) for k in MODALITY_NAMES)
            + " |"
        )
    lines += ["", _verdict(report), ""]
    return "\n".join(lines)
