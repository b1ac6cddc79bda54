"""`gaussian-frames` (msvdd's frame-wise Mahalanobis term without the network), `mixture-frames`,
`context-frames` and `context-net-frames` against scikit-learn, scipy, `msvdd.context` and
`msvdd.context_net`."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
from scipy.spatial.distance import mahalanobis
from scipy.special import logsumexp
from scipy.stats import multivariate_normal
from sklearn.covariance import LedoitWolf

from benchmarks import methods
from benchmarks.methods.frames import (
    MIXTURE_COMPONENTS,
    ContextFrameReference,
    FrameReference,
    LearnedContextFrameReference,
    MixtureFrameReference,
)
from msvdd.context import CONTEXT_DIM, CONTEXT_NEIGHBOURS, fit_context_mixture
from msvdd.context_net import fit_context_net
from msvdd.contract import WindowError
from msvdd.frontend import InputNormalizer
from msvdd.residual import MIXTURE_REG
from msvdd.synthetic import toy_windows


def _input_frames(norm: InputNormalizer, batch: object) -> list[np.ndarray]:
    """msvdd's normalised inputs cut into log-mel frames (67 x 64) and IMU frames (50 x 56), float64."""
    audio, imu = norm.tensors(batch)  # type: ignore[arg-type]
    n = audio.shape[0]
    return [
        audio.permute(0, 2, 1, 3).reshape(n, 67, 64).numpy().astype(np.float64),
        imu.reshape(n, 50, 56).numpy().astype(np.float64),
    ]


def _covariance(precision_cholesky: np.ndarray) -> np.ndarray:
    """A component's covariance C from scikit-learn's factor P (P P^T = C^-1)."""
    return np.linalg.inv(precision_cholesky @ precision_cholesky.T)


def test_scores_are_the_largest_frame_distances_by_hand(tmp_path: Path) -> None:
    train, _ = toy_windows(40, 0, seed=3)
    test, labels = toy_windows(3, 3, seed=4)
    det = methods.make("gaussian-frames", seed=0, scale="smoke").fit(train)
    assert isinstance(det, FrameReference)
    # By hand: msvdd's normalised inputs, cut into log-mel frames (both channels' 32 bands) and 8-sample IMU
    # frames (7 axes); per modality scikit-learn's Ledoit-Wolf Gaussian of the training frames, scipy's
    # Mahalanobis distance, the largest over a window's frames, over its training mean; summed.
    norm = InputNormalizer.fit(train, "logmel", "all")
    want = np.zeros(len(test))
    for tr, te in zip(_input_frames(norm, train), _input_frames(norm, test), strict=True):
        peer = LedoitWolf().fit(tr.reshape(-1, tr.shape[2]))
        precision = np.linalg.inv(peer.covariance_)

        def peak(x: np.ndarray, p: LedoitWolf = peer, inv: np.ndarray = precision) -> np.ndarray:
            return np.array([max(mahalanobis(f, p.location_, inv) for f in w) for w in x])

        want += peak(te) / peak(tr).mean()
    np.testing.assert_allclose(det.score(test), want, rtol=1e-5)
    assert det.score(test)[labels == 1].min() > det.score(test)[labels == 0].max()  # the toy anomalies
    det.save(tmp_path / "m.npz")
    np.testing.assert_array_equal(FrameReference.load(tmp_path / "m.npz").score(test), det.score(test))


def test_mixture_scores_are_peak_mixture_distances_in_units_of_training_means(tmp_path: Path) -> None:
    train, _ = toy_windows(40, 0, seed=3)
    test, labels = toy_windows(3, 3, seed=4)
    det = methods.make("mixture-frames", seed=5, scale="smoke").fit(train)
    assert isinstance(det, MixtureFrameReference)
    assert [m.means.shape[0] for m in det.mixtures] == [MIXTURE_COMPONENTS, MIXTURE_COMPONENTS]
    # By hand: each frame's mixture density from scipy's multivariate normal with the fitted weights, means
    # and covariances (log-sum-exp over components); the floor is the largest component density at its own
    # mean; per modality sqrt(2 (largest negative log-likelihood - floor)) of a window, over its training
    # mean; summed.
    norm = InputNormalizer.fit(train, "logmel", "all")
    want = np.zeros(len(test))
    for m, tr, te in zip(det.mixtures, _input_frames(norm, train), _input_frames(norm, test), strict=True):
        parts = [
            (lw, multivariate_normal(mu, _covariance(p)))
            for lw, mu, p in zip(
                m.log_weights.numpy(), m.means.numpy(), m.precision_cholesky.numpy(), strict=True
            )
        ]
        floor = -max(g.logpdf(g.mean) for _, g in parts)

        def peak(x: np.ndarray, parts: list[Any] = parts, floor: float = floor) -> np.ndarray:
            flat = x.reshape(-1, x.shape[2])
            nll = -logsumexp(np.stack([lw + g.logpdf(flat) for lw, g in parts]), axis=0)
            return np.sqrt(2.0 * (nll.reshape(x.shape[:2]).max(axis=1) - floor))

        want += peak(te) / peak(tr).mean()
    np.testing.assert_allclose(det.score(test), want, rtol=1e-6)
    assert det.score(test)[labels == 1].min() > det.score(test)[labels == 0].max()  # the toy anomalies
    det.save(tmp_path / "m.npz")
    np.testing.assert_array_equal(MixtureFrameReference.load(tmp_path / "m.npz").score(test), det.score(test))
    again = methods.make("mixture-frames", seed=5, scale="smoke").fit(train)
    np.testing.assert_array_equal(again.score(test), det.score(test))  # the seed fixes the fit


def test_one_component_is_the_maximum_likelihood_gaussian() -> None:
    train, _ = toy_windows(20, 0, seed=6)
    det = MixtureFrameReference(seed=0, components=1).fit(train)
    norm = InputNormalizer.fit(train, "logmel", "all")
    for m, frames in zip(det.mixtures, _input_frames(norm, train), strict=True):
        flat = frames.reshape(-1, frames.shape[2])
        np.testing.assert_allclose(m.means[0].numpy(), flat.mean(axis=0), atol=1e-9)
        want = np.cov(flat, rowvar=False, bias=True) + MIXTURE_REG * np.eye(flat.shape[1])
        np.testing.assert_allclose(_covariance(m.precision_cholesky[0].numpy()), want, atol=1e-8)


def test_mixture_needs_as_many_frames_as_components() -> None:
    train, _ = toy_windows(2, 0, seed=6)  # 2 x 67 log-mel frames
    with pytest.raises(WindowError, match="at least 200 training frames per modality; got 134"):
        MixtureFrameReference(seed=0, components=200).fit(train)
    with pytest.raises(ValueError, match="components = 0 is invalid"):
        MixtureFrameReference(components=0)


def test_context_scores_are_conditional_peak_distances_in_units_of_training_means(tmp_path: Path) -> None:
    train, _ = toy_windows(40, 0, seed=3)
    test, labels = toy_windows(3, 3, seed=4)
    det = methods.make("context-frames", seed=5, scale="smoke").fit(train)
    assert isinstance(det, ContextFrameReference)
    # By hand: msvdd's normalised input frames per modality (log-mel 67 x 64, IMU 50 x 56), each modality's
    # conditional mixture given two neighbours on either side (`msvdd.context`, tested there against the
    # Gaussian conditional), its largest conditional distance over a window, over its training mean; summed.
    norm = InputNormalizer.fit(train, "logmel", "all")
    want = np.zeros(len(test))
    for tr, te in zip(_input_frames(norm, train), _input_frames(norm, test), strict=True):
        model = fit_context_mixture(torch.from_numpy(tr), MIXTURE_COMPONENTS, seed=5)
        assert model.neighbours == CONTEXT_NEIGHBOURS and model.basis.shape[1] == CONTEXT_DIM
        want += (
            model.peak_distance(torch.from_numpy(te)).numpy()
            / model.peak_distance(torch.from_numpy(tr)).numpy().mean()
        )
    np.testing.assert_allclose(det.score(test), want, rtol=1e-6)
    assert det.score(test)[labels == 1].min() > det.score(test)[labels == 0].max()  # the toy anomalies
    det.save(tmp_path / "m.npz")
    np.testing.assert_array_equal(ContextFrameReference.load(tmp_path / "m.npz").score(test), det.score(test))
    with pytest.raises(WindowError, match="at least 200 training frames per modality; got 134"):
        ContextFrameReference(seed=0, components=200).fit(toy_windows(2, 0, seed=6)[0])


def test_context_net_scores_the_audio_by_its_network_and_the_imu_by_the_context_mixture(
    tmp_path: Path,
) -> None:
    train, _ = toy_windows(40, 0, seed=3)
    val, _ = toy_windows(10, 0, seed=7)
    test, labels = toy_windows(3, 3, seed=4)
    det = methods.make("context-net-frames", seed=5, scale="smoke").fit(train, val)
    assert isinstance(det, LearnedContextFrameReference)
    # By hand: the log-mel frames' `ContextNet` (the validation windows' frames choosing its epoch; tested in
    # tests/msvdd/test_context_net.py), the IMU frames' context mixture, each window's largest distance over
    # its training mean, summed.
    norm = InputNormalizer.fit(train, "logmel", "all")
    (a_tr, i_tr), (a_te, i_te) = _input_frames(norm, train), _input_frames(norm, test)
    a_val = torch.from_numpy(_input_frames(norm, val)[0])
    net = fit_context_net(torch.from_numpy(a_tr).float(), a_val.float(), seed=5)
    imu = fit_context_mixture(torch.from_numpy(i_tr), MIXTURE_COMPONENTS, seed=5)
    want = np.zeros(len(test))
    for model, tr, te in ((net, a_tr, a_te), (imu, i_tr, i_te)):
        want += (
            model.peak_distance(torch.from_numpy(te)).numpy()
            / model.peak_distance(torch.from_numpy(tr)).numpy().mean()
        )
    np.testing.assert_allclose(det.score(test), want, rtol=1e-5)
    assert det.score(test)[labels == 1].min() > det.score(test)[labels == 0].max()  # the toy anomalies
    det.save(tmp_path / "m.npz")
    loaded = LearnedContextFrameReference.load(tmp_path / "m.npz")
    np.testing.assert_array_equal(loaded.score(test), det.score(test))
    again = methods.make("context-net-frames", seed=5, scale="smoke").fit(train, val)
    np.testing.assert_array_equal(again.score(test), det.score(test))
    with pytest.raises(WindowError, match="at least 200 training frames per modality; got 100"):
        LearnedContextFrameReference(seed=0, components=200).fit(toy_windows(2, 0, seed=6)[0])
