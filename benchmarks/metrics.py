"""Honest detection metrics on plain arrays: thresholded P/R/F1, oracle best F1, ROC-AUC, pAUC, delays.

Labels are 1 for anomalous windows and 0 for normal ones; scores are higher = more anomalous. The
thresholded metrics use the detector's `threshold_` (from nominal data only); `f1_oracle` is the best
F1 over every threshold on the test precision-recall curve (the paper's protocol) and is named oracle
because it sees the test labels. Every function here is checked against scikit-learn in the tests.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields
from typing import Any

import numpy as np

NORMAL_KIND = "normal"
COLLISION_KIND = "collision"
MECHANICAL_KIND = "mechanical"


def _binary(
    labels: np.ndarray | Sequence[int], scores: np.ndarray | Sequence[float]
) -> tuple[np.ndarray, np.ndarray]:
    y = np.asarray(labels)
    s = np.asarray(scores, dtype=np.float64)
    if y.ndim != 1 or s.shape != y.shape:
        raise ValueError(f"labels {y.shape} and scores {s.shape} must be 1-D of the same length")
    if not np.all(np.isin(y, (0, 1))):
        raise ValueError("labels must be 0 (normal) or 1 (anomalous)")
    if not np.all(np.isfinite(s)):
        raise ValueError("scores hold NaN or inf")
    return y.astype(bool), s


def precision_recall_f1(
    labels: np.ndarray | Sequence[int], scores: np.ndarray | Sequence[float], threshold: float
) -> tuple[float, float, float]:
    """Precision, recall and F1 of the flags `score > threshold` (0 where undefined)."""
    y, s = _binary(labels, scores)
    flags = s > threshold
    tp = float(np.sum(flags & y))
    fp = float(np.sum(flags & ~y))
    fn = float(np.sum(~flags & y))
    precision = tp / (tp + fp) if tp + fp > 0 else 0.0
    recall = tp / (tp + fn) if tp + fn > 0 else 0.0
    f1 = 2 * tp / (2 * tp + fp + fn) if tp > 0 else 0.0
    return precision, recall, f1


def _ranked_counts(y: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cumulative true and false positives flagging `score >= t` for each distinct score t, descending."""
    order = np.argsort(-s, kind="mergesort")
    s_sorted, y_sorted = s[order], y[order]
    last_of_tie = np.r_[np.flatnonzero(np.diff(s_sorted)), y.size - 1]
    tps = np.cumsum(y_sorted)[last_of_tie].astype(np.float64)
    fps = (last_of_tie + 1) - tps
    return tps, fps, s_sorted[last_of_tie]


def f1_oracle(
    labels: np.ndarray | Sequence[int], scores: np.ndarray | Sequence[float]
) -> tuple[float, float]:
    """ORACLE best F1 over every threshold of the test precision-recall curve, and that threshold.

    It sees the test labels: report it next to, never instead of, the F1 at the detector's threshold.
    The threshold t means flags `score >= t`.
    """
    y, s = _binary(labels, scores)
    if not y.any():
        raise ValueError("f1_oracle needs at least one anomalous window")
    tps, fps, thresholds = _ranked_counts(y, s)
    f1 = 2 * tps / (tps + fps + y.sum())
    best = int(np.argmax(f1))
    return float(f1[best]), float(thresholds[best])


def roc_curve(
    labels: np.ndarray | Sequence[int], scores: np.ndarray | Sequence[float]
) -> tuple[np.ndarray, np.ndarray]:
    """(fpr, tpr) at every distinct score, starting at (0, 0) and ending at (1, 1)."""
    y, s = _binary(labels, scores)
    n_pos, n_neg = int(y.sum()), int((~y).sum())
    if n_pos == 0 or n_neg == 0:
        raise ValueError(f"ROC needs both classes; got {n_pos} anomalous and {n_neg} normal windows")
    tps, fps, _ = _ranked_counts(y, s)
    return np.r_[0.0, fps / n_neg], np.r_[0.0, tps / n_pos]


def roc_auc(
    labels: np.ndarray | Sequence[int], scores: np.ndarray | Sequence[float], max_fpr: float | None = None
) -> float:
    """Area under the ROC curve (ties count one half).

    With `max_fpr`, the partial AUC over FPR <= max_fpr with McClish's standardisation, exactly as
    `sklearn.metrics.roc_auc_score(..., max_fpr=...)` (the DCASE pAUC convention): 0.5 is chance, 1 perfect.
    """
    fpr, tpr = roc_curve(labels, scores)
    if max_fpr is None or max_fpr == 1.0:
        return float(np.trapezoid(tpr, fpr))
    if not 0.0 < max_fpr <= 1.0:
        raise ValueError(f"max_fpr must be in (0, 1], got {max_fpr}")
    stop = int(np.searchsorted(fpr, max_fpr, side="right"))
    x_interp = [fpr[stop - 1], fpr[stop]]
    y_interp = [tpr[stop - 1], tpr[stop]]
    tpr_part = np.append(tpr[:stop], np.interp(max_fpr, x_interp, y_interp))
    fpr_part = np.append(fpr[:stop], max_fpr)
    partial = float(np.trapezoid(tpr_part, fpr_part))
    min_area = 0.5 * max_fpr**2
    return 0.5 * (1.0 + (partial - min_area) / (max_fpr - min_area))


def auc_normal_vs(
    scores: np.ndarray | Sequence[float],
    groups: np.ndarray | Sequence[str],
    positive: str,
    normal: str = NORMAL_KIND,
    kinds: np.ndarray | Sequence[str] | None = None,
) -> float:
    """ROC-AUC of the normal windows against the windows whose group is `positive`, others left out.

    `groups` holds a kind or a sub-kind per window; normal windows are those with `kinds == normal`
    (or `groups == normal` when `kinds` is not given). NaN when either side is empty.
    """
    s = np.asarray(scores, dtype=np.float64)
    g = np.asarray(groups).astype(str)
    k = g if kinds is None else np.asarray(kinds).astype(str)
    if g.shape != s.shape or k.shape != s.shape:
        raise ValueError(f"scores {s.shape}, groups {g.shape} and kinds {k.shape} must have the same shape")
    is_normal = k == normal
    is_pos = (g == positive) & ~is_normal
    if not is_normal.any() or not is_pos.any():
        return math.nan
    keep = is_normal | is_pos
    return roc_auc(is_pos[keep].astype(int), s[keep])


def detection_delays(
    window_episode: np.ndarray | Sequence[Any],
    window_start: np.ndarray | Sequence[float],
    flags: np.ndarray | Sequence[bool],
    event_episode: np.ndarray | Sequence[Any],
    event_onset: np.ndarray | Sequence[float],
    window_s: float = 2.0,
    max_delay_s: float = 10.0,
) -> np.ndarray:
    """Seconds from each event's onset to the end of the first flagged window overlapping or following it.

    A window [start, start + window_s) of the event's episode qualifies if it ends after the onset and
    starts no later than onset + max_delay_s; the detection time is the window's end, when a causal
    detector has seen it, so the delay is never negative. NaN for an event no qualifying window flags.

    Returns:
        (n_events,) float64 delays.
    """
    w_ep = np.asarray(window_episode)
    w_start = np.asarray(window_start, dtype=np.float64)
    f = np.asarray(flags, dtype=bool)
    e_ep = np.asarray(event_episode)
    onset = np.asarray(event_onset, dtype=np.float64)
    if not (w_ep.shape == w_start.shape == f.shape) or w_ep.ndim != 1:
        raise ValueError(
            f"window_episode {w_ep.shape}, window_start {w_start.shape}, flags {f.shape} must match"
        )
    if e_ep.shape != onset.shape or e_ep.ndim != 1:
        raise ValueError(
            f"event_episode {e_ep.shape} and event_onset {onset.shape} must be 1-D of one length"
        )
    w_end = w_start + window_s
    ok = (
        (e_ep[:, None] == w_ep[None, :])
        & f[None, :]
        & (w_end[None, :] > onset[:, None])
        & (w_start[None, :] <= onset[:, None] + max_delay_s)
    )
    first_end = np.where(ok, w_end[None, :], np.inf).min(axis=1, initial=np.inf)
    return np.where(np.isfinite(first_end), first_end - onset, np.nan)


def mean_std(values: Sequence[float] | np.ndarray) -> tuple[float, float]:
    """Mean and sample standard deviation (ddof=1; 0 for one value) over seeds, ignoring NaN."""
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return math.nan, math.nan
    return float(v.mean()), float(v.std(ddof=1)) if v.size > 1 else 0.0


@dataclass(frozen=True)
class MethodMetrics:
    """Every metric of one method on one test set (NaN where undefined, e.g. no collision windows)."""

    auc: float
    """ROC-AUC, normal against every anomaly."""
    auc_collision: float
    """ROC-AUC, normal against collision windows only."""
    auc_mechanical: float
    """ROC-AUC, normal against mechanical-fault windows only."""
    pauc: float
    """Partial ROC-AUC at FPR <= max_fpr, McClish-standardised (DCASE convention)."""
    precision: float
    """Precision at the detector's threshold."""
    recall: float
    """Recall at the detector's threshold."""
    f1: float
    """F1 at the detector's threshold."""
    f1_oracle: float
    """ORACLE best F1 over the test precision-recall curve (sees test labels; the paper's protocol)."""
    threshold: float
    """The detector's threshold used for precision, recall, F1 and delays."""
    threshold_oracle: float
    """The test-label threshold that gives `f1_oracle` (flags score >= it)."""
    false_alarm_rate: float
    """Fraction of normal test windows flagged at the detector's threshold."""
    n_normal: int
    """Normal test windows."""
    n_collision: int
    """Collision test windows."""
    n_mechanical: int
    """Mechanical-fault test windows."""
    auc_by_sub_kind: dict[str, float] = field(default_factory=dict)
    """ROC-AUC of normal against each anomalous sub-kind present (obstacle or fault kind)."""
    delay_mean_s: float = math.nan
    """Mean detection delay over detected events, s (NaN without event timing)."""
    delay_median_s: float = math.nan
    """Median detection delay over detected events, s."""
    detection_rate: float = math.nan
    """Fraction of events flagged within the delay horizon."""
    n_events: int = 0
    """Events with timing given."""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (NaN becomes None)."""

        def clean(v: Any) -> Any:
            if isinstance(v, float) and not math.isfinite(v):
                return None
            if isinstance(v, dict):
                return {k: clean(x) for k, x in v.items()}
            return v

        return {k: clean(v) for k, v in asdict(self).items()}


SCALAR_METRICS: tuple[str, ...] = tuple(
    f.name for f in fields(MethodMetrics) if f.name not in ("auc_by_sub_kind",)
)
"""Names of the scalar fields of `MethodMetrics`."""


def compute_metrics(
    scores: np.ndarray | Sequence[float],
    threshold: float,
    kinds: np.ndarray | Sequence[str],
    sub_kinds: np.ndarray | Sequence[str] | None = None,
    *,
    window_episode: np.ndarray | Sequence[Any] | None = None,
    window_start: np.ndarray | Sequence[float] | None = None,
    event_episode: np.ndarray | Sequence[Any] | None = None,
    event_onset: np.ndarray | Sequence[float] | None = None,
    window_s: float = 2.0,
    max_delay_s: float = 10.0,
    max_fpr: float = 0.1,
) -> MethodMetrics:
    """Every metric of one method's test scores.

    Args:
        scores: (N,) test scores, higher = more anomalous.
        threshold: the detector's threshold (`threshold_`, from nominal data).
        kinds: (N,) `normal`, `collision` or `mechanical`.
        sub_kinds: (N,) sub-kind names (obstacle or fault kind; `none` for normal), or None.
        window_episode, window_start: (N,) episode id and start time (s) of each window, for delays.
        event_episode, event_onset: (E,) episode id and onset time (s) of each anomalous event.
        window_s: window length, s.
        max_delay_s: detection horizon after onset, s.
        max_fpr: FPR limit of the pAUC.

    Raises:
        ValueError: shapes differ, an unknown kind, or a test set without both normal and anomalous windows.
    """
    s, k, labels = _test_set(scores, kinds)
    precision, recall, f1 = precision_recall_f1(labels, s, threshold)
    best_f1, best_t = f1_oracle(labels, s)
    by_sub = _auc_by_sub_kind(s, k, labels, sub_kinds)
    delays = _timed_delays(
        s > threshold, window_episode, window_start, event_episode, event_onset, window_s, max_delay_s
    )
    delay_mean, delay_median, detection_rate = _delay_summary(delays)
    return MethodMetrics(
        auc=roc_auc(labels, s),
        auc_collision=auc_normal_vs(s, k, COLLISION_KIND),
        auc_mechanical=auc_normal_vs(s, k, MECHANICAL_KIND),
        pauc=roc_auc(labels, s, max_fpr=max_fpr),
        precision=precision,
        recall=recall,
        f1=f1,
        f1_oracle=best_f1,
        threshold=float(threshold),
        threshold_oracle=best_t,
        false_alarm_rate=float(np.mean(s[labels == 0] > threshold)),
        n_normal=int(np.sum(k == NORMAL_KIND)),
        n_collision=int(np.sum(k == COLLISION_KIND)),
        n_mechanical=int(np.sum(k == MECHANICAL_KIND)),
        auc_by_sub_kind=by_sub,
        delay_mean_s=delay_mean,
        delay_median_s=delay_median,
        detection_rate=detection_rate,
        n_events=int(delays.size),
    )


def _test_set(
    scores: np.ndarray | Sequence[float], kinds: np.ndarray | Sequence[str]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Scores (float64), kinds (str) and 0/1 labels of a test set, checked: 1-D, of one length, known
    kinds, both normal and anomalous windows."""
    s = np.asarray(scores, dtype=np.float64)
    k = np.asarray(kinds).astype(str)
    if k.shape != s.shape or s.ndim != 1:
        raise ValueError(f"scores {s.shape} and kinds {k.shape} must be 1-D of the same length")
    allowed = (NORMAL_KIND, COLLISION_KIND, MECHANICAL_KIND)
    unknown = sorted(set(np.unique(k)) - set(allowed))
    if unknown:
        raise ValueError(f"unknown kinds {unknown}; allowed: {', '.join(allowed)}")
    labels = (k != NORMAL_KIND).astype(int)
    if labels.sum() == 0 or labels.sum() == labels.size:
        raise ValueError(
            f"the test set needs normal and anomalous windows; {int(labels.sum())} of {labels.size} anomalous"
        )
    return s, k, labels


def _auc_by_sub_kind(
    s: np.ndarray, k: np.ndarray, labels: np.ndarray, sub_kinds: np.ndarray | Sequence[str] | None
) -> dict[str, float]:
    """ROC-AUC of normal against each anomalous sub-kind present, by name (empty without sub-kinds)."""
    if sub_kinds is None:
        return {}
    sk = np.asarray(sub_kinds).astype(str)
    if sk.shape != s.shape:
        raise ValueError(f"sub_kinds {sk.shape} must match scores {s.shape}")
    return {name: auc_normal_vs(s, sk, name, kinds=k) for name in sorted(set(np.unique(sk[labels == 1])))}


def _timed_delays(
    flags: np.ndarray,
    window_episode: np.ndarray | Sequence[Any] | None,
    window_start: np.ndarray | Sequence[float] | None,
    event_episode: np.ndarray | Sequence[Any] | None,
    event_onset: np.ndarray | Sequence[float] | None,
    window_s: float,
    max_delay_s: float,
) -> np.ndarray:
    """`detection_delays` of the flagged windows; empty when no timing is given, refused when only part is."""
    timing = (window_episode, window_start, event_episode, event_onset)
    if all(t is None for t in timing):
        return np.zeros(0)
    if window_episode is None or window_start is None or event_episode is None or event_onset is None:
        raise ValueError("delays need window_episode, window_start, event_episode and event_onset together")
    return detection_delays(
        window_episode,
        window_start,
        flags,
        event_episode,
        event_onset,
        window_s=window_s,
        max_delay_s=max_delay_s,
    )


def _delay_summary(delays: np.ndarray) -> tuple[float, float, float]:
    """Mean and median delay over the detected events, and the fraction detected (NaN where undefined)."""
    found = delays[np.isfinite(delays)]
    return (
        float(found.mean()) if found.size else math.nan,
        float(np.median(found)) if found.size else math.nan,
        float(found.size / delays.size) if delays.size else math.nan,
    )


def aggregate(runs: Sequence[MethodMetrics]) -> dict[str, tuple[float, float]]:
    """Mean and standard deviation over seeds of every scalar metric and each sub-kind AUC (`auc_<sub>`)."""
    if not runs:
        raise ValueError("aggregate needs at least one run")
    out = {name: mean_std([float(getattr(r, name)) for r in runs]) for name in SCALAR_METRICS}
    subs = sorted({name for r in runs for name in r.auc_by_sub_kind})
    for name in subs:
        out[f"auc_{name}"] = mean_std([r.auc_by_sub_kind.get(name, math.nan) for r in runs])
    return out


def summary_table(
    per_method: Mapping[str, Sequence[MethodMetrics]], columns: Sequence[str]
) -> list[list[str]]:
    """Rows `[method, "mean ± std", ...]` for the given metric columns (a helper for Markdown tables)."""
    rows = []
    for method, runs in per_method.items():
        agg = aggregate(runs)
        row = [method]
        for col in columns:
            m, sd = agg.get(col, (math.nan, math.nan))
            row.append("n/a" if not math.isfinite(m) else f"{m:.3f} ± {sd:.3f}")
        rows.append(row)
    return rows
