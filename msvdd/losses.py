"""The paper's loss terms (Methodology): Mahalanobis SVDD soft boundary, Huber reconstruction, regulariser.

- `svdd_loss`: R^2 + 1/(nu N) sum_i max(0, D_i^2 - R^2) (nu = 1 is the paper's mean).
- `reconstruction_loss`: per window, the mean Huber loss (delta 1) of the audio plus that of the IMU.
- `covariance_regulariser`: sum_i 1/(Sigma_ii + eps) + lambda_max / (lambda_min + eps).
- `batch_statistics`: mu and Sigma of a batch by MCD: the support is chosen without gradient (FastMCD), then
  mu = mean of the support and Sigma = its 1/h covariance + eps I, both differentiable in z.

What this loss can learn: over the support, the mean squared distance of a batch to its own estimate is
exactly tr((S + eps I)^-1 S) = sum_k lambda_k / (lambda_k + eps), S the support covariance with eigenvalues
lambda_k, whatever the embeddings are. It is about s for any batch that spreads in every direction, so its
gradient carries no information about normality except one: sinking eigenvalues below eps lowers it. Trained
this way the embeddings collapse onto a few directions (`msvdd-bench diagnose` shows the spectrum of Sigma of
a trained model), and the covariance regulariser at alpha3 = 0.001 is too weak to stop it.
`tests/msvdd/test_losses.py` checks the identity.

- `floored_covariance`: the covariance `svdd_fit="frozen"` holds fixed between its estimates (Deep SVDD's
  fixed centre, extended to the ellipsoid): eigenvalues raised to a fraction of their mean, then eps I.
  Estimated over the whole training split with no gradient, it cannot be moved by the loss it enters; with a
  relative floor and eps, shrinking the embeddings' scale changes nothing after the next estimate.
- `effective_rank`: exp(entropy) of a spectrum, the figure `msvdd-bench diagnose` and the training history
  report to show whether Sigma keeps its rank.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

from msvdd.mcd import min_cov_det, support_estimate


def svdd_loss(d2: torch.Tensor, radius: torch.Tensor, nu: float = 1.0) -> torch.Tensor:
    """Soft-boundary loss of squared distances d2 (N,) with radius R (scalar)."""
    r2 = radius * radius
    return r2 + torch.clamp(d2 - r2, min=0).sum() / (nu * d2.shape[0])


def huber_per_window(x: torch.Tensor, x_hat: torch.Tensor) -> torch.Tensor:
    """(N,) mean Huber loss (delta 1) over all elements of each window."""
    err = F.huber_loss(x_hat, x, reduction="none", delta=1.0)
    return err.reshape(err.shape[0], -1).mean(dim=1)


def reconstruction_loss(
    audio: torch.Tensor | None,
    audio_rec: torch.Tensor | None,
    imu: torch.Tensor | None,
    imu_rec: torch.Tensor | None,
) -> torch.Tensor:
    """(N,) per-window Huber(A, A_hat) + Huber(I, I_hat), over the modalities present."""
    terms = [
        huber_per_window(x, x_hat)
        for x, x_hat in ((audio, audio_rec), (imu, imu_rec))
        if x is not None and x_hat is not None
    ]
    if not terms:
        raise ValueError("reconstruction_loss needs at least one (signal, reconstruction) pair")
    return torch.stack(terms).sum(dim=0)


def covariance_regulariser(sigma: torch.Tensor, eps: float) -> torch.Tensor:
    """sum_i 1/(Sigma_ii + eps) + lambda_max / (lambda_min + eps) of a symmetric (s, s) Sigma."""
    eig = torch.linalg.eigvalsh(sigma)
    return (1.0 / (torch.diagonal(sigma) + eps)).sum() + eig[-1] / (eig[0] + eps)


def floored_covariance(cov: torch.Tensor, floor: float, eps: float) -> torch.Tensor:
    """Symmetric (s, s) `cov` with its eigenvalues raised to at least `floor` times their mean, plus eps I.

    The floor bounds the condition number of the result by about 1 / floor whatever the embeddings' scale;
    a ridge eps I alone is an absolute floor, which shrinking embeddings make dominant.
    """
    sym = 0.5 * (cov + cov.T)
    lam, vec = torch.linalg.eigh(sym)
    lam = lam.clamp_min(0.0)
    lam = torch.maximum(lam, floor * lam.mean())
    eye = torch.eye(cov.shape[0], dtype=cov.dtype, device=cov.device)
    return (vec * lam) @ vec.T + eps * eye


def effective_rank(eigenvalues: torch.Tensor) -> float:
    """exp(Shannon entropy of p = lambda / sum lambda) of a spectrum (negative values clipped to 0): between 1
    (one direction) and its length (all equal); nan if every eigenvalue is 0."""
    lam = eigenvalues.detach().to(torch.float64).clamp_min(0.0)
    total = float(lam.sum())
    if total <= 0:
        return float("nan")
    p = lam[lam > 0] / total
    return float(torch.exp(-(p * torch.log(p)).sum()))


def batch_statistics(
    z: torch.Tensor, eps: float, support_fraction: float | None, seed: int, n_trials: int = 30
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(mu (s,), Sigma (s, s) incl. eps I, support (N,) bool) of a batch z (N, s) by MCD; differentiable."""
    mcd = min_cov_det(
        z.detach(), support_fraction=support_fraction, random_state=seed, n_trials=n_trials, ridge=eps
    )
    mu, cov = support_estimate(z, mcd.support)
    sigma = cov + eps * torch.eye(z.shape[1], dtype=z.dtype, device=z.device)
    return mu, sigma, mcd.support
