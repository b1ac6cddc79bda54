"""Every loss term against a hand computation on a tiny case."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from msvdd.losses import (
    batch_statistics,
    covariance_regulariser,
    huber_per_window,
    reconstruction_loss,
    svdd_loss,
)
from msvdd.mcd import mahalanobis_sq


def test_svdd_soft_boundary() -> None:
    d2 = torch.tensor([0.5, 2.0, 4.0, 1.0])
    r = torch.tensor(1.2)
    # R^2 = 1.44; excess: 0, 0.56, 2.56, 0 -> mean 0.78.
    assert float(svdd_loss(d2, r)) == pytest.approx(1.44 + 0.78)
    assert float(svdd_loss(d2, r, nu=0.5)) == pytest.approx(1.44 + 1.56)


def test_svdd_gradient_reaches_radius() -> None:
    r = torch.tensor(1.0, requires_grad=True)
    svdd_loss(torch.tensor([4.0, 0.25]), r).backward()
    # d/dR [R^2 + (4 - R^2)/2] = 2R - R = 1 at R = 1.
    assert r.grad is not None and float(r.grad) == pytest.approx(1.0)


def test_huber() -> None:
    x = torch.zeros(2, 4)
    x_hat = torch.tensor([[0.5, -2.0, 0.0, 1.0], [3.0, 0.0, 0.0, 0.0]])
    # 0.125, 1.5, 0, 0.5 -> mean 0.53125; 2.5 -> mean 0.625.
    np.testing.assert_allclose(huber_per_window(x, x_hat).numpy(), [0.53125, 0.625])


def test_reconstruction_sums_modalities() -> None:
    a, a_hat = torch.zeros(1, 3, 2), torch.full((1, 3, 2), 0.5)
    i, i_hat = torch.zeros(1, 4), torch.tensor([[2.0, 0.0, 0.0, 0.0]])
    # audio: 0.125; imu: 1.5 / 4 = 0.375.
    assert float(reconstruction_loss(a, a_hat, i, i_hat)[0]) == pytest.approx(0.5)
    assert float(reconstruction_loss(None, None, i, i_hat)[0]) == pytest.approx(0.375)
    with pytest.raises(ValueError, match="at least one"):
        reconstruction_loss(None, None, None, None)


def test_covariance_regulariser() -> None:
    sigma = torch.tensor([[2.0, 1.0], [1.0, 2.0]])  # eigenvalues 1 and 3
    eps = 0.5
    expected = 2 * (1 / 2.5) + 3 / 1.5
    assert float(covariance_regulariser(sigma, eps)) == pytest.approx(expected)


def test_batch_statistics_is_mcd_of_support_plus_eps() -> None:
    g = torch.Generator().manual_seed(0)
    z = torch.randn(40, 3, generator=g, dtype=torch.float64)
    z[:4] += 20.0
    z.requires_grad_(True)
    mu, sigma, support = batch_statistics(z, eps=1e-3, support_fraction=None, seed=0)
    assert not bool(support[:4].any())
    zs = z.detach()[support]
    np.testing.assert_allclose(mu.detach().numpy(), zs.mean(0).numpy(), atol=1e-12)
    c = (zs - zs.mean(0)).numpy()
    np.testing.assert_allclose(sigma.detach().numpy(), c.T @ c / len(zs) + 1e-3 * np.eye(3), atol=1e-12)
    sigma.trace().backward()
    assert z.grad is not None and float(z.grad[support].abs().sum()) > 0
    assert float(z.grad[~support].abs().sum()) == 0


def test_batch_mahalanobis_depends_only_on_the_spectrum_against_eps() -> None:
    # Why the paper's loss collapses embeddings (`msvdd.losses`' docstring): over the MCD support the mean
    # squared distance to the batch's own estimate is tr((S + eps I)^-1 S) = sum_k lambda_k / (lambda_k +
    # eps), whatever z is. It is about s for any spread-out batch and falls only as eigenvalues sink below
    # eps.
    g = torch.Generator().manual_seed(0)
    eps = 1e-3
    for scale in (1.0, 1e-2, 1e-4):
        z = scale * torch.randn(64, 8, generator=g, dtype=torch.float64)
        mu, sigma, support = batch_statistics(z, eps, None, seed=0, n_trials=5)
        d2 = mahalanobis_sq(z, mu, sigma)
        lam = torch.linalg.eigvalsh(sigma - eps * torch.eye(8, dtype=torch.float64))
        expected = float((lam / (lam + eps)).sum())
        assert float(d2[support].mean()) == pytest.approx(expected, rel=1e-9)
    assert expected < 0.5  # scale 1e-4: variances 1e-8 << eps, the loss term is nearly 0
