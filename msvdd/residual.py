"""Frames of a window and Gaussian mixtures of them: the pieces of the frame densities.

A window's normalised input is cut into frames, one per time step of the network's tokens (a log-mel frame of
both channels, 8 IMU samples of every channel, 180 waveform samples of both channels), so each frame is a
vector of p values (`cut_frames`). `FrameMixture` is a Gaussian mixture of frames (scikit-learn's
`GaussianMixture` on a seeded sample, scored in torch float64), the building block of
`msvdd.context.ContextMixture`; a window's distance is sqrt(2 (nll - floor)) of its least likely frame: a
6 ms impact fills one frame of 50 and stands out where a window mean would dilute it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch


def cut_frames(x: torch.Tensor, time_axis: int, block: int) -> torch.Tensor:
    """(N, T, p) frames of `x`: `block` consecutive steps of `time_axis` with everything but the batch
    flattened into each frame (time step major); a remainder shorter than a block is dropped."""
    r = x.movedim(time_axis, 1)
    steps = r.shape[1] // block
    return r[:, : steps * block].reshape(r.shape[0], steps, -1)


MIXTURE_COMPONENTS = 16
"""Components of a frame mixture (the IMU density of `context-net-frames`; chosen on the dev dataset among
1, 4, 8, 16 and 32)."""
MIXTURE_FRAMES = 60_000
"""Frames a `FrameMixture` is fitted on (a seeded sample of the training frames; all when there are fewer)."""
MIXTURE_REG = 1e-3
"""Added to each component's covariance diagonal (the inputs are z-scored: 0.1 % of their variance)."""


@dataclass(frozen=True)
class FrameMixture:
    """A Gaussian mixture of frames (full covariances), scored in torch float64.

    A frame's negative log-likelihood is -log sum_k w_k N(r; m_k, C_k). It is never below the floor
    min_k (p/2 log 2 pi - log det P_k), P_k the Cholesky factor of C_k^-1 (a mixture's density is at most
    its largest component peak). `peak_distance` reports sqrt(2 (nll - floor)) of each window's worst frame:
    with one component that is the frame's Mahalanobis distance.
    """

    log_weights: torch.Tensor
    """(K,) float64 log mixing weights."""
    means: torch.Tensor
    """(K, p) float64 component means."""
    precision_cholesky: torch.Tensor
    """(K, p, p) float64 upper-triangular P_k with P_k P_k^T = C_k^-1 (scikit-learn's layout)."""

    @property
    def floor(self) -> float:
        """The smallest negative log-likelihood the mixture can give: -max_k log N(m_k; m_k, C_k)."""
        return float(_floor(self.precision_cholesky))

    def nll(self, frames: torch.Tensor) -> torch.Tensor:
        """(..., p) frames -> (...) float64 negative log-likelihood under the mixture."""
        return mixture_nll(frames, self.log_weights, self.means, self.precision_cholesky)

    def peak_distance(self, frames: torch.Tensor) -> torch.Tensor:
        """(N, T, p) frames -> (N,) float64 sqrt(2 (nll - floor)) of each window's least likely frame."""
        return mixture_peak_distance(frames, self.log_weights, self.means, self.precision_cholesky)

    def state(self) -> dict[str, torch.Tensor]:
        """Tensors for `MSVDD.save` (CPU)."""
        return {
            "log_weights": self.log_weights.cpu(),
            "means": self.means.cpu(),
            "precision_cholesky": self.precision_cholesky.cpu(),
        }

    @classmethod
    def from_state(cls, state: dict[str, torch.Tensor], device: torch.device) -> FrameMixture:
        """Inverse of `state` (a missing key: KeyError)."""
        return cls(
            **{k: state[k].to(device, torch.float64) for k in ("log_weights", "means", "precision_cholesky")}
        )


def _log_norms(precision_cholesky: torch.Tensor) -> torch.Tensor:
    """(K,) log N(m_k; m_k, C_k) = log det P_k - p/2 log 2 pi: each component's log density at its mean."""
    p = precision_cholesky.shape[-1]
    logdet = torch.diagonal(precision_cholesky, dim1=-2, dim2=-1).log().sum(dim=-1)
    return logdet - 0.5 * p * math.log(2.0 * math.pi)


def _floor(precision_cholesky: torch.Tensor) -> torch.Tensor:
    """-max_k log N(m_k; m_k, C_k): a mixture's density is at most its largest component peak."""
    return -_log_norms(precision_cholesky).max()


def mixture_nll(
    frames: torch.Tensor, log_weights: torch.Tensor, means: torch.Tensor, precision_cholesky: torch.Tensor
) -> torch.Tensor:
    """(..., p) frames -> (...) float64 -log sum_k w_k N(frame; m_k, C_k) (`FrameMixture`'s fields)."""
    k, p = means.shape
    # (x - m_k) P_k for every k from one product: x [P_1 ... P_K] - [m_1 P_1 ... m_K P_K].
    stacked = precision_cholesky.permute(1, 0, 2).reshape(p, k * p)
    offsets = torch.einsum("kp,kpq->kq", means, precision_cholesky)
    y = (frames.to(torch.float64) @ stacked).unflatten(-1, (k, p)) - offsets
    logp = log_weights + _log_norms(precision_cholesky) - 0.5 * y.square().sum(dim=-1)
    return -torch.logsumexp(logp, dim=-1)


def mixture_peak_distance(
    frames: torch.Tensor, log_weights: torch.Tensor, means: torch.Tensor, precision_cholesky: torch.Tensor
) -> torch.Tensor:
    """(N, T, p) frames -> (N,) float64 sqrt(2 (nll - floor)) of each window's least likely frame, the floor
    -max_k log N(m_k; m_k, C_k) being the smallest negative log-likelihood the mixture can give."""
    nll = mixture_nll(frames, log_weights, means, precision_cholesky).amax(dim=1)
    return (2.0 * (nll - _floor(precision_cholesky)).clamp_min(0.0)).sqrt()


def fit_frame_mixture(frames: torch.Tensor, components: int, seed: int, max_iter: int = 100) -> FrameMixture:
    """The `FrameMixture` of training frames (n, p): scikit-learn's `GaussianMixture` (full covariances,
    `MIXTURE_REG` on the diagonal, k-means start with `seed`, at most `max_iter` EM iterations) on a seeded
    sample of `MIXTURE_FRAMES` frames.

    Raises:
        ValueError: fewer frames than components.
    """
    from sklearn.mixture import GaussianMixture

    n = frames.shape[0]
    if n < components:
        raise ValueError(
            f"a {components}-component frame mixture needs at least {components} frames, got {n}"
        )
    rows = np.arange(n)
    if n > MIXTURE_FRAMES:
        rows = np.sort(np.random.default_rng(seed).choice(n, MIXTURE_FRAMES, replace=False))
    x = frames[torch.from_numpy(rows)].to(torch.float64).cpu().numpy()
    mixture = GaussianMixture(
        components, covariance_type="full", reg_covar=MIXTURE_REG, random_state=seed, max_iter=max_iter
    )
    mixture.fit(x)
    device = frames.device
    return FrameMixture(
        log_weights=torch.from_numpy(np.log(mixture.weights_)).to(device),
        means=torch.from_numpy(mixture.means_).to(device),
        precision_cholesky=torch.from_numpy(mixture.precisions_cholesky_).to(device),
    )
