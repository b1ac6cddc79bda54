"""Frames of a window and the frame mixture (the building block of `msvdd.context.ContextMixture`) against
scikit-learn and scipy."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.spatial.distance import mahalanobis

from msvdd import residual
from msvdd.residual import cut_frames


def test_frames_cut_the_time_axis_into_blocks() -> None:
    # IMU (N, 400, 7): frame t holds samples 8t..8t+7 of every channel, sample major.
    x = torch.arange(2 * 400 * 7, dtype=torch.float64).reshape(2, 400, 7)
    frames = cut_frames(x, 1, 8)
    assert frames.shape == (2, 50, 56)
    assert torch.equal(frames[1, 3], x[1, 24:32].reshape(-1))
    # Log-mel (N, 2, T, M): frame t holds both channels' bands at frame t; a remainder is dropped.
    m = torch.randn(3, 2, 67, 32)
    frames = cut_frames(m, 2, 1)
    assert frames.shape == (3, 67, 64)
    assert torch.equal(frames[2, 10], m[2, :, 10].reshape(-1))
    assert cut_frames(x, 1, 9).shape == (2, 44, 63)


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
    # With K = 1, sqrt(2 (nll - floor)) = sqrt((x - m)^T C^-1 (x - m)): the Mahalanobis distance.
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
