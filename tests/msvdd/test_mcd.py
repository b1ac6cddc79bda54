"""min_cov_det against scikit-learn's MinCovDet (raw estimate) and Mahalanobis against scipy."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.spatial.distance import mahalanobis as scipy_mahalanobis
from sklearn.covariance import MinCovDet

from msvdd.mcd import (
    MCDError,
    SingularCovarianceError,
    mahalanobis,
    min_cov_det,
    support_estimate,
    support_size,
)


def _contaminated(n: int, p: int, frac: float, seed: int) -> tuple[np.ndarray, int]:
    rng = np.random.default_rng(seed)
    mix = np.eye(p) + 0.3 * rng.standard_normal((p, p))
    x = rng.standard_normal((n, p)) @ mix.T + rng.uniform(-2, 2, size=p)
    k = int(frac * n)
    x[:k] = rng.standard_normal((k, p)) + 10.0
    return x, k


@pytest.mark.parametrize(("n", "p", "frac", "seed"), [(300, 4, 0.1, 0), (400, 6, 0.2, 1), (2500, 8, 0.15, 2)])
def test_matches_sklearn_raw_estimate(n: int, p: int, frac: float, seed: int) -> None:
    x, k = _contaminated(n, p, frac, seed)
    ref = MinCovDet(random_state=0).fit(x)
    ours = min_cov_det(torch.from_numpy(x), random_state=0)
    # Same support -> same location and covariance (1/h normalisation, no consistency correction).
    loc, cov = support_estimate(torch.from_numpy(x), torch.from_numpy(ref.raw_support_))
    np.testing.assert_allclose(loc.numpy(), ref.raw_location_, atol=1e-10)
    np.testing.assert_allclose(cov.numpy(), ref.raw_covariance_, atol=1e-10)
    # The outliers are outside our support, and our support has size h.
    support = ours.support.numpy()
    assert not support[:k].any()
    assert support.sum() == support_size(n, p)
    # Full run: within tolerance of sklearn's raw estimate, and a determinant at least as small (to 1e-3).
    np.testing.assert_allclose(ours.location.numpy(), ref.raw_location_, atol=0.05)
    np.testing.assert_allclose(ours.covariance.numpy(), ref.raw_covariance_, atol=0.1)
    assert ours.log_det <= np.linalg.slogdet(ref.raw_covariance_)[1] + 1e-3
    assert (support == ref.raw_support_).mean() > 0.95


def test_same_seed_same_answer() -> None:
    x, _ = _contaminated(200, 3, 0.1, 3)
    a = min_cov_det(torch.from_numpy(x), random_state=7)
    b = min_cov_det(torch.from_numpy(x), random_state=7)
    assert torch.equal(a.support, b.support)
    assert torch.equal(a.covariance, b.covariance)


def test_support_fraction() -> None:
    x, _ = _contaminated(100, 3, 0.1, 4)
    res = min_cov_det(torch.from_numpy(x), support_fraction=0.75)
    assert int(res.support.sum()) == 75


def test_refuses_support_that_is_not_a_true_subset() -> None:
    # Batch of 32 in 32 dimensions (the reference code's setting): h = 33 > 32.
    with pytest.raises(MCDError, match="not a true subset"):
        support_size(32, 32)
    with pytest.raises(MCDError, match="not a true subset"):
        min_cov_det(torch.randn(32, 32))
    assert support_size(64, 32) == 49
    with pytest.raises(MCDError, match="support_fraction"):
        support_size(100, 3, 1.0)


def test_bad_input() -> None:
    with pytest.raises(MCDError, match="2-D"):
        min_cov_det(torch.randn(10))
    x = torch.randn(50, 3)
    x[3, 1] = float("nan")
    with pytest.raises(MCDError, match="NaN"):
        min_cov_det(x)
    flat = torch.zeros(50, 3)
    flat[:, 0] = torch.randn(50)
    with pytest.raises(SingularCovarianceError, match="singular"):
        min_cov_det(flat)
    assert min_cov_det(flat, ridge=1e-3).covariance.shape == (3, 3)


def test_mahalanobis_matches_scipy() -> None:
    rng = np.random.default_rng(5)
    a = rng.standard_normal((4, 4))
    cov = a @ a.T + 0.5 * np.eye(4)
    mu = rng.standard_normal(4)
    z = rng.standard_normal((20, 4))
    ours = mahalanobis(torch.from_numpy(z), torch.from_numpy(mu), torch.from_numpy(cov)).numpy()
    inv = np.linalg.inv(cov)
    ref = np.array([scipy_mahalanobis(row, mu, inv) for row in z])
    np.testing.assert_allclose(ours, ref, rtol=1e-10)


def test_mahalanobis_singular_covariance() -> None:
    with pytest.raises(SingularCovarianceError, match="singular"):
        mahalanobis(torch.randn(5, 2), torch.zeros(2), torch.tensor([[1.0, 1.0], [1.0, 1.0]]))
