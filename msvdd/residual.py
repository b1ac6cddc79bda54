"""The Mahalanobis reconstruction term (`rec_score="mahalanobis"`): how unusual each frame's residual is.

A window's reconstruction residual x - x_hat is cut into frames, one per time step of the network's tokens
(a log-mel frame of both channels, 8 IMU samples of every channel, 180 waveform samples of both channels), so
each frame is a vector r_t of p values. Over every frame of every training window a Gaussian is fitted: the
mean and the Ledoit-Wolf shrunk covariance S (Ledoit & Wolf 2004, the estimator of
`sklearn.covariance.LedoitWolf`, computed here in blocks of frames so that a waveform's 360-value frames need
no float64 copy of the whole set). A window's term is the largest distance sqrt((r_t - m)^T S^-1 (r_t - m))
over its frames: a 6 ms impact fills one frame of 50 and stands out against what the residual of nominal
driving looks like in every direction of the frame, not only in its energy.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

_BLOCK = 65536
"""Frames per block of the covariance sums."""


def cut_frames(x: torch.Tensor, time_axis: int, block: int) -> torch.Tensor:
    """(N, T, p) frames of `x`: `block` consecutive steps of `time_axis` with everything but the batch
    flattened into each frame (time step major); a remainder shorter than a block is dropped."""
    r = x.movedim(time_axis, 1)
    steps = r.shape[1] // block
    return r[:, : steps * block].reshape(r.shape[0], steps, -1)


def residual_frames(x: torch.Tensor, x_hat: torch.Tensor, time_axis: int, block: int) -> torch.Tensor:
    """(N, T, p) frames (`cut_frames`) of the residual `x - x_hat`."""
    return cut_frames(x - x_hat, time_axis, block)


@dataclass(frozen=True)
class FrameGaussian:
    """A Gaussian of residual frames: y = (r - mean) @ whiten has identity covariance."""

    mean: torch.Tensor
    """(p,) float64 mean frame."""
    whiten: torch.Tensor
    """(p, p) float64 whitening matrix: the transposed inverse of the covariance's Cholesky factor."""

    def peak_distance(self, frames: torch.Tensor) -> torch.Tensor:
        """(N, T, p) frames -> (N,) float64 largest Mahalanobis distance over each window's frames."""
        y = (frames.to(torch.float64) - self.mean) @ self.whiten
        return y.square().sum(dim=2).sqrt().amax(dim=1)

    def state(self) -> dict[str, torch.Tensor]:
        """Tensors for `MSVDD.save` (CPU)."""
        return {"mean": self.mean.cpu(), "whiten": self.whiten.cpu()}

    @classmethod
    def from_state(cls, state: dict[str, torch.Tensor], device: torch.device) -> FrameGaussian:
        """Inverse of `state` (a missing key: KeyError)."""
        return cls(
            mean=state["mean"].to(device, torch.float64), whiten=state["whiten"].to(device, torch.float64)
        )


def ledoit_wolf(frames: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, float]:
    """(mean (p,), shrunk covariance (p, p), shrinkage) of `frames` (n, p), all float64.

    The empirical covariance (divided by n) shrunk towards mu I, mu its mean eigenvalue, by the
    Ledoit-Wolf shrinkage; the sums run over blocks of frames, each cast to float64 on its own.
    """
    n, p = frames.shape
    if n < 2:
        raise ValueError(f"a frame Gaussian needs at least 2 frames, got {n}")
    mean = torch.zeros(p, dtype=torch.float64, device=frames.device)
    for block in frames.split(_BLOCK):
        mean += block.to(torch.float64).sum(dim=0)
    mean /= n
    cross = torch.zeros(p, p, dtype=torch.float64, device=frames.device)
    cross_sq = torch.zeros(p, p, dtype=torch.float64, device=frames.device)
    for block in frames.split(_BLOCK):
        c = block.to(torch.float64) - mean
        cross += c.T @ c
        c2 = c * c
        cross_sq += c2.T @ c2
    emp = cross / n
    mu = float(torch.trace(emp)) / p
    delta_ = float((emp * emp).sum())
    beta = (float(cross_sq.sum()) / n - delta_) / (p * n)
    delta = (delta_ - 2.0 * mu * float(torch.trace(emp)) + p * mu * mu) / p
    beta = min(beta, delta)
    shrinkage = 0.0 if beta == 0.0 else beta / delta
    cov = (1.0 - shrinkage) * emp + shrinkage * mu * torch.eye(p, dtype=torch.float64, device=frames.device)
    return mean, cov, shrinkage


def fit_frame_gaussian(frames: torch.Tensor) -> FrameGaussian:
    """The `FrameGaussian` of training frames (n, p) (Ledoit-Wolf covariance)."""
    mean, cov, _ = ledoit_wolf(frames)
    chol = torch.linalg.cholesky(cov)
    eye = torch.eye(cov.shape[0], dtype=torch.float64, device=cov.device)
    whiten = torch.linalg.solve_triangular(chol, eye, upper=False).T.contiguous()
    return FrameGaussian(mean=mean, whiten=whiten)
