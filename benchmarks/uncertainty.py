"""How sure an AUC is: episode-cluster bootstrap confidence intervals and paired differences.

Windows of one episode are not independent (same room, unit, SNR, route), so resampling windows would
understate the uncertainty. The bootstrap here resamples whole episodes with replacement, separately
among the normal episodes and among the anomalous ones (so every replicate has both classes), and
recomputes the AUC with each window weighted by how often its episode was drawn. A paired difference
uses the same episode draws for both methods; a method is better than another only when the 95 %
interval of the difference excludes zero.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

BOOTSTRAP_REPLICATES = 1000
"""Bootstrap replicates per interval."""
BOOTSTRAP_SEED = 20261130
"""Seed of the episode draws: the same scores always give the same interval."""
CONFIDENCE = 0.95
"""Coverage of every interval."""
MIN_EPISODES_PER_CLASS = 2
"""A seed-mean interval needs this many normal and anomalous episodes; one episode cannot be resampled into
variety, so with fewer the interval is undefined (NaN) rather than a misleading point."""


@dataclass(frozen=True)
class Interval:
    """A point estimate with its episode-cluster bootstrap interval."""

    value: float
    """The estimate on the data as it is."""
    low: float
    """Lower end of the interval."""
    high: float
    """Upper end of the interval."""

    @property
    def half_width(self) -> float:
        """Half the interval's width."""
        return 0.5 * (self.high - self.low)

    def excludes(self, x: float) -> bool:
        """Whether `x` lies outside the interval."""
        return not self.low <= x <= self.high

    def to_dict(self) -> dict[str, float | None]:
        """JSON-ready (NaN becomes None)."""

        def clean(v: float) -> float | None:
            return v if math.isfinite(v) else None

        return {"value": clean(self.value), "low": clean(self.low), "high": clean(self.high)}


NAN_INTERVAL = Interval(math.nan, math.nan, math.nan)
"""What an undefined estimate (one class missing) reports."""


def weighted_auc(scores: np.ndarray, positive: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """ROC-AUC of `positive` against the rest with per-window weights, ties counting one half.

    Args:
        scores: (n,) scores, higher = more anomalous.
        positive: (n,) bool, the anomalous windows.
        weights: (B, n) or (n,) non-negative weights (B replicates at once).

    Returns:
        (B,) AUCs (a scalar array for 1-D weights); NaN where a class has zero weight.
    """
    s = np.asarray(scores, dtype=np.float64)
    pos = np.asarray(positive, dtype=bool)
    w = np.atleast_2d(np.asarray(weights, dtype=np.float64))
    order = np.argsort(s, kind="mergesort")
    s_sorted = s[order]
    ws = w[:, order]
    neg_w = np.where(pos[order], 0.0, ws)
    pos_w = np.where(pos[order], ws, 0.0)
    # Tie groups: the last index of each run of equal scores.
    last = np.r_[np.flatnonzero(np.diff(s_sorted)), s.size - 1]
    cum_neg = np.cumsum(neg_w, axis=1)[:, last]
    cum_pos = np.cumsum(pos_w, axis=1)[:, last]
    group_neg = np.diff(cum_neg, axis=1, prepend=0.0)
    group_pos = np.diff(cum_pos, axis=1, prepend=0.0)
    below = cum_neg - group_neg
    total_pos, total_neg = cum_pos[:, -1], cum_neg[:, -1]
    wins = np.sum(group_pos * (below + 0.5 * group_neg), axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        auc = np.where((total_pos > 0) & (total_neg > 0), wins / (total_pos * total_neg), np.nan)
    return auc if np.ndim(weights) > 1 else auc.reshape(())


def episode_draws(
    clusters: np.ndarray,
    positive: np.ndarray,
    replicates: int = BOOTSTRAP_REPLICATES,
    seed: int = BOOTSTRAP_SEED,
) -> np.ndarray:
    """(B, n) window weights: each replicate draws the normal and the anomalous episodes with replacement.

    An episode counts as anomalous when any of its windows is positive (anomaly episodes contribute only
    anomalous windows; nominal sequences only normal ones).
    """
    c = np.asarray(clusters).astype(str)
    pos = np.asarray(positive, dtype=bool)
    names, index = np.unique(c, return_inverse=True)
    anomalous = np.zeros(names.size, dtype=bool)
    np.logical_or.at(anomalous, index, pos)
    rng = np.random.default_rng(seed)
    counts = np.zeros((replicates, names.size))
    for group in (np.flatnonzero(~anomalous), np.flatnonzero(anomalous)):
        if group.size:
            draws = rng.integers(0, group.size, size=(replicates, group.size))
            counts[:, group] = np.stack([np.bincount(d, minlength=group.size) for d in draws])
    return counts[:, index]


def excludes_zero(iv: Interval) -> bool | None:
    """Whether the interval lies wholly above or below zero (None when it is undefined)."""
    if not (math.isfinite(iv.low) and math.isfinite(iv.high)):
        return None
    return iv.excludes(0.0)


def format_interval(iv: Interval, *, percent: bool = True, signed: bool = False, digits: int = 1) -> str:
    """`84.0 [81.2, 86.5]` (an AUC in percent), `+1.2 [-0.5, +3.0]` with `signed`, `1.030 [0.990, 1.070]`
    with `percent=False, digits=3` (a ratio); `[n/a]` for an undefined interval, `n/a` for an undefined
    value."""
    if not math.isfinite(iv.value):
        return "n/a"
    scale = 100.0 if percent else 1.0
    pattern = f"{{:{'+' if signed else ''}.{digits}f}}"
    text = pattern.format(scale * iv.value)
    if math.isfinite(iv.low) and math.isfinite(iv.high):
        return text + f" [{pattern.format(scale * iv.low)}, {pattern.format(scale * iv.high)}]"
    return text + " [n/a]"


def _interval(value: float, replicates: np.ndarray) -> Interval:
    r = replicates[np.isfinite(replicates)]
    if not math.isfinite(value) or r.size == 0:
        return Interval(value, math.nan, math.nan)
    tail = 100.0 * (1.0 - CONFIDENCE) / 2.0
    low, high = np.percentile(r, [tail, 100.0 - tail])
    return Interval(float(value), float(low), float(high))


def auc_interval(
    scores: np.ndarray | Sequence[float],
    positive: np.ndarray | Sequence[bool],
    clusters: np.ndarray | Sequence[str],
    replicates: int = BOOTSTRAP_REPLICATES,
    seed: int = BOOTSTRAP_SEED,
) -> Interval:
    """ROC-AUC and its episode-cluster bootstrap 95 % interval (NaN interval if a class is missing)."""
    s = np.asarray(scores, dtype=np.float64)
    pos = np.asarray(positive, dtype=bool)
    if s.shape != pos.shape or np.shape(clusters) != s.shape:
        raise ValueError(f"scores {s.shape}, positive {pos.shape}, clusters {np.shape(clusters)} must match")
    if not pos.any() or pos.all():
        return NAN_INTERVAL
    value = float(weighted_auc(s, pos, np.ones(s.size)))
    weights = episode_draws(np.asarray(clusters), pos, replicates, seed)
    return _interval(value, weighted_auc(s, pos, weights))


def paired_auc_difference(
    scores_a: np.ndarray | Sequence[float],
    scores_b: np.ndarray | Sequence[float],
    positive: np.ndarray | Sequence[bool],
    clusters: np.ndarray | Sequence[str],
    replicates: int = BOOTSTRAP_REPLICATES,
    seed: int = BOOTSTRAP_SEED,
) -> Interval:
    """AUC(a) - AUC(b) on the same windows, with the interval from the same episode draws for both."""
    a = np.asarray(scores_a, dtype=np.float64)
    b = np.asarray(scores_b, dtype=np.float64)
    pos = np.asarray(positive, dtype=bool)
    if a.shape != b.shape or a.shape != pos.shape:
        raise ValueError(f"scores_a {a.shape}, scores_b {b.shape} and positive {pos.shape} must match")
    if not pos.any() or pos.all():
        return NAN_INTERVAL
    ones = np.ones(a.size)
    value = float(weighted_auc(a, pos, ones) - weighted_auc(b, pos, ones))
    weights = episode_draws(np.asarray(clusters), pos, replicates, seed)
    return _interval(value, weighted_auc(a, pos, weights) - weighted_auc(b, pos, weights))


def enough_episodes(
    clusters: np.ndarray | Sequence[str],
    positive: np.ndarray | Sequence[bool],
    minimum: int = MIN_EPISODES_PER_CLASS,
) -> bool:
    """Whether the normal and the anomalous windows each come from at least `minimum` episodes."""
    c = np.asarray(clusters).astype(str)
    pos = np.asarray(positive, dtype=bool)
    return len(set(c[~pos])) >= minimum and len(set(c[pos])) >= minimum


@dataclass(frozen=True, eq=False)
class BootstrapAuc:
    """An AUC averaged over training seeds, on the data as it is and in every bootstrap replicate."""

    value: float
    """Mean over seeds of the AUC on the data as it is (NaN if a class is missing)."""
    replicates: np.ndarray
    """(B,) mean over seeds of the AUC in each replicate; every seed is weighted by the same episode draws."""
    defined: bool = True
    """False when a class has fewer than `MIN_EPISODES_PER_CLASS` episodes: the intervals are then NaN."""

    def interval(self) -> Interval:
        """The estimate with its percentile interval."""
        if not self.defined:
            return Interval(self.value, math.nan, math.nan)
        return _interval(self.value, self.replicates)

    def minus(self, other: BootstrapAuc) -> Interval:
        """Paired difference self - other, replicate by replicate (both must come from the same draws)."""
        if self.replicates.shape != other.replicates.shape:
            raise ValueError(
                f"replicates {self.replicates.shape} and {other.replicates.shape} differ: not the same draws"
            )
        if not (self.defined and other.defined):
            return Interval(self.value - other.value, math.nan, math.nan)
        return _interval(self.value - other.value, self.replicates - other.replicates)


def bootstrap_mean_auc(
    scores: np.ndarray | Sequence[Sequence[float]],
    positive: np.ndarray | Sequence[bool],
    clusters: np.ndarray | Sequence[str],
    weights: np.ndarray,
) -> BootstrapAuc:
    """ROC-AUC averaged over training seeds, on the data and inside each replicate of `weights`.

    Args:
        scores: (S, n) scores of S training seeds on the same windows, or (n,) for one seed.
        positive: (n,) bool, the anomalous windows.
        clusters: (n,) episode of each window (the intervals are undefined with too few episodes).
        weights: (B, n) window weights (`episode_draws` of these clusters), applied alike to every seed.

    Returns:
        The seed-mean AUC and its (B,) replicates (NaN throughout if a class is missing).
    """
    s, pos, w = _checked(scores, positive, clusters, weights)
    if not pos.any() or pos.all():
        return BootstrapAuc(math.nan, np.full(w.shape[0], math.nan), defined=False)
    ones = np.ones(pos.size)
    value = float(np.mean([weighted_auc(row, pos, ones) for row in s]))
    replicates = np.mean([weighted_auc(row, pos, w) for row in s], axis=0)
    return BootstrapAuc(value, replicates, defined=enough_episodes(clusters, pos))


def _checked(
    scores: np.ndarray | Sequence[Sequence[float]],
    positive: np.ndarray | Sequence[bool],
    clusters: np.ndarray | Sequence[str],
    weights: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(scores (S, n), positive (n,) bool, weights (B, n)) as arrays; ValueError if the shapes disagree."""
    s = np.atleast_2d(np.asarray(scores, dtype=np.float64))
    pos = np.asarray(positive, dtype=bool)
    w = np.atleast_2d(np.asarray(weights, dtype=np.float64))
    if s.ndim != 2 or s.shape[0] == 0 or s.shape[1] != pos.size or w.shape[1] != pos.size:
        raise ValueError(f"scores {s.shape}, positive {pos.shape} and weights {w.shape} must match")
    if np.shape(clusters) != pos.shape:
        raise ValueError(f"positive {pos.shape} and clusters {np.shape(clusters)} must match")
    return s, pos, w


PAUC_MAX_FPR = 0.1
"""FPR limit of the pAUC, as in run reports (`benchmarks.metrics.compute_metrics`; the DCASE convention)."""


def counted_pauc(
    scores: np.ndarray, positive: np.ndarray, counts: np.ndarray, max_fpr: float = PAUC_MAX_FPR
) -> float:
    """pAUC (`benchmarks.metrics.roc_auc` with `max_fpr`) of the windows each repeated `counts` times.

    `counts` are an `episode_draws` replicate (whole numbers): the pAUC of the resampled test set exactly.
    """
    from benchmarks.metrics import roc_auc

    reps = np.rint(np.asarray(counts, dtype=np.float64)).astype(np.int64)
    keep = reps > 0
    labels = np.repeat(np.asarray(positive, dtype=np.int64)[keep], reps[keep])
    return roc_auc(labels, np.repeat(np.asarray(scores, dtype=np.float64)[keep], reps[keep]), max_fpr)


def bootstrap_mean_pauc(
    scores: np.ndarray | Sequence[Sequence[float]],
    positive: np.ndarray | Sequence[bool],
    clusters: np.ndarray | Sequence[str],
    weights: np.ndarray,
    max_fpr: float = PAUC_MAX_FPR,
) -> BootstrapAuc:
    """`bootstrap_mean_auc` for the pAUC at FPR <= `max_fpr`: seed-mean, on the data and in each replicate.

    `weights` must be `episode_draws` counts; the result's `minus` gives paired pAUC differences.
    """
    s, pos, w = _checked(scores, positive, clusters, weights)
    if not pos.any() or pos.all():
        return BootstrapAuc(math.nan, np.full(w.shape[0], math.nan), defined=False)
    ones = np.ones(pos.size)
    value = float(np.mean([counted_pauc(row, pos, ones, max_fpr) for row in s]))
    replicates = np.array(
        [np.mean([counted_pauc(row, pos, draw, max_fpr) for row in s]) for draw in w], dtype=np.float64
    )
    return BootstrapAuc(value, replicates, defined=enough_episodes(clusters, pos))


def mean_auc_interval(
    scores: np.ndarray | Sequence[Sequence[float]],
    positive: np.ndarray | Sequence[bool],
    clusters: np.ndarray | Sequence[str],
    replicates: int = BOOTSTRAP_REPLICATES,
    seed: int = BOOTSTRAP_SEED,
) -> Interval:
    """Mean ROC-AUC over training seeds and its episode-cluster bootstrap 95 % interval.

    Each replicate's episode draws weight every seed's (S, n) scores, and the per-seed AUCs are averaged
    inside the replicate; with one seed this is `auc_interval`, except that the interval is NaN when a class
    has fewer than `MIN_EPISODES_PER_CLASS` episodes.
    """
    pos = np.asarray(positive, dtype=bool)
    if np.shape(clusters) != pos.shape:
        raise ValueError(f"positive {pos.shape} and clusters {np.shape(clusters)} must match")
    weights = episode_draws(np.asarray(clusters), pos, replicates, seed)
    return bootstrap_mean_auc(scores, pos, clusters, weights).interval()


def paired_mean_auc_difference(
    scores_a: np.ndarray | Sequence[Sequence[float]],
    scores_b: np.ndarray | Sequence[Sequence[float]],
    positive: np.ndarray | Sequence[bool],
    clusters: np.ndarray | Sequence[str],
    replicates: int = BOOTSTRAP_REPLICATES,
    seed: int = BOOTSTRAP_SEED,
) -> Interval:
    """Seed-mean AUC of a minus that of b ((S_a, n), (S_b, n) scores), the same draws for every seed of both.

    With one seed each this is `paired_auc_difference` (but NaN with too few episodes, like
    `mean_auc_interval`); a method against itself gives exactly 0 [0, 0].
    """
    pos = np.asarray(positive, dtype=bool)
    if np.shape(clusters) != pos.shape:
        raise ValueError(f"positive {pos.shape} and clusters {np.shape(clusters)} must match")
    weights = episode_draws(np.asarray(clusters), pos, replicates, seed)
    a = bootstrap_mean_auc(scores_a, pos, clusters, weights)
    return a.minus(bootstrap_mean_auc(scores_b, pos, clusters, weights))


def auc_per_normal_episode(
    scores: np.ndarray | Sequence[float],
    positive: np.ndarray | Sequence[bool],
    clusters: np.ndarray | Sequence[str],
) -> dict[str, float]:
    """AUC of all anomalous windows against the normal windows of each normal episode alone.

    How much the figure depends on which nominal sequence happens to be the test normal set.
    """
    s = np.asarray(scores, dtype=np.float64)
    pos = np.asarray(positive, dtype=bool)
    c = np.asarray(clusters).astype(str)
    out: dict[str, float] = {}
    for name in sorted(set(c[~pos])):
        keep = pos | (c == name)
        out[name] = float(weighted_auc(s[keep], pos[keep], np.ones(int(keep.sum()))))
    return out
