"""Kernel SVDD (Tax & Duin, 2004) solved as its dual quadratic program by SMO, in numpy.

The dual: maximise sum_i a_i K_ii - sum_ij a_i a_j K_ij subject to sum_i a_i = 1 and 0 <= a_i <= C,
with C = 1 / (nu n) so that at most a fraction nu of the training points lies outside the sphere. We
minimise f(a) = a'Ka - a'diag(K) by sequential minimal optimisation: each step moves weight between the
maximal-violating pair (first-order choice of i, second-order choice of j, as Fan, Chen and Lin 2005),
which keeps both constraints exactly, until the KKT gap is below `tol`. The squared distance of a point
z to the centre is K(z, z) - 2 sum_i a_i K(x_i, z) + a'Ka; R^2 is that distance at the unbounded support
vectors (0 < a_i < C); the score is distance^2 - R^2 (positive outside the sphere).

With an RBF kernel K_ii = 1, so the solution equals the one-class SVM's (Schölkopf) up to scaling; the
tests check this against scikit-learn. The optimiser here is our own; it is not OCSVM renamed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def rbf_kernel(a: np.ndarray, b: np.ndarray, gamma: float) -> np.ndarray:
    """(len(a), len(b)) RBF kernel exp(-gamma ||a_i - b_j||^2)."""
    sq = (a**2).sum(axis=1)[:, None] + (b**2).sum(axis=1)[None, :] - 2.0 * (a @ b.T)
    return np.exp(-gamma * np.maximum(sq, 0.0))


@dataclass(frozen=True)
class SVDDSolution:
    """The solved dual."""

    alpha: np.ndarray
    """(n,) dual weights, sum 1, each in [0, C]."""
    r2: float
    """Squared radius R^2 in feature space."""
    aka: float
    """a'Ka, the squared norm of the centre in feature space."""
    dist2: np.ndarray
    """(n,) squared distance of every training point to the centre."""
    iterations: int
    """SMO steps taken."""
    gap: float
    """Final KKT gap max_{a_j > 0} g_j - min_{a_i < C} g_i (<= tol when converged)."""
    converged: bool
    """Whether the gap fell below tol within max_iter."""


def solve_svdd_dual(
    kernel: np.ndarray, c: float, tol: float = 1e-6, max_iter: int | None = None
) -> SVDDSolution:
    """Solve the SVDD dual for a precomputed (n, n) kernel matrix with box bound `c`.

    Raises:
        ValueError: a non-square or non-finite kernel, or c < 1 / n (no feasible point).
    """
    k = np.asarray(kernel, dtype=np.float64)
    n = k.shape[0]
    if k.ndim != 2 or k.shape != (n, n) or n == 0:
        raise ValueError(f"kernel must be a non-empty square matrix, got shape {k.shape}")
    if not np.all(np.isfinite(k)):
        raise ValueError("kernel holds NaN or inf")
    if c * n < 1.0 - 1e-12:
        raise ValueError(f"C = {c} < 1/n = {1.0 / n}: sum(alpha) = 1 is infeasible; use nu <= 1")
    c = min(c, 1.0)
    diag = np.diag(k).copy()
    alpha = np.full(n, 1.0 / n)
    grad = 2.0 * (k @ alpha) - diag
    limit = max_iter if max_iter is not None else 100 * n + 10_000
    gap = np.inf
    it = 0
    while it < limit:
        up = alpha < c
        low = alpha > 0.0
        g_up = np.where(up, grad, np.inf)
        i = int(np.argmin(g_up))
        g_low = np.where(low, grad, -np.inf)
        gap = float(g_low.max() - g_up[i])
        if gap <= tol:
            break
        b = grad - grad[i]
        quad = np.maximum(diag[i] + diag - 2.0 * k[i], 1e-12)
        gain = np.where(low & (b > 0.0), b * b / quad, -np.inf)
        j = int(np.argmax(gain))
        t = min(b[j] / (2.0 * quad[j]), c - alpha[i], alpha[j])
        if t >= c - alpha[i]:
            t = c - alpha[i]
            alpha[i] = c
        else:
            alpha[i] += t
        if t >= alpha[j]:
            alpha[j] = 0.0
        else:
            alpha[j] -= t
        grad += 2.0 * t * (k[:, i] - k[:, j])
        it += 1
    aka = float(alpha @ (k @ alpha))
    dist2 = diag - 2.0 * (k @ alpha) + aka
    return SVDDSolution(
        alpha=alpha,
        r2=_radius2(alpha, dist2, c),
        aka=aka,
        dist2=dist2,
        iterations=it,
        gap=gap,
        converged=gap <= tol,
    )


def _radius2(alpha: np.ndarray, dist2: np.ndarray, c: float) -> float:
    """R^2 from the KKT conditions: the mean distance^2 of unbounded SVs, else the middle of its bracket."""
    eps = 1e-10 * c
    free = (alpha > eps) & (alpha < c - eps)
    if free.any():
        return float(dist2[free].mean())
    inside = dist2[alpha <= eps]
    outside = dist2[alpha >= c - eps]
    lo = float(inside.max()) if inside.size else float(outside.min())
    hi = float(outside.min()) if outside.size else lo
    return 0.5 * (lo + hi)


class KernelSVDD:
    """RBF kernel SVDD on feature rows; score(x) = ||phi(x) - a||^2 - R^2 (higher = more anomalous)."""

    def __init__(
        self, nu: float = 0.05, gamma: float | None = None, max_train: int = 2000, seed: int = 0
    ) -> None:
        """Configure the model.

        Args:
            nu: upper bound on the fraction of training points outside the sphere (C = 1 / (nu n)).
            gamma: RBF width; None = 1 / (n_features * variance of the data) (sklearn's "scale").
            max_train: training rows used; a larger set is subsampled uniformly without replacement.
            seed: seed of the subsample.
        """
        if not 0.0 < nu <= 1.0:
            raise ValueError(f"nu must be in (0, 1], got {nu}")
        if max_train < 2:
            raise ValueError(f"max_train must be >= 2, got {max_train}")
        self.nu = nu
        self.gamma = gamma
        self.max_train = max_train
        self.seed = seed
        self.support_: np.ndarray = np.zeros((0, 0))
        self.alpha_: np.ndarray = np.zeros(0)
        self.gamma_ = float("nan")
        self.r2_ = float("nan")
        self.aka_ = float("nan")
        self.n_fit_ = 0
        self.n_offered_ = 0
        self.solution_: SVDDSolution | None = None

    def fit(self, x: np.ndarray) -> KernelSVDD:
        """Solve the dual on (n, d) rows (subsampled to `max_train` if larger, recorded in `n_fit_`)."""
        data = np.asarray(x, dtype=np.float64)
        self.n_offered_ = data.shape[0]
        if data.shape[0] > self.max_train:
            pick = np.random.default_rng(self.seed).choice(data.shape[0], self.max_train, replace=False)
            data = data[np.sort(pick)]
        self.n_fit_ = data.shape[0]
        var = float(data.var())
        self.gamma_ = (
            self.gamma if self.gamma is not None else 1.0 / (data.shape[1] * (var if var > 0 else 1.0))
        )
        solution = solve_svdd_dual(rbf_kernel(data, data, self.gamma_), 1.0 / (self.nu * data.shape[0]))
        sv = solution.alpha > 0.0
        self.support_, self.alpha_ = data[sv], solution.alpha[sv]
        self.r2_, self.aka_ = solution.r2, solution.aka
        self.solution_ = solution
        return self

    def score(self, x: np.ndarray) -> np.ndarray:
        """(n,) squared feature-space distance to the centre minus R^2."""
        kx = rbf_kernel(np.asarray(x, dtype=np.float64), self.support_, self.gamma_)
        return 1.0 - 2.0 * (kx @ self.alpha_) + self.aka_ - self.r2_
