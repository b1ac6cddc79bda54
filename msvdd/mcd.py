"""FastMCD (Rousseeuw & Van Driessen, 1999) in torch, and the Mahalanobis distance.

`min_cov_det` returns the raw MCD estimate (the location and 1/h covariance of the h-subset with the smallest
covariance determinant, like scikit-learn's `raw_location_`, `raw_covariance_`, `raw_support_`), without the
consistency correction or re-weighting. All random starts run at once as batched tensors: each is a random
h-subset, refined by two C-steps; the best ten are iterated to convergence and the lowest determinant wins.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

_START_SAMPLE = 1000
"""Above this many samples, the random starts run on a random subsample of this size."""
_FULL_CANDIDATES = 3
"""With subsampled starts, the best candidates (converged on the subsample) refined on the full data."""


class MCDError(ValueError):
    """MCD cannot run on this input (too few samples for a true-subset support, bad values)."""


class SingularCovarianceError(ValueError):
    """A covariance matrix is singular (still, after any regularisation); the message says which."""


@dataclass(frozen=True)
class MCDResult:
    """Raw MCD estimate."""

    location: torch.Tensor
    """(p,) mean of the support."""
    covariance: torch.Tensor
    """(p, p) covariance of the support, normalised by h (no consistency correction)."""
    support: torch.Tensor
    """(n,) bool, True for the h samples of the support."""
    log_det: float
    """log-determinant of `covariance`."""


def support_size(n: int, p: int, support_fraction: float | None = None) -> int:
    """h: the support size for n samples in p dimensions (default ceil((n + p + 1) / 2), as scikit-learn).

    Raises:
        MCDError: if h is not a true subset (h >= n) or too small for a full-rank covariance (h <= p).
    """
    if support_fraction is None:
        h = math.ceil(0.5 * (n + p + 1))
    else:
        if not 0.0 < support_fraction < 1.0:
            raise MCDError(f"support_fraction {support_fraction}; allowed: 0 < support_fraction < 1")
        h = int(support_fraction * n)
    if h >= n:
        raise MCDError(
            f"MCD support h={h} is not a true subset of n={n} samples in p={p} dimensions; "
            f"need n >= {p + 3} (default support) or a smaller support_fraction"
        )
    if h <= p:
        raise MCDError(f"MCD support h={h} <= p={p}: too few samples for a full-rank covariance (n={n})")
    return h


def support_estimate(z: torch.Tensor, support: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(location (p,), covariance (p, p) normalised by h) of the rows of z (n, p) where support is True."""
    zs = z[support]
    loc = zs.mean(dim=0)
    c = zs - loc
    return loc, c.T @ c / zs.shape[0]


def mahalanobis(z: torch.Tensor, location: torch.Tensor, covariance: torch.Tensor) -> torch.Tensor:
    """(n,) Mahalanobis distances sqrt((z - mu)^T Sigma^-1 (z - mu)) of the rows of z (n, p).

    Raises:
        SingularCovarianceError: if `covariance` is not positive definite.
    """
    return torch.sqrt(mahalanobis_sq(z, location, covariance))


def mahalanobis_sq(z: torch.Tensor, location: torch.Tensor, covariance: torch.Tensor) -> torch.Tensor:
    """(n,) squared Mahalanobis distances (differentiable; see `mahalanobis`)."""
    chol, info = torch.linalg.cholesky_ex(covariance)
    if int(info) != 0:
        raise SingularCovarianceError(
            f"covariance ({covariance.shape[0]}x{covariance.shape[0]}) is singular or not positive definite "
            f"(Cholesky failed at order {int(info)}); increase eps or check for collapsed embeddings"
        )
    y = torch.linalg.solve_triangular(chol, (z - location).T, upper=False)
    return (y * y).sum(dim=0)


def _estimate(x: torch.Tensor, idx: torch.Tensor, ridge: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Batched (location (K, p), Cholesky factor (K, p, p)) of the subsets x[idx] (idx (K, h))."""
    xs = x[idx]
    loc = xs.mean(dim=1)
    c = xs - loc.unsqueeze(1)
    cov = c.transpose(1, 2) @ c / idx.shape[1]
    if ridge > 0:
        cov = cov + ridge * torch.eye(x.shape[1], dtype=x.dtype, device=x.device)
    chol, info = torch.linalg.cholesky_ex(cov)
    if bool((info != 0).any()):
        raise SingularCovarianceError(
            "MCD: the covariance of an h-subset is singular (the data lie in a lower-dimensional "
            "subspace or repeat); add a ridge or check the inputs"
        )
    return loc, chol


def _c_step(x: torch.Tensor, idx: torch.Tensor, h: int, ridge: float) -> tuple[torch.Tensor, torch.Tensor]:
    """One batched C-step on x (n, p): subsets idx (K, h_old) -> (new sorted subsets (K, h), old log-dets)."""
    loc, chol = _estimate(x, idx, ridge)
    log_det = 2.0 * torch.log(torch.diagonal(chol, dim1=1, dim2=2)).sum(dim=1)
    eye = torch.eye(x.shape[1], dtype=x.dtype, device=x.device).expand_as(chol)
    inv_t = torch.linalg.solve_triangular(chol, eye, upper=False).transpose(1, 2)
    y = (x.unsqueeze(0) - loc.unsqueeze(1)) @ inv_t
    dist = (y * y).sum(dim=2)
    new_idx = torch.topk(dist, h, dim=1, largest=False, sorted=False).indices
    return torch.sort(new_idx, dim=1).values, log_det


def _converge(x: torch.Tensor, idx: torch.Tensor, h: int, ridge: float, max_iter: int) -> torch.Tensor:
    """C-steps on every subset idx (K, h) until its support stops changing (or max_iter); -> (K, h)."""
    done: list[torch.Tensor] = []
    for _ in range(max_iter):
        new_idx, _ = _c_step(x, idx, h, ridge)
        same = (new_idx == idx).all(dim=1)
        done.append(idx[same])
        idx = new_idx[~same]
        if idx.shape[0] == 0:
            break
    done.append(idx)
    return torch.cat(done)


def min_cov_det(
    z: torch.Tensor,
    support_fraction: float | None = None,
    random_state: int | None = None,
    n_trials: int = 30,
    n_best: int = 10,
    max_iter: int = 30,
    ridge: float = 0.0,
) -> MCDResult:
    """Raw Minimum Covariance Determinant estimate of z (n, p) by FastMCD.

    Args:
        z: (n, p) samples (float32 or float64; any device). Not differentiated through.
        support_fraction: h / n; None gives h = ceil((n + p + 1) / 2).
        random_state: seed of the random starts (None means 0: the result is always reproducible).
        n_trials: random h-subset starts, refined by two C-steps each.
        n_best: starts iterated to convergence.
        max_iter: C-step limit for the convergence phase.
        ridge: added to the diagonal of every candidate covariance while selecting (0 = plain FastMCD).

    Raises:
        MCDError: wrong shape, non-finite values, or n too small for a true-subset support.
        SingularCovarianceError: a candidate covariance is singular (and ridge is 0).
    """
    if z.ndim != 2:
        raise MCDError(f"min_cov_det needs a 2-D (n, p) tensor, got shape {tuple(z.shape)}")
    n, p = z.shape
    if not bool(torch.isfinite(z).all()):
        raise MCDError("min_cov_det input holds NaN or inf")
    h = support_size(n, p, support_fraction)
    x = z.detach().to(torch.float64)
    gen = torch.Generator().manual_seed(0 if random_state is None else int(random_state))
    with torch.no_grad():
        # Random starts and their first C-steps on a subsample (FastMCD's nested start), full data after.
        m = min(n, _START_SAMPLE)
        sub = torch.randperm(n, generator=gen)[:m].to(x.device) if m < n else torch.arange(n, device=x.device)
        h_sub = h if m == n else max(p + 1, math.ceil(h * m / n))
        starts = torch.argsort(torch.rand(n_trials, m, generator=gen), dim=1)[:, :h_sub].to(x.device)
        idx, _ = _c_step(x[sub], starts, h_sub, ridge)
        idx, log_det = _c_step(x[sub], idx, h_sub, ridge)
        idx = idx[torch.argsort(log_det)[: min(n_best, n_trials)]]
        if m < n:
            idx = _converge(x[sub], idx, h_sub, ridge, max_iter)
            _, chol = _estimate(x[sub], idx, ridge)
            log_det = 2.0 * torch.log(torch.diagonal(chol, dim1=1, dim2=2)).sum(dim=1)
            idx, _ = _c_step(x, sub[idx[torch.argsort(log_det)[:_FULL_CANDIDATES]]], h, ridge)
        cand = _converge(x, idx, h, ridge, max_iter)
        _, chol = _estimate(x, cand, ridge)
        log_det = 2.0 * torch.log(torch.diagonal(chol, dim1=1, dim2=2)).sum(dim=1)
        support = torch.zeros(n, dtype=torch.bool, device=x.device)
        support[cand[int(torch.argmin(log_det))]] = True
        loc, cov = support_estimate(x, support)
        sign, raw_log_det = torch.linalg.slogdet(cov)
    return MCDResult(
        location=loc.to(z.dtype),
        covariance=cov.to(z.dtype),
        support=support,
        log_det=float(raw_log_det) if float(sign) > 0 else float("-inf"),
    )
