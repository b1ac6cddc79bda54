"""Metric functions against scikit-learn and hand computations."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sklearn.metrics import f1_score, precision_recall_curve, precision_score, recall_score, roc_auc_score

from benchmarks import metrics

HAND_LABELS = np.array([0, 0, 1, 1, 0, 1, 0, 1])
HAND_SCORES = np.array([0.1, 0.4, 0.35, 0.8, 0.4, 0.9, 0.2, 0.4])


def _random_case(seed: int, n: int = 300, ties: bool = False) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    y = (rng.random(n) < 0.3).astype(int)
    s = rng.standard_normal(n) + 1.2 * y
    if ties:
        s = np.round(s, 1)
    return y, s


def test_precision_recall_f1_hand_case() -> None:
    # flags at 0.35: 0.4, 0.8, 0.4, 0.9, 0.4 -> tp = 3 (0.8, 0.9, 0.4), fp = 2, fn = 1 (0.35)
    p, r, f = metrics.precision_recall_f1(HAND_LABELS, HAND_SCORES, 0.35)
    assert (p, r) == pytest.approx((3 / 5, 3 / 4))
    assert f == pytest.approx(2 * 3 / (2 * 3 + 2 + 1))


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("threshold", [-0.5, 0.3, 1.0, 5.0])
def test_precision_recall_f1_matches_sklearn(seed: int, threshold: float) -> None:
    y, s = _random_case(seed)
    pred = (s > threshold).astype(int)
    got = metrics.precision_recall_f1(y, s, threshold)
    want = (
        precision_score(y, pred, zero_division=0),
        recall_score(y, pred, zero_division=0),
        f1_score(y, pred, zero_division=0),
    )
    assert got == pytest.approx(want, abs=1e-12)


@pytest.mark.parametrize("ties", [False, True])
@pytest.mark.parametrize("seed", [0, 3])
def test_roc_auc_and_pauc_match_sklearn(seed: int, ties: bool) -> None:
    y, s = _random_case(seed, ties=ties)
    assert metrics.roc_auc(y, s) == pytest.approx(roc_auc_score(y, s), abs=1e-12)
    for max_fpr in (0.05, 0.1, 0.5):
        assert metrics.roc_auc(y, s, max_fpr=max_fpr) == pytest.approx(
            roc_auc_score(y, s, max_fpr=max_fpr), abs=1e-12
        )


def test_roc_auc_hand_case_with_ties() -> None:
    # pairs (pos, neg) = 4 x 4; pos 0.35 beats 0.1, 0.2; 0.4 ties 0.4, 0.4 and beats 0.1, 0.2;
    # 0.8 and 0.9 beat all four: (2 + 2 + 2 * 0.5 + 4 + 4) / 16
    assert metrics.roc_auc(HAND_LABELS, HAND_SCORES) == pytest.approx(13 / 16)


def test_f1_oracle_is_the_best_f1_on_the_pr_curve() -> None:
    for seed in range(3):
        y, s = _random_case(seed, ties=seed == 2)
        precision, recall, _ = precision_recall_curve(y, s)
        with np.errstate(invalid="ignore", divide="ignore"):
            f1 = np.nan_to_num(2 * precision * recall / (precision + recall))
        best, t = metrics.f1_oracle(y, s)
        assert best == pytest.approx(f1.max(), abs=1e-12)
        assert f1_score(y, (s >= t).astype(int)) == pytest.approx(best, abs=1e-12)


def test_f1_oracle_at_least_f1_at_any_threshold() -> None:
    y, s = _random_case(5)
    best, _ = metrics.f1_oracle(y, s)
    assert all(metrics.precision_recall_f1(y, s, t)[2] <= best + 1e-12 for t in np.unique(s))


def test_auc_normal_vs_one_kind_leaves_other_anomalies_out() -> None:
    kinds = np.array(["normal", "normal", "collision", "mechanical", "mechanical", "normal"])
    scores = np.array([0.1, 0.3, 0.2, 0.9, 0.05, 0.2])
    # collision 0.2 vs normals (0.1, 0.3, 0.2): 1 + 0 + 0.5 over 3
    assert metrics.auc_normal_vs(scores, kinds, "collision") == pytest.approx(0.5)
    keep = kinds != "collision"
    want = roc_auc_score((kinds[keep] == "mechanical").astype(int), scores[keep])
    assert metrics.auc_normal_vs(scores, kinds, "mechanical") == pytest.approx(want)
    assert math.isnan(metrics.auc_normal_vs(scores[kinds == "normal"], kinds[kinds == "normal"], "collision"))


def test_detection_delays_hand_case() -> None:
    # episode a: windows every 1 s, 2 s long; event at 3.5 s. Window starting 2.0 overlaps it but is not
    # flagged; the one at 3.0 (end 5.0) is the first flagged -> delay 1.5 s. Window at 1.0 is flagged but ends
    # at 3.0, before the onset. Episode b: the event at 1.0 is never flagged within 10 s -> NaN.
    episode = np.array(["a"] * 6 + ["b"] * 3)
    start = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 0.0, 1.0, 12.0])
    flags = np.array([False, True, False, True, True, False, False, False, True])
    delays = metrics.detection_delays(episode, start, flags, np.array(["a", "b"]), np.array([3.5, 1.0]))
    assert delays[0] == pytest.approx(1.5)
    assert math.isnan(delays[1])


def test_mean_std_over_seeds() -> None:
    m, s = metrics.mean_std([0.8, 0.9, float("nan"), 1.0])
    assert (m, s) == pytest.approx((0.9, np.std([0.8, 0.9, 1.0], ddof=1)))
    assert metrics.mean_std([0.7]) == (0.7, 0.0)


def test_compute_metrics_end_to_end_and_json() -> None:
    rng = np.random.default_rng(0)
    kinds = np.array(["normal"] * 60 + ["collision"] * 20 + ["mechanical"] * 20)
    sub = np.array(["none"] * 60 + ["wall"] * 10 + ["box"] * 10 + ["bearing"] * 20)
    scores = rng.standard_normal(100) + np.where(kinds == "normal", 0.0, 2.0)
    scores[kinds == "mechanical"] -= 1.0
    m = metrics.compute_metrics(scores, 1.0, kinds, sub)
    y = (kinds != "normal").astype(int)
    assert m.auc == pytest.approx(roc_auc_score(y, scores))
    assert m.pauc == pytest.approx(roc_auc_score(y, scores, max_fpr=0.1))
    assert m.f1 == pytest.approx(f1_score(y, (scores > 1.0).astype(int)))
    assert m.f1_oracle >= m.f1
    assert m.auc_collision > m.auc_mechanical
    assert set(m.auc_by_sub_kind) == {"wall", "box", "bearing"}
    assert m.auc_by_sub_kind["bearing"] == pytest.approx(m.auc_mechanical)
    assert (m.n_normal, m.n_collision, m.n_mechanical) == (60, 20, 20)
    assert m.false_alarm_rate == pytest.approx(np.mean(scores[:60] > 1.0))
    d = m.to_dict()
    assert d["delay_mean_s"] is None and d["auc"] == m.auc
    agg = metrics.aggregate([m, m])
    assert agg["auc"] == (m.auc, 0.0)
    assert agg["auc_wall"][0] == pytest.approx(m.auc_by_sub_kind["wall"])
    rows = metrics.summary_table({"x": [m, m]}, ["auc", "delay_mean_s"])
    assert rows == [["x", f"{m.auc:.3f} ± 0.000", "n/a"]]


def test_compute_metrics_refuses_a_test_set_without_anomalies() -> None:
    with pytest.raises(ValueError, match="normal and anomalous"):
        metrics.compute_metrics(np.arange(4.0), 1.0, ["normal"] * 4)
    with pytest.raises(ValueError, match="unknown kinds"):
        metrics.compute_metrics(np.arange(2.0), 1.0, ["normal", "crash"])
    with pytest.raises(ValueError, match="NaN"):
        metrics.roc_auc([0, 1], [0.0, float("nan")])


def test_compute_metrics_with_event_timing() -> None:
    kinds = np.array(["normal", "normal", "collision", "collision", "normal", "mechanical"])
    scores = np.array([0.1, 0.2, 0.9, 0.3, 0.1, 0.8])
    m = metrics.compute_metrics(
        scores,
        0.5,
        kinds,
        window_episode=np.array([0, 0, 0, 0, 1, 1]),
        window_start=np.array([0.0, 1.0, 2.0, 3.0, 0.0, 1.0]),
        event_episode=np.array([0, 1]),
        event_onset=np.array([2.5, 0.5]),
    )
    # episode 0: window at 2.0 s (ends 4.0) flagged -> 1.5 s; episode 1: window at 1.0 (ends 3.0) -> 2.5 s
    assert (m.delay_mean_s, m.detection_rate, m.n_events) == pytest.approx((2.0, 1.0, 2))
    with pytest.raises(ValueError, match="together"):
        metrics.compute_metrics(scores, 0.5, kinds, window_episode=np.zeros(6))
