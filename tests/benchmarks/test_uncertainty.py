"""Episode-cluster bootstrap: weighted AUC against scikit-learn, intervals and paired differences."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.metrics import roc_auc_score

from benchmarks.uncertainty import (
    auc_interval,
    auc_per_normal_episode,
    bootstrap_mean_auc,
    episode_draws,
    mean_auc_interval,
    paired_auc_difference,
    paired_mean_auc_difference,
    weighted_auc,
)


def _data(seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    episodes = np.repeat([f"n{i}" for i in range(8)] + [f"a{i}" for i in range(12)], 15)
    positive = np.char.startswith(episodes, "a")
    shift = np.repeat(rng.normal(0.0, 0.5, 20), 15)  # episode effects: windows are not independent
    scores = rng.normal(0.0, 1.0, episodes.size) + shift + 0.8 * positive
    return np.round(scores, 1), positive, episodes  # rounding makes ties


def test_weighted_auc_matches_sklearn_with_ties_and_integer_weights() -> None:
    scores, positive, _ = _data()
    assert float(weighted_auc(scores, positive, np.ones(scores.size))) == pytest.approx(
        roc_auc_score(positive, scores), abs=1e-12
    )
    counts = np.random.default_rng(1).integers(0, 4, scores.size)
    repeated = np.repeat(np.arange(scores.size), counts)
    assert float(weighted_auc(scores, positive, counts)) == pytest.approx(
        roc_auc_score(positive[repeated], scores[repeated]), abs=1e-12
    )
    many = weighted_auc(scores, positive, np.stack([np.ones(scores.size), counts]))
    assert many.shape == (2,)


def test_episode_draws_resample_whole_episodes_within_each_class() -> None:
    _, positive, episodes = _data()
    w = episode_draws(episodes, positive, replicates=50, seed=3)
    assert w.shape == (50, episodes.size)
    for name in np.unique(episodes):  # every window of an episode gets the episode's count
        cols = w[:, episodes == name]
        assert np.all(cols == cols[:, :1])
    n_windows = 15
    assert np.all(w[:, ~positive].sum(axis=1) == 8 * n_windows)  # 8 normal episodes drawn 8 times
    assert np.all(w[:, positive].sum(axis=1) == 12 * n_windows)


def test_interval_contains_estimate_and_narrows_with_more_episodes() -> None:
    scores, positive, episodes = _data()
    ci = auc_interval(scores, positive, episodes)
    assert ci.low < ci.value < ci.high
    assert ci.value == pytest.approx(roc_auc_score(positive, scores))
    assert auc_interval(scores, positive, episodes).to_dict() == ci.to_dict()  # deterministic
    # Windows treated as their own episodes understate the uncertainty.
    naive = auc_interval(scores, positive, np.arange(scores.size).astype(str))
    assert naive.half_width < ci.half_width


def test_paired_difference_of_a_method_with_itself_is_exactly_zero() -> None:
    scores, positive, episodes = _data()
    same = paired_auc_difference(scores, scores, positive, episodes)
    assert same.value == same.low == same.high == 0.0
    better = paired_auc_difference(scores + 3.0 * positive, scores, positive, episodes)
    assert better.value > 0 and better.excludes(0.0)


def test_seed_mean_interval_averages_seeds_inside_each_replicate() -> None:
    scores, positive, episodes = _data()
    other = scores + np.random.default_rng(5).normal(0.0, 0.5, scores.size)
    # One seed: exactly the single-run interval and paired difference.
    assert mean_auc_interval(scores[None, :], positive, episodes) == auc_interval(scores, positive, episodes)
    assert paired_mean_auc_difference(scores, other, positive, episodes) == paired_auc_difference(
        scores, other, positive, episodes
    )
    # Two seeds: the estimate is the mean of the seeds' AUCs, and each replicate averages them.
    both = np.stack([scores, other])
    ci = mean_auc_interval(both, positive, episodes, replicates=300)
    assert ci.value == pytest.approx(np.mean([roc_auc_score(positive, s) for s in both]), abs=1e-12)
    weights = episode_draws(episodes, positive, replicates=300)
    per_seed = np.stack([weighted_auc(s, positive, weights) for s in both])
    boot = bootstrap_mean_auc(both, positive, episodes, weights)
    np.testing.assert_allclose(boot.replicates, per_seed.mean(axis=0))
    assert ci.low < ci.value < ci.high


def test_seed_mean_difference_of_a_method_with_itself_is_exactly_zero() -> None:
    scores, positive, episodes = _data()
    runs = np.stack([scores, scores[::-1], np.round(scores * 0.5, 1)])
    same = paired_mean_auc_difference(runs, runs, positive, episodes)
    assert same.value == same.low == same.high == 0.0
    weights = episode_draws(episodes, positive, replicates=10)
    with pytest.raises(ValueError, match="not the same draws"):
        bootstrap_mean_auc(runs, positive, episodes, weights).minus(
            bootstrap_mean_auc(runs, positive, episodes, weights[:5])
        )


def test_one_episode_in_a_class_leaves_the_seed_mean_interval_undefined() -> None:
    scores, positive, episodes = _data()
    one_normal = np.where(positive, episodes, "n0")  # every normal window in one episode
    ci = mean_auc_interval(scores, positive, one_normal)
    assert ci.value == pytest.approx(roc_auc_score(positive, scores))
    assert np.isnan(ci.low) and np.isnan(ci.high)
    diff = paired_mean_auc_difference(scores, scores[::-1], positive, one_normal)
    assert np.isfinite(diff.value) and np.isnan(diff.half_width)


def test_auc_per_normal_episode_uses_one_normal_sequence_at_a_time() -> None:
    scores, positive, episodes = _data()
    per = auc_per_normal_episode(scores, positive, episodes)
    assert sorted(per) == [f"n{i}" for i in range(8)]
    keep = positive | (episodes == "n3")
    assert per["n3"] == pytest.approx(roc_auc_score(positive[keep], scores[keep]))


def test_missing_class_gives_nan_interval() -> None:
    ci = auc_interval([0.1, 0.2], [False, False], ["a", "b"])
    assert np.isnan(ci.value) and np.isnan(ci.half_width)
