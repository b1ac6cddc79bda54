"""A frame's density given its neighbours: p(x_t | c_t) = p(x_t, c_t) / p(c_t), two Gaussian mixtures.

`msvdd.residual.FrameMixture` scores each frame x_t of a window on its own. A frame that is ordinary in
isolation can still be out of place where it is: a wheel's thump that nominal driving produces on a seam but
not on a smooth floor at the same speed, a change of the motion between two frames. `ContextMixture` scores
x_t against what its neighbours make likely. The context c_t is the `neighbours` frames on either side of
x_t in the same window (the window's first and last frame repeated at its edges), concatenated and projected
on its first `dim` principal axes over the training frames (centre and basis from the eigenvectors of their
covariance, each axis signed so that its largest entry is positive). Two mixtures of full-covariance Gaussians
are fitted on the same seeded sample of training frames (`msvdd.residual.fit_frame_mixture`): one of the joint
vector (x_t, c_t), one of c_t, so that -log p(x_t | c_t) = nll_joint(x_t, c_t) - nll_context(c_t).

A conditional density has no analytic floor, so the floor is the smallest conditional negative
log-likelihood over every training frame, and a window's distance is sqrt(2 (nll - floor)) of its least
likely frame (0 below the floor), the measure of `FrameMixture.peak_distance`.

`neighbours` = 2 and `dim` = 16 were chosen on the dev dataset (seed 1) of the `paper` preset among
contexts of the mean of the neighbours (d = 8) and their concatenation (d = 8, 16), against the window's
mean frame, with no network; the chosen context scored above the unconditional mixture there
(docs/detectors.md).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import torch

from msvdd.residual import MIXTURE_FRAMES, FrameMixture, fit_frame_mixture, mixture_nll

CONTEXT_NEIGHBOURS = 2
"""Frames on each side of x_t that make its context (chosen on the dev dataset)."""
CONTEXT_DIM = 16
"""Principal axes the context is projected on (chosen on the dev dataset among 8 and 16)."""
CONTEXT_MAX_ITER = 300
"""EM iterations of the two mixtures (scikit-learn's default of 100 leaves the 80-value joint unconverged)."""
_MIXTURE_FIELDS = ("log_weights", "means", "precision_cholesky")
STATE_FIELDS = (
    "neighbours",
    "center",
    "basis",
    "floor",
    *(f"{prefix}_{k}" for prefix in ("joint", "context") for k in _MIXTURE_FIELDS),
)
"""The keys of `ContextMixture.state`."""
_BLOCK = 256
"""Windows per block when contexts are built for scoring (bounds the memory of the concatenation)."""


def _offsets(neighbours: int) -> list[int]:
    """The context's steps relative to t: -k, ..., -1, 1, ..., k."""
    if neighbours < 1:
        raise ValueError(f"neighbours = {neighbours} is invalid; allowed: 1 or more")
    return [o for o in range(-neighbours, neighbours + 1) if o != 0]


def neighbour_context(frames: torch.Tensor, neighbours: int) -> torch.Tensor:
    """(N, T, p) frames -> (N, T, 2 k p) the k = `neighbours` frames before and after each frame,
    concatenated in time order (t-k, ..., t-1, t+1, ..., t+k); the window's edge frames are repeated."""
    steps = frames.shape[1]
    t = torch.arange(steps, device=frames.device)
    return torch.cat([frames[:, (t + o).clamp(0, steps - 1)] for o in _offsets(neighbours)], dim=2)


def context_nll(
    frames: torch.Tensor,
    neighbours: int,
    center: torch.Tensor,
    basis: torch.Tensor,
    joint: tuple[torch.Tensor, torch.Tensor, torch.Tensor],
    context: tuple[torch.Tensor, torch.Tensor, torch.Tensor],
) -> torch.Tensor:
    """(N, T, p) window frames -> (N, T) float64 -log p(x_t | c_t) in one pass (`ContextMixture`'s fields;
    each mixture as (log_weights, means, precision_cholesky)); `ContextMixture.nll` runs it in blocks."""
    x = frames.to(torch.float64)
    c = (neighbour_context(x, neighbours) - center) @ basis
    return mixture_nll(torch.cat([x, c], dim=2), *joint) - mixture_nll(c, *context)


@dataclass(frozen=True)
class ContextMixture:
    """The conditional frame density p(x_t | c_t) of the module docstring; `fit_context_mixture` builds it."""

    neighbours: int
    """Frames on each side of x_t in its context."""
    center: torch.Tensor
    """(2 k p,) float64 mean context vector of the training frames."""
    basis: torch.Tensor
    """(2 k p, d) float64 principal axes of the training contexts (orthonormal columns)."""
    joint: FrameMixture
    """Mixture of (x_t, c_t), p + d values."""
    context: FrameMixture
    """Mixture of c_t, d values."""
    floor: float
    """The smallest conditional negative log-likelihood of a training frame."""

    def project(self, frames: torch.Tensor) -> torch.Tensor:
        """(N, T, p) frames -> (N, T, d) float64 projected contexts c_t."""
        c = neighbour_context(frames.to(torch.float64), self.neighbours)
        return (c - self.center) @ self.basis

    def nll(self, frames: torch.Tensor) -> torch.Tensor:
        """(N, T, p) window frames -> (N, T) float64 -log p(x_t | c_t), computed in blocks of windows."""
        joint = (self.joint.log_weights, self.joint.means, self.joint.precision_cholesky)
        context = (self.context.log_weights, self.context.means, self.context.precision_cholesky)
        out = [
            context_nll(block, self.neighbours, self.center, self.basis, joint, context)
            for block in frames.split(_BLOCK)
        ]
        if not out:
            return torch.zeros(0, frames.shape[1], dtype=torch.float64, device=frames.device)
        return torch.cat(out)

    def peak_distance(self, frames: torch.Tensor) -> torch.Tensor:
        """(N, T, p) window frames -> (N,) float64 sqrt(2 (nll - floor)) of each window's least likely
        frame."""
        nll = self.nll(frames).amax(dim=1)
        return (2.0 * (nll - self.floor).clamp_min(0.0)).sqrt()

    def state(self) -> dict[str, torch.Tensor]:
        """Tensors for saving (CPU): the projection, both mixtures (prefixed `joint_`, `context_`), the floor
        and the number of neighbours."""
        state = {
            "neighbours": torch.tensor(self.neighbours),
            "center": self.center.cpu(),
            "basis": self.basis.cpu(),
            "floor": torch.tensor(self.floor, dtype=torch.float64),
        }
        for prefix, mixture in (("joint", self.joint), ("context", self.context)):
            state.update({f"{prefix}_{k}": v for k, v in mixture.state().items()})
        return state

    @classmethod
    def from_state(cls, state: dict[str, torch.Tensor], device: torch.device) -> ContextMixture:
        """Inverse of `state` (a missing key: KeyError)."""

        def mixture(prefix: str) -> FrameMixture:
            return FrameMixture.from_state({k: state[f"{prefix}_{k}"] for k in _MIXTURE_FIELDS}, device)

        return cls(
            neighbours=int(state["neighbours"]),
            center=state["center"].to(device, torch.float64),
            basis=state["basis"].to(device, torch.float64),
            joint=mixture("joint"),
            context=mixture("context"),
            floor=float(state["floor"]),
        )


def _principal_axes(vectors: torch.Tensor, dim: int) -> tuple[torch.Tensor, torch.Tensor]:
    """(mean (q,), basis (q, dim)) of `vectors` (n, q) float64: the eigenvectors of the covariance with the
    `dim` largest eigenvalues, largest first, each signed so that its largest-magnitude entry is positive."""
    center = vectors.mean(dim=0)
    c = vectors - center
    _, vecs = torch.linalg.eigh(c.T @ c / max(len(c) - 1, 1))
    basis = vecs[:, -dim:].flip(1)
    rows = basis.abs().argmax(dim=0)
    signs = torch.sign(basis[rows, torch.arange(dim, device=basis.device)])
    return center, basis * torch.where(signs == 0, 1.0, signs)


def fit_context_mixture(
    frames: torch.Tensor,
    components: int,
    seed: int,
    neighbours: int = CONTEXT_NEIGHBOURS,
    dim: int = CONTEXT_DIM,
) -> ContextMixture:
    """The `ContextMixture` of training windows' frames (N, T, p): principal axes, joint and context mixtures
    fitted on one seeded sample of `msvdd.residual.MIXTURE_FRAMES` frames, the floor over every frame.

    Raises:
        ValueError: `dim` outside 1 .. 2 k p, or fewer frames than components.
    """
    n, steps, p = frames.shape
    q = len(_offsets(neighbours)) * p
    if not 1 <= dim <= q:
        raise ValueError(
            f"dim = {dim} is invalid; allowed: 1 to {q} (2 x {neighbours} neighbours x {p} values)"
        )
    if n * steps < components:
        raise ValueError(
            f"a {components}-component context mixture needs at least {components} frames, got {n * steps}"
        )
    rows = np.arange(n * steps)
    if len(rows) > MIXTURE_FRAMES:
        rows = np.sort(np.random.default_rng(seed).choice(len(rows), MIXTURE_FRAMES, replace=False))
    index = torch.from_numpy(rows).to(frames.device)
    window, step = index // steps, index % steps
    x = frames[window, step].to(torch.float64)
    c_raw = torch.cat(
        [frames[window, (step + o).clamp(0, steps - 1)] for o in _offsets(neighbours)], dim=1
    ).to(torch.float64)
    center, basis = _principal_axes(c_raw, dim)
    c = (c_raw - center) @ basis
    joint = fit_frame_mixture(torch.cat([x, c], dim=1), components, seed, max_iter=CONTEXT_MAX_ITER)
    context = fit_frame_mixture(c, components, seed, max_iter=CONTEXT_MAX_ITER)
    model = ContextMixture(neighbours, center, basis, joint, context, floor=0.0)
    return dataclasses.replace(model, floor=float(model.nll(frames).min()))
