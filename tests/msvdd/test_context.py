"""`msvdd.context`: a frame's density given its neighbours, against the Gaussian conditional (Schur
complement), numpy's eigenvectors and a frame that is ordinary alone but out of place in its window."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.stats import multivariate_normal

from msvdd.context import (
    ContextMixture,
    _principal_axes,
    fit_context_mixture,
    neighbour_context,
)
from msvdd.residual import MIXTURE_REG, fit_frame_mixture


def _smooth_windows(n: int, steps: int, p: int, seed: int) -> np.ndarray:
    """(n, steps, p) windows of frames that drift slowly: each frame is its predecessor plus a little noise,
    each window starting from another level."""
    rng = np.random.default_rng(seed)
    start = 3.0 * rng.standard_normal((n, 1, p))
    return start + np.cumsum(0.3 * rng.standard_normal((n, steps, p)), axis=1)


def test_neighbour_context_is_the_frames_around_t_with_edges_repeated() -> None:
    f = torch.arange(2 * 5 * 3, dtype=torch.float64).reshape(2, 5, 3)
    c = neighbour_context(f, 2)
    assert c.shape == (2, 5, 12)
    assert torch.equal(c[1, 2], torch.cat([f[1, 0], f[1, 1], f[1, 3], f[1, 4]]))
    assert torch.equal(c[0, 0], torch.cat([f[0, 0], f[0, 0], f[0, 1], f[0, 2]]))  # t-2, t-1 -> frame 0
    assert torch.equal(c[0, 4], torch.cat([f[0, 2], f[0, 3], f[0, 4], f[0, 4]]))
    with pytest.raises(ValueError, match="neighbours = 0 is invalid"):
        neighbour_context(f, 0)


def test_principal_axes_are_numpys_leading_eigenvectors() -> None:
    rng = np.random.default_rng(2)
    x = rng.standard_normal((400, 6)) @ rng.standard_normal((6, 6)) + 1.5
    center, basis = _principal_axes(torch.from_numpy(x), 3)
    _, vecs = np.linalg.eigh(np.cov(x, rowvar=False))
    want = vecs[:, ::-1][:, :3]
    want = want * np.sign(want[np.abs(want).argmax(axis=0), range(3)])
    np.testing.assert_allclose(center.numpy(), x.mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose(basis.numpy(), want, atol=1e-10)


def test_one_component_gives_the_gaussian_conditional_density() -> None:
    # With one component both mixtures are the sample Gaussians (plus MIXTURE_REG on the diagonal), so
    # -log p(x | c) is the Gaussian conditional of (x, c): mean m_x + S_xc S_cc^-1 (c - m_c), covariance the
    # Schur complement S_xx - S_xc S_cc^-1 S_cx, scipy's multivariate normal.
    windows = _smooth_windows(60, 12, 3, seed=0)
    model = fit_context_mixture(torch.from_numpy(windows), components=1, seed=0, neighbours=1, dim=4)
    x = windows.reshape(-1, 3)
    c = model.project(torch.from_numpy(windows)).numpy().reshape(-1, 4)
    joint = np.concatenate([x, c], axis=1)
    s_joint = np.cov(joint, rowvar=False, bias=True)
    s_xx, s_xc = s_joint[:3, :3] + MIXTURE_REG * np.eye(3), s_joint[:3, 3:]
    s_cc = np.cov(c, rowvar=False, bias=True) + MIXTURE_REG * np.eye(4)
    gain = s_xc @ np.linalg.inv(s_cc)
    cond_mean = x.mean(axis=0) + (c - c.mean(axis=0)) @ gain.T
    cond_cov = s_xx - gain @ s_xc.T
    want = np.array([-multivariate_normal(m, cond_cov).logpdf(v) for m, v in zip(cond_mean, x, strict=True)])
    got = model.nll(torch.from_numpy(windows)).numpy().reshape(-1)
    np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-6)
    assert model.floor == pytest.approx(want.min(), abs=1e-6)
    peaks = model.peak_distance(torch.from_numpy(windows)).numpy()
    want_peaks = np.sqrt(2.0 * (want.reshape(60, 12).max(axis=1) - want.min()))
    np.testing.assert_allclose(peaks, want_peaks, atol=1e-6)


def test_a_frame_out_of_place_stands_out_given_its_neighbours_only() -> None:
    # Test windows whose frame 6 is taken from another nominal window: ordinary on its own (the
    # unconditional mixture ranks those windows among the nominal ones), out of place between its
    # neighbours (the conditional density ranks every one above every nominal window).
    train = torch.from_numpy(_smooth_windows(300, 12, 3, seed=1))
    nominal = _smooth_windows(40, 12, 3, seed=2)
    donors = _smooth_windows(40, 12, 3, seed=3)
    spliced = nominal.copy()
    spliced[:, 6] = donors[::-1, 6]
    test = torch.from_numpy(np.concatenate([nominal, spliced]))
    model = fit_context_mixture(train, components=4, seed=0, neighbours=2, dim=8)
    got = model.peak_distance(test).numpy()
    assert got[40:].min() > got[:40].max()
    alone = fit_frame_mixture(train.reshape(-1, 3), 4, seed=0).peak_distance(test).numpy()
    assert alone[40:].min() < np.quantile(alone[:40], 0.9)


def test_state_round_trip_determinism_and_errors() -> None:
    train = torch.from_numpy(_smooth_windows(50, 10, 3, seed=4))
    model = fit_context_mixture(train, components=2, seed=7, neighbours=1, dim=5)
    again = ContextMixture.from_state(model.state(), torch.device("cpu"))
    np.testing.assert_array_equal(again.peak_distance(train).numpy(), model.peak_distance(train).numpy())
    same = fit_context_mixture(train, components=2, seed=7, neighbours=1, dim=5)
    np.testing.assert_array_equal(same.nll(train).numpy(), model.nll(train).numpy())
    assert float(model.nll(train).min()) == model.floor
    assert float(model.peak_distance(train).min()) >= 0.0
    with pytest.raises(ValueError, match="dim = 7 is invalid; allowed: 1 to 6"):
        fit_context_mixture(train, components=2, seed=0, neighbours=1, dim=7)
    with pytest.raises(ValueError, match="needs at least 600 frames, got 500"):
        fit_context_mixture(train, components=600, seed=0, neighbours=1, dim=2)
