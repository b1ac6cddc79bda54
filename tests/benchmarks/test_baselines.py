"""SVDD = OCSVM with an RBF kernel, the shallow and naive baselines, and the registry's save/load errors."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import torch
from scipy.optimize import minimize
from scipy.stats import kurtosis, multivariate_normal, spearmanr
from sklearn.svm import OneClassSVM

from benchmarks import methods
from benchmarks.methods import naive
from benchmarks.methods.deep import DAGMM_RIDGE, _center, gmm_energy, gmm_parameters
from benchmarks.methods.shallow import ShallowConfig, ShallowDetector
from msvdd.config import MSVDDConfig
from msvdd.contract import ModelFormatError
from msvdd.synthetic import toy_windows


def _blob(n: int = 60, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.standard_normal((n, 2)) * np.array([1.0, 0.5])


def _rbf(a: np.ndarray, b: np.ndarray, gamma: float) -> np.ndarray:
    return np.exp(-gamma * ((a[:, None, :] - b[None, :, :]) ** 2).sum(axis=2))


def test_svdd_dual_equals_one_class_svm_for_rbf() -> None:
    # Why `svdd-*` is fitted as `ocsvm-*`: with K_ii = 1 the SVDD dual (Tax & Duin), min a'Ka - a'diag(K)
    # with sum a = 1 and 0 <= a <= 1 / (nu n), solved here by a generic QP, has the one-class SVM's
    # (Schölkopf) minimiser scaled by 1 / (nu n), and the SVDD distance ranks points as the OCSVM does.
    x = _blob(40, seed=2)
    nu, gamma = 0.2, 0.7
    k = _rbf(x, x, gamma)
    c = 1.0 / (nu * len(x))
    solved = minimize(
        lambda a: a @ k @ a - np.diag(k) @ a,
        np.full(len(x), 1.0 / len(x)),
        jac=lambda a: 2.0 * k @ a - np.diag(k),
        bounds=[(0.0, c)] * len(x),
        constraints=[{"type": "eq", "fun": lambda a: a.sum() - 1.0, "jac": lambda a: np.ones_like(a)}],
        method="SLSQP",
        options={"ftol": 1e-14, "maxiter": 1000},
    )
    assert solved.success
    ocsvm = OneClassSVM(kernel="rbf", nu=nu, gamma=gamma, tol=1e-10).fit(x)
    ref = np.zeros(len(x))
    ref[ocsvm.support_] = ocsvm.dual_coef_[0] / (nu * len(x))
    np.testing.assert_allclose(solved.x, ref, atol=1e-5)
    probe = np.random.default_rng(3).standard_normal((50, 2)) * 2
    a = solved.x
    svdd_dist2 = 1.0 - 2.0 * _rbf(probe, x, gamma) @ a + a @ k @ a
    ocsvm_score = -ocsvm.decision_function(probe)
    assert spearmanr(svdd_dist2, ocsvm_score).statistic == pytest.approx(1.0)
    np.testing.assert_allclose(np.corrcoef(svdd_dist2, ocsvm_score)[0, 1], 1.0, atol=1e-8)


def test_svdd_rows_equal_ocsvm_rows_by_construction() -> None:
    windows, _ = toy_windows(40, 8, seed=12)
    train, test = windows.subset(slice(0, 32)), windows.subset(slice(32, None))
    for fusion in ("early", "late"):
        svdd = methods.make(f"svdd-{fusion}", seed=0, scale="smoke").fit(train)
        ocsvm = methods.make(f"ocsvm-{fusion}", seed=0, scale="smoke").fit(train)
        np.testing.assert_array_equal(svdd.score(test), ocsvm.score(test))
        assert svdd.threshold_ == ocsvm.threshold_


def test_model_of_the_former_svdd_solver_is_refused(tmp_path: Path) -> None:
    windows, _ = toy_windows(30, 0, seed=13)
    det = methods.make("svdd-early", seed=0, scale="smoke").fit(windows)
    path = tmp_path / "model.npz"
    det.save(path)
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    arrays["b0_support"] = arrays["b0_train_x"][:3]
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)
    with pytest.raises(ModelFormatError, match="former hand-written SVDD solver"):
        ShallowDetector.load(path)


def test_naive_statistics_match_closed_forms() -> None:
    windows, _ = toy_windows(5, 3, seed=4)
    audio = windows.audio.astype(np.float64)
    np.testing.assert_allclose(
        naive.window_rms(windows.audio), np.sqrt((audio**2).mean(axis=(1, 2))), rtol=1e-12
    )
    np.testing.assert_allclose(
        naive.window_kurtosis(windows.imu), kurtosis(windows.imu.astype(np.float64), axis=1)
    )
    assert naive.window_kurtosis(np.ones((1, 400)))[0] == 0.0


def test_late_fusion_scores_are_z_normalised_per_modality() -> None:
    windows, _ = toy_windows(40, 0, seed=5)
    det = ShallowDetector(ShallowConfig(model="svdd", fusion="late", seed=0)).fit(windows)
    blocks = det._blocks
    assert len(blocks) == 2
    train_scores = det.score(windows)
    # averaging two training-z-scored series gives mean 0 on the training windows
    assert train_scores.mean() == pytest.approx(0.0, abs=1e-9)
    assert det.threshold_ == pytest.approx(np.percentile(train_scores, 95))


def test_refit_that_does_not_reproduce_training_scores_is_refused(tmp_path: Path) -> None:
    windows, _ = toy_windows(30, 0, seed=6)
    det = methods.make("iforest-early", seed=0, scale="smoke").fit(windows)
    path = tmp_path / "model.npz"
    det.save(path)
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    arrays["b0_train_scores"] = arrays["b0_train_scores"] + 1e-9
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)
    with pytest.raises(ModelFormatError, match="did not reproduce"):
        ShallowDetector.load(path)


def test_registry_errors(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"allowed: .*iforest-early"):
        methods.make("no-such-method", seed=0, scale="smoke")
    with pytest.raises(ValueError, match="device 'tpu'"):
        methods.make("audio-rms", seed=0, scale="smoke", device="tpu")
    with pytest.raises(ValueError, match="scale 'huge'"):
        methods.make("audio-rms", seed=0, scale="huge")
    with pytest.raises(ValueError, match=r"'tiny' is unknown; allowed: smoke, short, full .*dataset preset"):
        methods.make("audio-rms", seed=0, scale="tiny")
    with pytest.raises(ValueError, match="already registered"):
        methods.register(
            "audio-rms",
            lambda s, c, d: naive.AudioRMS(),
            cls=naive.AudioRMS,
            family="naive",
            modality="audio",
            description="",
        )
    assert set(methods.names("naive")) == {"audio-rms", "imu-kurtosis"}
    with pytest.raises(FileNotFoundError, match=r"method\.json"):
        methods.load_detector(tmp_path)
    windows, _ = toy_windows(10, 0, seed=7)
    det = methods.make("audio-rms", seed=0, scale="smoke").fit(windows)
    folder = methods.save_detector(det, "audio-rms", tmp_path / "m")
    info = json.loads((folder / "method.json").read_text())
    assert info["method"] == "audio-rms" and "numpy" in info["versions"]
    info["format_version"] = 99
    (folder / "method.json").write_text(json.dumps(info))
    with pytest.raises(ModelFormatError, match="format_version 99"):
        methods.load_detector(folder)
    methods.save_detector(det, "audio-rms", folder)
    (folder / "model.bin").unlink()
    with pytest.raises(FileNotFoundError, match=r"model\.bin"):
        methods.load_detector(folder)
    with pytest.raises(ModelFormatError, match="'audio-rms' model, expected 'imu-kurtosis'"):
        det.save(tmp_path / "x.npz")
        naive.IMUKurtosis.load(tmp_path / "x.npz")


def test_dagmm_energy_matches_scipy_mixture_density() -> None:
    rng = np.random.default_rng(8)
    x = rng.standard_normal((40, 3))
    gamma = rng.dirichlet(np.ones(2), size=40)
    phi, mu, cov = gmm_parameters(torch.from_numpy(x), torch.from_numpy(gamma))
    weights = gamma.sum(axis=0)
    np.testing.assert_allclose(phi.numpy(), weights / 40)
    for k in range(2):
        want_mu = gamma[:, k] @ x / weights[k]
        centred = x - want_mu
        want_cov = (gamma[:, k, None] * centred).T @ centred / weights[k] + DAGMM_RIDGE * np.eye(3)
        np.testing.assert_allclose(mu[k].numpy(), want_mu, atol=1e-12)
        np.testing.assert_allclose(cov[k].numpy(), want_cov, atol=1e-12)
    probe = rng.standard_normal((5, 3))
    density = sum(
        float(phi[k]) * multivariate_normal(mu[k].numpy(), cov[k].numpy()).pdf(probe) for k in range(2)
    )
    energy = gmm_energy(torch.from_numpy(probe), phi, mu, cov).numpy()
    np.testing.assert_allclose(energy, -np.log(density), rtol=1e-9)


def test_deep_svdd_centre_is_kept_away_from_zero() -> None:
    z = torch.tensor([[0.05, -0.02, 1.0], [0.03, -0.04, 3.0]])
    np.testing.assert_allclose(_center(z).numpy(), [0.1, -0.1, 2.0])


def test_shallow_subsampling_is_recorded_and_survives_save(tmp_path: Path) -> None:
    windows, _ = toy_windows(30, 0, seed=9)
    config = ShallowConfig(model="svdd", fusion="early", seed=0, max_train=20)
    det = ShallowDetector(config).fit(windows)
    assert det.training_rows == [(30, 20)]
    det.save(tmp_path / "m.npz")
    assert ShallowDetector.load(tmp_path / "m.npz").training_rows == [(30, 20)]


def test_registry_lists_every_family_of_the_paper() -> None:
    by_family = {f: methods.names(f) for f in methods.FAMILIES}
    assert sorted(n for v in by_family.values() for n in v) == sorted(methods.names())
    assert {"msvdd", "msvdd-euclidean", "msvdd-s64"} <= set(by_family["msvdd"])
    assert set(by_family["deep"]) == {"dsvdd", "dae", "vae-svdd", "dagmm", "deep-if", "dcase-ae"}
    assert len(by_family["shallow"]) == 6
    assert set(by_family["reference"]) == {
        "gaussian-early",
        "gaussian-audio",
        "gaussian-imu",
        "frame-density-msvdd",
        "frame-density",
        "context-net-frames",
        "order-reference",
    }
    # The paper's per-batch MCD needs batches of 2 s; the held statistics do not.
    assert methods.make("msvdd-s64", seed=0, scale="full").config.batch_size == 64  # type: ignore[attr-defined]
    frames = methods.make("frame-density-msvdd", seed=0, scale="full").config  # type: ignore[attr-defined]
    assert frames.svdd_fit == "batch" and frames.batch_size == 64


def test_msvdd_is_the_paper_model_and_the_frame_density_detector_has_its_own_name() -> None:
    def config(name: str) -> MSVDDConfig:
        return methods.make(name, seed=0, scale="full").config  # type: ignore[attr-defined,no-any-return]

    current, paper, frames = config("msvdd"), config("msvdd-paper"), config("frame-density-msvdd")
    # msvdd: D + w Rec of its own decoders, the held-statistics fit; the frame term only under its own name.
    assert not current.frame_density and current.use_reconstruction and current.svdd_fit == "frozen"
    assert current.bias_free and not paper.bias_free
    assert not paper.frame_density and paper.svdd_fit == "batch"
    assert frames.frame_density and frames.svdd_fit == "batch" and frames.w == 100.0
    assert current.audio_frontend == frames.audio_frontend == "logmel" and paper.audio_frontend == "waveform"
    # Each ablation is msvdd with one switch.
    for name, field, value in (
        ("msvdd-no-rec", "use_reconstruction", False),
        ("msvdd-euclidean", "use_mahalanobis", False),
        ("msvdd-imu-only", "use_audio", False),
        ("msvdd-audio-only", "use_imu", False),
        ("msvdd-fusion-sum", "fusion", "sum"),
        ("msvdd-s16", "s", 16),
    ):
        assert config(name) == dataclasses.replace(current, **{field: value}), name


def test_msvdd_paper_trains_without_a_validation_set_too_small_for_its_mcd() -> None:
    torch.set_num_threads(1)
    windows, _ = toy_windows(48, 0, seed=10)
    det = methods.make("msvdd-paper", seed=0, scale="smoke")
    with pytest.warns(UserWarning, match="too few for the validation MCD"):
        det.fit(windows.subset(slice(0, 40)), windows.subset(slice(40, 45)))
    assert np.isfinite(det.threshold_)
    assert np.ptp(det.score(windows.subset(slice(45, 48)))) > 0


def test_models_saved_before_the_renaming_load_under_the_new_name_or_are_refused(tmp_path: Path) -> None:
    """A model folder of the old `msvdd` (model format 3: the frame-density term as `rec_score="fused"`) loads
    as `frame-density-msvdd`; an old model of an entry that changed what it is is refused, saying why."""
    torch.set_num_threads(1)
    train, _ = toy_windows(40, 0, seed=10)
    det = methods.make("frame-density-msvdd", seed=0, scale="smoke")
    det.config = dataclasses.replace(det.config, epochs=1)  # type: ignore[attr-defined]
    det.fit(train)
    folder = methods.save_detector(det, "frame-density-msvdd", tmp_path / "old")
    payload = torch.load(folder / "model.bin", weights_only=True)
    new_fields = ("frame_density", "svdd_fit", "stats_warmup", "stats_every", "variance_floor", "bias_free")
    payload["config"] = {k: v for k, v in payload["config"].items() if k not in new_fields}
    payload["config"]["rec_score"] = "fused"
    payload["rec_gauss"] = payload.pop("frame_density")
    for key in ("sigma_raw", "stats_fits"):
        del payload[key]
    payload["format_version"] = 3
    torch.save(payload, folder / "model.bin")
    info = json.loads((folder / "method.json").read_text())
    (folder / "method.json").write_text(json.dumps({**info, "method": "msvdd"}))
    name, loaded = methods.load_detector(folder)
    assert name == "frame-density-msvdd"
    batch = train.subset(slice(0, 5))
    np.testing.assert_array_equal(loaded.score(batch), det.score(batch))
    (folder / "method.json").write_text(json.dumps({**info, "method": "msvdd-no-rec"}))
    with pytest.raises(ModelFormatError, match=r"model\.bin: this 'msvdd-no-rec' model was saved .* again"):
        methods.load_detector(folder)
