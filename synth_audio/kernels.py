"""Compiled loops (numba) for the two shapes numpy handles badly: scattering many copies of a kernel into a
signal (overlap-add) and reading a signal at moving fractional positions (a Doppler path). Numpy builds an
index per product and sums with `bincount`, or makes a pass and a temporary per tap; a loop touches each
output sample once.

Compiled without fast-math, so the same inputs give the same samples on the same machine; `cache=True`
keeps the machine code beside the module (`__pycache__`), so a worker process loads it instead of
compiling it again.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def overlap_add_into(
    out: np.ndarray, positions: np.ndarray, amps: np.ndarray, kernel: np.ndarray
) -> None:  # pragma: no cover - compiled
    """out[p_i + k] += amps[i] kernel[k] for every event i and tap k inside out (float32, in place), the
    events in their order."""
    n = out.shape[0]
    size = kernel.shape[0]
    for e in range(positions.shape[0]):
        p = positions[e]
        a = np.float32(amps[e])
        lo = max(0, -p)
        hi = min(size, n - p)
        for k in range(lo, hi):
            out[p + k] += a * kernel[k]


@njit(cache=True, nogil=True)
def lagrange_read(
    padded: np.ndarray,
    pad: int,
    position: np.ndarray,
    gain: np.ndarray,
    control: int,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """out[j] += g(j) x(p(j)) for j < out.size: x read at fractional sample p(j) by third-order Lagrange
    interpolation over x[i - 1 .. i + 2] (i = floor p, f = p - i), p and g ramped linearly between their
    values every `control` samples (`position`, `gain`: one more than out.size / control).

    `padded` is x with `pad` zeros on either side; reads beyond them are those zeros.
    """
    last = padded.shape[0] - 1
    for j in range(out.shape[0]):
        k = j // control
        r = (j - k * control) / control
        p = position[k] + (position[k + 1] - position[k]) * r
        g = gain[k] + (gain[k + 1] - gain[k]) * r
        i = int(np.floor(p))
        f = p - i
        base = i + pad - 1  # x[i - 1] in `padded`
        if base < 0 or base + 3 > last:
            taps = np.zeros(4)
            for t in range(4):
                q = base + t
                if 0 <= q <= last:
                    taps[t] = padded[q]
            x0, x1, x2, x3 = taps[0], taps[1], taps[2], taps[3]
        else:
            x0, x1, x2, x3 = padded[base], padded[base + 1], padded[base + 2], padded[base + 3]
        low = (f - 1.0) * (f - 2.0)
        high = (f + 1.0) * f
        y = (
            -f * low / 6.0 * x0
            + (f + 1.0) * low * 0.5 * x1
            - high * (f - 2.0) * 0.5 * x2
            + high * (f - 1.0) / 6.0 * x3
        )
        out[j] += np.float32(g * y)


@njit(cache=True, nogil=True)
def fractional_delay_into(
    out: np.ndarray, x: np.ndarray, shift: int, taps: np.ndarray, start: int
) -> None:  # pragma: no cover - compiled
    """out[start + j] += sum_k taps[k] x[j - shift - k] over the samples of out that x reaches (float32, in
    place; x is zero outside itself): a four-tap fractional delay in one pass."""
    n = out.shape[0]
    m = x.shape[0]
    t0, t1, t2, t3 = taps[0], taps[1], taps[2], taps[3]
    lo = max(start + shift, 0)
    hi = min(start + shift + m + 3, n)
    for q in range(lo, hi):
        i = q - start - shift  # x index of tap 0
        if 3 <= i < m:
            out[q] += t0 * x[i] + t1 * x[i - 1] + t2 * x[i - 2] + t3 * x[i - 3]
        else:
            acc = np.float32(0.0)
            if 0 <= i < m:
                acc += t0 * x[i]
            if 0 <= i - 1 < m:
                acc += t1 * x[i - 1]
            if 0 <= i - 2 < m:
                acc += t2 * x[i - 2]
            if 0 <= i - 3 < m:
                acc += t3 * x[i - 3]
            out[q] += acc
