"""The M-SVDD detector end to end on the toy task: separation, non-collapse, persistence, bad input."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest
import torch
from sklearn.metrics import roc_auc_score

from msvdd.config import MSVDDConfig
from msvdd.context_net import ContextNet, fit_context_net
from msvdd.contract import Detector, ModelFormatError, WindowError, Windows
from msvdd.model import FORMAT_VERSION, MSVDD, NotFittedError
from msvdd.synthetic import toy_windows


def test_separates_toy_anomalies(toy_test: tuple[Windows, np.ndarray]) -> None:
    # The paper's network size (d = s = 32, MCD on batches of 64), 5 short epochs.
    train, _ = toy_windows(192, 0, seed=0)
    cfg = MSVDDConfig.smoke(d=32, s=32, batch_size=64, val_fraction=0.2)
    model = MSVDD(cfg).fit(train)
    batch, labels = toy_test
    scores = model.score(batch)
    assert roc_auc_score(labels, scores) > 0.85
    # No val given: the threshold is the 95th percentile of the training scores (the internal split's
    # windows included), so 5 % of them are above it.
    assert model.threshold_source_ == "train"
    assert float(np.mean(model.score(train) > model.threshold_)) == pytest.approx(0.05, abs=0.01)


def test_not_collapsed_and_finite(small_model: MSVDD, toy_test: tuple[Windows, np.ndarray]) -> None:
    scores = small_model.score(toy_test[0])
    assert scores.dtype == np.float64 and scores.shape == (80,)
    assert np.all(np.isfinite(scores)) and np.std(scores) > 1e-3 * np.mean(np.abs(scores))
    assert small_model.mu_ is not None and small_model.sigma_ is not None
    assert bool(torch.isfinite(small_model.mu_).all()) and bool(torch.isfinite(small_model.sigma_).all())
    assert np.isfinite(small_model.radius_) and np.isfinite(small_model.threshold_)
    assert torch.linalg.eigvalsh(small_model.sigma_).min() > 0
    z = small_model.embed(toy_test[0])
    assert z.shape == (80, 8) and float(z.std(axis=0).min()) > 0


def test_score_is_delta_of_components(small_model: MSVDD, toy_test: tuple[Windows, np.ndarray]) -> None:
    d, rec = small_model.score_components(toy_test[0])
    w = small_model.config.w
    expected = d + w * (small_model.mean_d_ / small_model.mean_rec_) * rec
    np.testing.assert_allclose(small_model.score(toy_test[0]), expected, rtol=1e-12)
    np.testing.assert_array_equal(small_model.predict(toy_test[0]), expected > small_model.threshold_)


def test_meets_detector_contract(small_model: MSVDD) -> None:
    assert isinstance(small_model, Detector)


def test_save_load_identical(
    small_model: MSVDD, toy_test: tuple[Windows, np.ndarray], tmp_path: Path
) -> None:
    path = tmp_path / "sub" / "model.pt"
    small_model.save(path)
    assert [p.name for p in path.parent.iterdir()] == ["model.pt"]  # no temp file left behind
    loaded = MSVDD.load(path)
    np.testing.assert_array_equal(loaded.score(toy_test[0]), small_model.score(toy_test[0]))
    assert loaded.threshold_ == small_model.threshold_
    assert loaded.config == small_model.config
    # The training history travels with the model (the diagnosis reads R's trajectory from it).
    assert loaded.history_ == small_model.history_ and loaded.history_ is not None
    epochs = small_model.config.epochs
    assert {k: len(v) for k, v in loaded.history_.epochs.items()} == dict.fromkeys(
        ("radius", "svdd", "rec", "reg"), epochs
    )
    kept = loaded.history_.best_epoch  # the weights (R among them) of the best validation epoch are kept
    assert loaded.history_.epochs["radius"][kept] == pytest.approx(small_model.radius_)


def test_load_refuses_other_format_version(small_model: MSVDD, tmp_path: Path) -> None:
    path = tmp_path / "model.pt"
    small_model.save(path)
    payload = torch.load(path, weights_only=True)
    payload["format_version"] = FORMAT_VERSION + 1
    torch.save(payload, path)
    with pytest.raises(ModelFormatError, match=f"version {FORMAT_VERSION + 1}"):
        MSVDD.load(path)
    torch.save({"something": torch.zeros(1)}, path)
    with pytest.raises(ModelFormatError, match="not an M-SVDD model"):
        MSVDD.load(path)
    with pytest.raises(FileNotFoundError, match="does not exist"):
        MSVDD.load(tmp_path / "missing.pt")


def test_load_names_the_file_and_a_missing_or_malformed_field(small_model: MSVDD, tmp_path: Path) -> None:
    path = tmp_path / "model.pt"
    small_model.save(path)
    payload = torch.load(path, weights_only=True)
    del payload["mu"]
    torch.save(payload, path)
    with pytest.raises(ModelFormatError, match=f"{re.escape(str(path))}: field 'mu' is missing"):
        MSVDD.load(path)
    small_model.save(path)
    payload = torch.load(path, weights_only=True)
    payload["config"]["epochs"] = 0
    torch.save(payload, path)
    with pytest.raises(ModelFormatError, match=f"{re.escape(str(path))}: a field is malformed .*epochs"):
        MSVDD.load(path)


def test_same_seed_same_scores(toy_train: Windows, toy_test: tuple[Windows, np.ndarray]) -> None:
    cfg = MSVDDConfig.smoke(epochs=1)
    a = MSVDD(cfg).fit(toy_train).score(toy_test[0])
    b = MSVDD(cfg).fit(toy_train).score(toy_test[0])
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize(
    "overrides",
    [
        {"use_mahalanobis": False},
        {"use_reconstruction": False},
        {"use_audio": False},
        {"use_imu": False},
        {"fusion": "product"},
    ],
)
def test_ablations_train_and_score(overrides: dict[str, object], toy_train: Windows) -> None:
    model = MSVDD(MSVDDConfig.smoke(epochs=1, **overrides)).fit(toy_train)
    scores = model.score(toy_train.subset(slice(0, 10)))
    assert np.all(np.isfinite(scores)) and np.std(scores) > 0
    if overrides.get("use_reconstruction") is False:
        np.testing.assert_array_equal(scores, model.score_components(toy_train.subset(slice(0, 10)))[0])


def test_too_few_windows() -> None:
    few, _ = toy_windows(20, 0, seed=3)
    with pytest.raises(WindowError, match="batch_size=32"):
        MSVDD(MSVDDConfig.smoke()).fit(few)


def test_validation_too_small_for_its_mcd_trains_without_it() -> None:
    some, _ = toy_windows(40, 0, seed=3)
    with pytest.warns(UserWarning, match="too few for the validation MCD in s=16"):
        model = MSVDD(MSVDDConfig.smoke(s=16, val_fraction=0.2)).fit(some)
    assert model.config.val_fraction == 0.0
    assert model.threshold_source_ == "train"
    assert model.threshold_ == np.quantile(model.score(some), 0.95)


def test_bad_input_errors(small_model: MSVDD) -> None:
    with pytest.raises(WindowError, match="Windows"):
        small_model.score(np.zeros((2, 8820, 2)))  # type: ignore[arg-type]
    with pytest.raises(NotFittedError):
        MSVDD(MSVDDConfig.smoke()).score(toy_windows(2, 0, seed=0)[0])


def test_config_validation() -> None:
    with pytest.raises(ValueError, match="not a true subset"):
        MSVDDConfig(batch_size=32, s=32)  # the reference code's batch: h = 33 > 32
    with pytest.raises(ValueError, match="fusion"):
        MSVDDConfig(fusion="attention")
    with pytest.raises(ValueError, match="at least one modality"):
        MSVDDConfig(use_audio=False, use_imu=False)
    with pytest.raises(ValueError, match="quantile"):
        MSVDDConfig(quantile=1.5)
    with pytest.raises(ValueError, match="unknown MSVDDConfig fields: bogus"):
        MSVDDConfig.from_dict({"bogus": 1})
    assert MSVDDConfig.from_dict(MSVDDConfig.full().to_dict()) == MSVDDConfig.full()
    assert MSVDDConfig.full().epochs == 40 and MSVDDConfig.full().alpha == (1.0, 1.0, 0.001)


def test_reads_format_version_1_files(
    small_model: MSVDD, toy_test: tuple[Windows, np.ndarray], tmp_path: Path
) -> None:
    # A version-1 file (the paper's waveform and z-velocity; scalar IMU statistics, no front-end names,
    # no history) scores exactly as the model that wrote it.
    path = tmp_path / "v1.pt"
    small_model.save(path)
    payload = torch.load(path, weights_only=True)
    state = payload["normalizer"]
    payload["normalizer"] = {
        "audio_mean": state["audio_mean"],
        "audio_std": state["audio_std"],
        "imu_mean": state["imu_mean"].reshape(()),
        "imu_std": state["imu_std"].reshape(()),
    }
    payload["format_version"] = 1
    for key in ("audio_frontend", "imu_input"):
        del payload["config"][key]
    del payload["history"]
    torch.save(payload, path)
    loaded = MSVDD.load(path)
    np.testing.assert_array_equal(loaded.score(toy_test[0]), small_model.score(toy_test[0]))


@pytest.mark.parametrize(
    ("audio_frontend", "imu_input"), [("logmel", "z"), ("logmel", "all"), ("waveform", "all")]
)
def test_front_ends_train_save_and_load(
    audio_frontend: str,
    imu_input: str,
    toy_train: Windows,
    toy_test: tuple[Windows, np.ndarray],
    tmp_path: Path,
) -> None:
    cfg = MSVDDConfig.smoke(epochs=1, audio_frontend=audio_frontend, imu_input=imu_input)
    model = MSVDD(cfg).fit(toy_train)
    scores = model.score(toy_test[0])
    assert np.all(np.isfinite(scores)) and np.std(scores) > 0
    model.save(tmp_path / "m.pt")
    np.testing.assert_array_equal(MSVDD.load(tmp_path / "m.pt").score(toy_test[0]), scores)


def test_all_imu_axes_need_imu6(toy_train: Windows) -> None:
    bare = Windows(audio=toy_train.audio, imu=toy_train.imu)
    with pytest.raises(WindowError, match="imu6"):
        MSVDD(MSVDDConfig.smoke(epochs=1, imu_input="all")).fit(bare)


def test_fused_term_by_hand(toy_train: Windows, toy_test: tuple[Windows, np.ndarray], tmp_path: Path) -> None:
    cfg = MSVDDConfig.smoke(epochs=1, audio_frontend="logmel", imu_input="all", frame_density=True)
    model = MSVDD(cfg).fit(toy_train, toy_train.subset(slice(0, 16)))
    assert model.frame_density_ is not None and all(isinstance(m, ContextNet) for m in model.frame_density_)
    audio_net, imu_net = model.frame_density_
    # The log-mel frames' density reads their neighbours only, the IMU frames' also the log-mel frames.
    assert (audio_net.p, audio_net.cross_p) == (64, 0) and (imu_net.p, imu_net.cross_p) == (56, 64)
    # Each term by hand: the networks fitted on the training windows' input frames (no residual: the
    # decoders do not enter), with the model's seed and the validation windows' frames choosing the epoch.
    train_frames = model.input_frames(*model._tensors(toy_train))
    val_frames = model.input_frames(*model._tensors(toy_train.subset(slice(0, 16))))
    peer = fit_context_net(train_frames[1], val_frames[1], cfg.seed, cross=(train_frames[0], val_frames[0]))
    test = toy_test[0].subset(slice(0, 4))
    frames = model.input_frames(*model._tensors(test))
    _, parts = model._distance_and_parts(model._tensors(test))
    np.testing.assert_allclose(parts[:, 1], peer.peak_distance(frames[1], frames[0]).numpy(), rtol=1e-6)
    np.testing.assert_allclose(parts[:, 0], audio_net.peak_distance(frames[0]).numpy(), rtol=1e-6)
    _, rec = model.score_components(toy_train)  # each modality in units of its training mean
    assert float(rec.mean()) == pytest.approx(2.0, rel=1e-6)
    # Persistence, and a file without the networks is refused naming the field.
    path = tmp_path / "m.pt"
    model.save(path)
    np.testing.assert_array_equal(MSVDD.load(path).score(toy_test[0]), model.score(toy_test[0]))
    payload = torch.load(path, weights_only=True)
    del payload["frame_density"]
    torch.save(payload, path)
    with pytest.raises(ModelFormatError, match="field 'frame_density' is missing"):
        MSVDD.load(path)


def test_retired_reconstruction_terms_are_refused_and_their_size_field_dropped() -> None:
    saved = {**MSVDDConfig.smoke().to_dict(), "rec_components": 16}  # a model saved before the retirement
    assert MSVDDConfig.from_dict(saved) == MSVDDConfig.smoke()
    # `rec_score` is retired: "mean" was Rec, "fused" the frame-density term (only with reconstruction).
    old = MSVDDConfig.smoke().to_dict()
    assert MSVDDConfig.from_dict({**old, "rec_score": "mean"}) == MSVDDConfig.smoke()
    fused = MSVDDConfig.from_dict({**old, "rec_score": "fused"})
    assert fused == MSVDDConfig.smoke(frame_density=True)
    no_rec = {**old, "rec_score": "fused", "use_reconstruction": False}
    assert MSVDDConfig.from_dict(no_rec) == MSVDDConfig.smoke(use_reconstruction=False)
    with pytest.raises(ValueError, match=r"rec_score = 'mixture'; allowed: mean \| fused"):
        MSVDDConfig.from_dict({**old, "rec_score": "mixture"})


def test_the_frame_density_term_is_chosen_after_training(toy_train: Windows) -> None:
    # `frame_density` changes scoring only: the network and D are those of the reconstruction term's model.
    cfg = MSVDDConfig.smoke(epochs=1, audio_frontend="logmel", imu_input="all", val_fraction=0.0)
    a = MSVDD(dataclasses.replace(cfg, frame_density=False)).fit(toy_train)
    b = MSVDD(dataclasses.replace(cfg, frame_density=True)).fit(toy_train)
    batch = toy_train.subset(slice(0, 8))
    np.testing.assert_array_equal(a.score_components(batch)[0], b.score_components(batch)[0])


def test_order_view_trains_saves_loads_and_needs_odometry(
    toy_train: Windows, toy_test: tuple[Windows, np.ndarray], tmp_path: Path
) -> None:
    cfg = MSVDDConfig.smoke(
        epochs=2, svdd_fit="frozen", bias_free=True, pooling="stats", order_view=True, stats_every=1
    )
    model = MSVDD(cfg).fit(toy_train)
    scores = model.score(toy_test[0])
    assert np.all(np.isfinite(scores)) and np.std(scores) > 0
    model.save(tmp_path / "m.pt")
    np.testing.assert_array_equal(MSVDD.load(tmp_path / "m.pt").score(toy_test[0]), scores)
    bare = Windows(audio=toy_test[0].audio, imu=toy_test[0].imu, imu6=toy_test[0].imu6)
    with pytest.raises(WindowError, match=r"odometry is None.*order_view"):
        model.score(bare)
    with pytest.raises(WindowError, match="odometry is None"):
        MSVDD(cfg).fit(Windows(audio=toy_train.audio, imu=toy_train.imu, imu6=toy_train.imu6))
    # the score reads the wheels' angles: other angles, other scores
    spun = Windows(
        audio=toy_test[0].audio,
        imu=toy_test[0].imu,
        imu6=toy_test[0].imu6,
        odometry=(toy_test[0].odometry * np.float32(1.5)) if toy_test[0].odometry is not None else None,
    )
    assert not np.allclose(model.score(spun), scores)
