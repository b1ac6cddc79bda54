"""The residual frame Gaussian of `rec_score="mahalanobis"` and the frame mixture of `"mixture"` against
scikit-learn and scipy."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.spatial.distance import mahalanobis
from sklearn.covariance import LedoitWolf

from msvdd import residual
from msvdd.residual import FrameGaussian, fit_frame_gaussian, ledoit_wolf, residual_frames


@pytest.mark.parametrize("block", [7, 65536])
def test_ledoit_wolf_is_scikit_learns(block: int, monkeypatch: pytest.MonkeyPatch) -> None:
    # Correlated, offset data; the sums run over blocks of 7 frames or in one block: the same estimate.
    monkeypatch.setattr(residual, "_BLOCK", block)
    rng = np.random.default_rng(0)
    x = (rng.standard_normal((200, 6)) @ rng.standard_normal((6, 6)) + 3.0).astype(np.float32)
    mean, cov, shrinkage = ledoit_wolf(torch.from_numpy(x))
    peer = LedoitWolf().fit(x.astype(np.float64))
    np.testing.assert_allclose(mean.numpy(), peer.location_, rtol=1e-12)
    np.testing.assert_allclose(cov.numpy(), peer.covariance_, rtol=1e-10, atol=1e-12)
    assert shrinkage == pytest.approx(peer.shrinkage_, rel=1e-10) and 0.0 < shrinkage < 1.0
    with pytest.raises(ValueError, match="at least 2 frames"):
        ledoit_wolf(torch.zeros(1, 3))


def test_peak_distance_is_the_largest_mahalanobis_distance_of_a_window() -> None:
    rng = np.random.default_rng(1)
    train = rng.standard_normal((500, 4)) @ np.diag([1.0, 2.0, 0.5, 3.0])
    gauss = fit_frame_gaussian(torch.from_numpy(train))
    _, cov, _ = ledoit_wolf(torch.from_numpy(train))
    precision = np.linalg.inv(cov.numpy())
    frames = rng.standard_normal((3, 5, 4))
    got = gauss.peak_distance(torch.from_numpy(frames)).numpy()
    want = [max(mahalanobis(f, gauss.mean.numpy(), precision) for f in window) for window in frames]
    np.testing.assert_allclose(got, want, rtol=1e-10)
    again = FrameGaussian.from_state(gauss.state(), torch.device("cpu"))
    np.testing.assert_array_equal(again.peak_distance(torch.from_numpy(frames)).numpy(), got)


def test_residual_frames_cut_the_time_axis_into_blocks() -> None:
    # IMU (N, 400, 7): frame t holds samples 8t..8t+7 of every channel, sample major.
    x = torch.arange(2 * 400 * 7, dtype=torch.float64).reshape(2, 400, 7)
    frames = residual_frames(x, torch.zeros_like(x), 1, 8)
    assert frames.shape == (2, 50, 56)
    assert torch.equal(frames[1, 3], x[1, 24:32].reshape(-1))
    # Log-mel (N, 2, T, M): frame t holds both channels' bands at frame t; a remainder is dropped.
    m = torch.randn(3, 2, 67, 32)
    m_hat = torch.randn(3, 2, 67, 32)
    frames = residual_frames(m, m_hat, 2, 1)
    assert frames.shape == (3, 67, 64)
    assert torch.equal(frames[2, 10], (m - m_hat)[2, :, 10].reshape(-1))
    assert residual_frames(x, x, 1, 9).shape == (2, 44, 63)


def test_frame_mixture_is_scikit_learns_and_its_distance_never_goes_below_the_floor() -> None:
    # Three separated clusters in 3-D; the fitted mixture scores frames as scikit-learn's own score_samples.
    from sklearn.mixture import GaussianMixture

    rng = np.random.default_rng(2)
    centres = np.array([[0.0, 0.0, 0.0], [6.0, 0.0, 1.0], [0.0, -5.0, 4.0]])
    train = np.concatenate([c + rng.standard_normal((300, 3)) * [1.0, 0.5, 2.0] for c in centres])
    mixture = residual.fit_frame_mixture(torch.from_numpy(train), components=3, seed=4)
    peer = GaussianMixture(3, covariance_type="full", reg_covar=residual.MIXTURE_REG, random_state=4)
    peer.fit(train)
    frames = rng.standard_normal((4, 6, 3)) * 4.0
    nll = mixture.nll(torch.from_numpy(frames)).numpy()
    np.testing.assert_allclose(nll, -peer.score_samples(frames.reshape(-1, 3)).reshape(4, 6), rtol=1e-10)
    # The floor is the smallest nll there is: no frame, not even a component's own mean, goes below it.
    means = torch.from_numpy(peer.means_)
    assert float(mixture.nll(means).min()) >= mixture.floor - 1e-12
    got = mixture.peak_distance(torch.from_numpy(frames)).numpy()
    np.testing.assert_allclose(got, np.sqrt(2.0 * (nll.max(axis=1) - mixture.floor)), rtol=1e-12)
    again = residual.FrameMixture.from_state(mixture.state(), torch.device("cpu"))
    np.testing.assert_array_equal(again.peak_distance(torch.from_numpy(frames)).numpy(), got)
    with pytest.raises(ValueError, match="needs at least 5 frames, got 4"):
        residual.fit_frame_mixture(torch.zeros(4, 3), components=5, seed=0)


def test_one_component_mixture_distance_is_the_mahalanobis_distance() -> None:
    # With K = 1, sqrt(2 (nll - floor)) = sqrt((x - m)^T C^-1 (x - m)): the measure of `FrameGaussian`.
    rng = np.random.default_rng(3)
    train = rng.standard_normal((400, 4)) @ rng.standard_normal((4, 4))
    mixture = residual.fit_frame_mixture(torch.from_numpy(train), components=1, seed=0)
    cov = np.cov(train, rowvar=False, bias=True) + residual.MIXTURE_REG * np.eye(4)
    frames = rng.standard_normal((3, 5, 4))
    want = [max(mahalanobis(f, train.mean(axis=0), np.linalg.inv(cov)) for f in w) for w in frames]
    np.testing.assert_allclose(mixture.peak_distance(torch.from_numpy(frames)).numpy(), want, rtol=1e-8)


def test_mixture_fits_a_seeded_sample_of_the_frames(monkeypatch: pytest.MonkeyPatch) -> None:
    # More frames than MIXTURE_FRAMES: the fit sees a sample fixed by the seed, the same one every time.
    monkeypatch.setattr(residual, "MIXTURE_FRAMES", 50)
    x = torch.from_numpy(np.random.default_rng(5).standard_normal((400, 2)))
    a, b = (residual.fit_frame_mixture(x, components=2, seed=1) for _ in range(2))
    np.testing.assert_array_equal(a.means.numpy(), b.means.numpy())
    full = residual.fit_frame_mixture(x[:50], components=1, seed=1)
    sample = residual.fit_frame_mixture(x, components=1, seed=1)
    assert not np.allclose(full.means.numpy(), sample.means.numpy())  # a sample of 400, not the first 50
