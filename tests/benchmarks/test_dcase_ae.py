"""The DCASE 2020 Task 2 autoencoder baseline (`dcase-ae`): separation, and its score against an oracle."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from benchmarks import methods
from benchmarks.features import FeatureConfig, log_mel
from benchmarks.methods.dcase_ae import DcaseAEConfig, DcaseAutoencoder
from benchmarks.metrics import roc_auc
from msvdd.synthetic import toy_windows

torch.set_num_threads(1)


def test_dcase_ae_separates_the_toy_anomalies() -> None:
    train, _ = toy_windows(80, 0, seed=21)
    test, labels = toy_windows(30, 30, seed=22)
    det = methods.make("dcase-ae", seed=0, scale="smoke").fit(train)
    assert roc_auc(labels, det.score(test)) > 0.9
    assert methods.spec("dcase-ae").modality == "audio"


def _oracle_scores(path: Path, audio: np.ndarray) -> np.ndarray:
    """Scores recomputed from the saved file alone: log-mel, 5-frame vectors, numpy forward pass, mean MSE."""
    with np.load(path) as data:
        arrays = {k: data[k].astype(np.float64) for k in data.files if k != "__header__"}
    mel = log_mel(audio, FeatureConfig(n_fft=256, hop=128, n_mels=32)).astype(np.float64)
    n_vec = mel.shape[1] - 4
    vectors = np.stack([mel[:, t : t + 5, :].reshape(len(audio), 160) for t in range(n_vec)], axis=1)
    h = (vectors - arrays["mean"]) / arrays["std"]
    x = h
    widths = []
    for block in range(9):  # (Linear, BatchNorm, ReLU) x (4 + bottleneck + 4), then the linear output
        lin, bn = f"net/{3 * block}.", f"net/{3 * block + 1}."
        widths.append(arrays[lin + "weight"].shape[0])
        h = h @ arrays[lin + "weight"].T + arrays[lin + "bias"]
        h = (h - arrays[bn + "running_mean"]) / np.sqrt(arrays[bn + "running_var"] + 1e-5)
        h = np.maximum(h * arrays[bn + "weight"] + arrays[bn + "bias"], 0.0)
    out = h @ arrays["net/27.weight"].T + arrays["net/27.bias"]
    assert widths == [128, 128, 128, 128, 8, 128, 128, 128, 128] and out.shape[-1] == 160
    return ((out - x) ** 2).mean(axis=2).mean(axis=1)


def test_dcase_ae_score_is_the_mean_frame_reconstruction_error(tmp_path: Path) -> None:
    train, _ = toy_windows(40, 0, seed=23)
    test, _ = toy_windows(4, 4, seed=24)
    det = methods.make("dcase-ae", seed=1, scale="smoke").fit(train)
    det.save(tmp_path / "model.npz")
    want = _oracle_scores(tmp_path / "model.npz", test.audio)
    np.testing.assert_allclose(det.score(test), want, rtol=1e-4)
    np.testing.assert_allclose(DcaseAutoencoder.load(tmp_path / "model.npz").score(test), want, rtol=1e-4)


def test_dcase_ae_scales_and_frame_vectors() -> None:
    epochs = [DcaseAEConfig.for_scale(0, s).epochs for s in methods.SCALES]
    assert epochs == sorted(epochs) and all(
        DcaseAEConfig.for_scale(0, s).batch_size == 512 for s in methods.SCALES
    )
    windows, _ = toy_windows(2, 0, seed=25)
    det = DcaseAutoencoder(DcaseAEConfig())
    assert det.vectors(windows).shape == (2, 63, 160)  # 67 frames of 2 s at hop 128, 5-frame context
    with pytest.raises(ValueError, match="scale"):
        DcaseAEConfig.for_scale(0, "huge")
