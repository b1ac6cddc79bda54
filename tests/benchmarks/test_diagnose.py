"""`msvdd-bench diagnose`: analytic oracles for its pieces, and the command end to end on the tiny preset."""

from __future__ import annotations

import json
import math
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from sklearn.metrics import roc_auc_score

from benchmarks.cli import main
from benchmarks.dataset import load_window_rows, open_dataset
from benchmarks.diagnose import (
    d_alone_intervals,
    decompose,
    effective_rank,
    explained_variance,
    load_msvdd,
    ridge_of,
    score_terms,
    spectrum,
    stratified_subsample,
    summarise_history,
    weight_sweep,
    window_covariates,
)
from msvdd.contract import AUDIO_LEN, IMU_LEN, Windows
from msvdd.training import TrainResult


def test_effective_rank_of_known_spectra() -> None:
    assert effective_rank(np.full(4, 2.5)) == pytest.approx(4.0)
    assert effective_rank(np.array([3.0, 0.0, 0.0])) == pytest.approx(1.0)
    # p = (1/2, 1/4, 1/4): entropy 1.5 ln 2, so exp(entropy) = 2^1.5.
    assert effective_rank(np.array([2.0, 1.0, 1.0])) == pytest.approx(2**1.5)


def test_spectrum_of_a_diagonal_matrix() -> None:
    eps = 1e-3
    s = spectrum(np.diag([4.0, eps, 1.0, 5 * eps]), eps)
    assert s.eigenvalues == pytest.approx([4.0, 1.0, 5 * eps, eps])
    assert s.condition_number == pytest.approx(4.0 / eps)
    assert s.n_ridge_dominated == 2  # eps and 5 eps are within 10 eps


def test_explained_variance_oracles() -> None:
    rng = np.random.default_rng(0)
    loud = rng.normal(size=2000)
    exact = np.column_stack([2.0 * loud + 1.0, -0.5 * loud, 3.0 * loud - 7.0])
    assert explained_variance(exact, loud) == pytest.approx(1.0, abs=1e-12)
    noise = rng.normal(size=(2000, 3))
    assert explained_variance(noise, loud) < 0.01
    # One dimension explained, one independent of equal variance: half the total variance.
    half = np.column_stack([loud, rng.normal(size=2000)])
    assert explained_variance(half, loud) == pytest.approx(0.5, abs=0.05)


def test_window_covariates_of_known_windows() -> None:
    n = 3
    amp = np.array([0.1, 0.5, 2.0], dtype=np.float32)
    signs = np.where(np.arange(AUDIO_LEN) % 2 == 0, 1.0, -1.0).astype(np.float32)
    audio = amp[:, None, None] * np.repeat(signs[None, :, None], 2, axis=2)
    imu = np.zeros((n, IMU_LEN), dtype=np.float32)
    imu[:, ::2] = np.array([1.0, 2.0, 3.0], dtype=np.float32)[:, None]  # std = half the step
    imu6 = np.zeros((n, IMU_LEN, 6), dtype=np.float32)
    imu6[:, :, 2] = 9.81
    cov = window_covariates(Windows(audio=audio, imu=imu, imu6=imu6))
    np.testing.assert_allclose(cov["loudness"], np.log(amp), rtol=1e-6)
    np.testing.assert_allclose(cov["motion"], [0.5, 1.0, 1.5], rtol=1e-6)
    np.testing.assert_allclose(cov["acc"], 0.0, atol=1e-6)
    assert "acc" not in window_covariates(Windows(audio=audio, imu=imu))


def test_stratified_subsample_keeps_shares_and_is_seeded() -> None:
    kinds = ["normal"] * 600 + ["collision"] * 300 + ["mechanical"] * 100
    subs = ["none"] * 600 + ["wall", "box"] * 150 + ["bearing"] * 100
    idx = stratified_subsample(kinds, subs, 100, seed=3)
    assert len(idx) == 100 and len(set(idx.tolist())) == 100 and np.all(np.diff(idx) > 0)
    picked = Counter(kinds[i] for i in idx)
    assert picked == {"normal": 60, "collision": 30, "mechanical": 10}
    assert Counter(subs[i] for i in idx)["wall"] == 15
    np.testing.assert_array_equal(idx, stratified_subsample(kinds, subs, 100, seed=3))
    assert not np.array_equal(idx, stratified_subsample(kinds, subs, 100, seed=4))
    np.testing.assert_array_equal(stratified_subsample(kinds, subs, 5000, seed=3), np.arange(1000))


def test_history_summary_and_the_collapse_rule() -> None:
    assert summarise_history(None, 8) is None
    radius = [2.0, 0.5, 0.01, 0.001]
    h = TrainResult(
        train_loss=[4.0, 3.0, 2.0, 1.0], best_epoch=2, epochs={"radius": radius, "svdd": [1, 2, 3, 4]}
    )
    s = summarise_history(h, 16)
    assert s is not None
    assert (s.radius_initial, s.radius_first, s.radius_kept, s.radius_last) == (4.0, 2.0, 0.01, 0.001)
    assert s.collapsed  # 0.01 < 1e-2 * sqrt(16)
    assert s.terms_kept == {"svdd": 3.0}
    kept_early = summarise_history(TrainResult(best_epoch=0, epochs={"radius": radius}), 16)
    assert kept_early is not None and not kept_early.collapsed


def test_d_alone_has_the_plain_auc_and_an_episode_cluster_interval_per_group() -> None:
    """Each group's value is scikit-learn's AUC of D against every normal window; its interval is the
    episode-cluster bootstrap's (episodes of three windows; a group a dataset lacks is left out)."""
    rng = np.random.default_rng(5)
    kinds = ["normal"] * 12 + ["collision"] * 9
    episodes = [f"n{i // 3}" for i in range(12)] + [f"c{i // 3}" for i in range(9)]
    d = np.r_[rng.normal(size=12), 1.0 + rng.normal(size=9)]
    out = d_alone_intervals(d, kinds, episodes)
    assert set(out) == {"collision", "all anomalies"}
    expected = roc_auc_score([k != "normal" for k in kinds], d)
    for iv in out.values():
        assert iv.value == pytest.approx(expected, abs=1e-12) and iv.low < iv.value < iv.high


def test_decompose_says_which_term_detects_what() -> None:
    kinds = ["normal"] * 4 + ["collision"] * 2 + ["mechanical"] * 2
    subs = ["none"] * 4 + ["wall", "wall", "bearing", "bearing"]
    d = np.array([1.0, 1.1, 0.9, 1.0, 5.0, 6.0, 1.0, 1.0])
    wrec = np.array([0.1, 0.2, 0.1, 0.2, 0.15, 0.15, 3.0, 4.0])
    terms = {t.group: t for t in decompose(d, wrec, kinds, subs)}
    assert list(terms) == ["normal", "collision", "mechanical", "all anomalies", "wall", "bearing"]
    assert terms["normal"].auc_d is None and terms["normal"].mean_d == pytest.approx(1.0)
    assert terms["collision"].auc_d == 1.0 and terms["collision"].auc_score == 1.0
    assert terms["mechanical"].auc_rec == 1.0 and terms["mechanical"].auc_d == pytest.approx(0.5)
    mech = terms["mechanical"]
    assert mech.share_d + mech.share_rec == pytest.approx(1.0)
    assert mech.share_rec == pytest.approx(3.5 / 4.5)
    no_rec = decompose(d, 0 * wrec, kinds, subs, has_rec=False)
    assert all(t.auc_rec is None for t in no_rec)
    # The weight sweep: at w = 0 the score is D alone (collisions found, faults at chance); a large w
    # makes Rec dominate (faults found). Against sklearn on the same scores.
    sweep = {x.w: x for x in weight_sweep(d, wrec, 1.0, kinds)}
    assert sweep[0.0].auc_collision == 1.0 and sweep[0.0].auc_mechanical == pytest.approx(0.5)
    assert sweep[10.0].auc_mechanical == 1.0
    y = np.array([k != "normal" for k in kinds])
    for w, x in sweep.items():
        assert x.auc == pytest.approx(roc_auc_score(y, d + w * wrec))


def test_score_terms_sum_to_the_score(tiny_dataset: Path, tiny_model: Path) -> None:
    _, model = load_msvdd(tiny_model)
    dataset = open_dataset(tiny_dataset, verify=False)
    rows = dataset.rows("test")
    batch, _ = load_window_rows(dataset.path, rows[:: max(1, len(rows) // 24)])
    d, wrec = score_terms(model, batch)
    np.testing.assert_allclose(d + wrec, model.score(batch), rtol=1e-12)


def test_cli_writes_both_files_and_reruns_the_same(
    tiny_dataset: Path, tiny_model: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "diag"
    argv = [
        "diagnose",
        str(tiny_model),
        "--data",
        str(tiny_dataset),
        "--out",
        str(out),
        "--max-windows",
        "40",
    ]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    md = (out / "diagnosis.md").read_text()
    assert printed.strip() == md.strip()
    assert "## 4. Score decomposition" in md and "## 1. Training history" in md
    assert "the radius R is not trained" in md  # `msvdd` holds mu and Sigma fixed between estimates
    # D alone and its share of the score, and the estimates held during training with their ranks.
    assert (
        "D alone: AUC" in md
        and "episode-cluster intervals" in md
        and "D's share of the mean score on normal test windows" in md
    )
    assert "| after epoch | effective rank |" in md and "| final |" in md
    first = json.loads((out / "diagnosis.json").read_text())
    assert first["method"] == "msvdd" and first["history"] is not None
    alone = first["d_alone"]
    assert set(alone) == {"collision", "mechanical", "all anomalies"}
    assert all(0.0 <= a["low"] <= a["value"] <= a["high"] <= 1.0 for a in alone.values())
    assert first["second_term"] == "reconstruction" and first["config"]["svdd_fit"] == "frozen"
    s = first["config"]["s"]
    assert [h["epoch"] for h in first["held"]] == [1, -1]  # smoke: 5 epochs, warm-up 1, every 5; final
    assert all(1.0 <= h["effective_rank"] <= s and h["smallest_over_largest"] > 0 for h in first["held"])
    assert first["sigma_raw"] is not None and len(first["sigma_raw"]["eigenvalues"]) == s
    normal = next(t for t in first["terms"] if t["group"] == "normal")
    assert 0.0 < normal["share_d"] < 1.0 and normal["share_d"] + normal["share_rec"] == pytest.approx(1.0)
    assert first["counts"]["train_used"] <= 40 and sum(first["counts"]["test_used"].values()) <= 40
    assert len(first["sigma"]["eigenvalues"]) == first["config"]["s"]
    assert set(first["encoding"]["r2"]) >= {"loudness", "motion"}
    assert all(math.isfinite(v) and v <= 1 + 1e-9 for v in first["encoding"]["r2"].values())
    assert main(argv) == 0  # an earlier diagnosis folder is replaced, with the same content
    assert json.loads((out / "diagnosis.json").read_text()) == first
    assert sorted(p.name for p in tmp_path.iterdir()) == ["diag"]  # no temp folders left


def test_a_model_of_another_family_exits_2(
    tiny_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    model = tmp_path / "rms"
    assert main(["train", "--data", str(tiny_dataset), "--method", "audio-rms", "--out", str(model)]) == 0
    capsys.readouterr()
    assert main(["diagnose", str(model), "--data", str(tiny_dataset)]) == 2
    err = capsys.readouterr().err
    assert "'audio-rms'" in err and "not an M-SVDD model" in err
    assert not (model / "diagnosis").exists()


def test_too_few_windows_exits_2_before_reading_anything(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["diagnose", str(tmp_path / "model"), "--data", str(tmp_path / "data"), "--max-windows", "5"]
    assert main(argv) == 2
    assert "--max-windows = 5 is invalid; allowed: an integer >= 20" in capsys.readouterr().err


def test_the_ridge_of_held_statistics_is_relative_to_the_spectrum(tiny_model: Path) -> None:
    # with svdd_fit="frozen" the floor adds eps times the raw estimate's mean eigenvalue, not eps I: Sigma is
    # that raw estimate, floored, plus that ridge
    _, model = load_msvdd(tiny_model)
    assert model.config.svdd_fit == "frozen" and model.sigma_raw_ is not None
    raw = model.sigma_raw_.detach().cpu().numpy()
    ridge = ridge_of(model)
    assert ridge == pytest.approx(model.config.eps * np.trace(raw) / raw.shape[0])
    assert model.sigma_ is not None
    sigma = model.sigma_.detach().cpu().numpy()
    assert np.linalg.eigvalsh(sigma).min() >= ridge * (1 - 1e-5)
