"""Benign transients (seams, thresholds, cables, kerb ramps, debris) as soft impacts at the wheel.

They excite the tyre and the robot's chassis like a collision does, at comparable levels per impulse, so a
detector cannot tell anomalies from bumps by loudness alone.
"""

from __future__ import annotations

import numpy as np

from synth_audio.dsp import add_at
from synth_audio.impacts import Material, struck_response

KINDS: dict[str, Material] = {
    "seam": Material((120, 480, 1600, 3200), (0.05, 0.03, 0.02, 0.015), (0.6, 0.6, 0.5, 0.25),
                     0.0015, 0.5, 1.0),
    "threshold": Material((80, 220, 640, 1450), (0.12, 0.08, 0.05, 0.04), (1.0, 0.7, 0.5, 0.3),
                          0.003, 0.3, 1.1),
    "cable": Material((90, 260, 700), (0.08, 0.05, 0.03), (1.0, 0.6, 0.3), 0.006, 0.2, 1.0),
    "kerb_ramp": Material((60, 150, 420, 1100), (0.15, 0.1, 0.06, 0.04), (1.0, 0.8, 0.4, 0.2),
                          0.005, 0.2, 1.2),
    "debris": Material((300, 1200, 3500), (0.03, 0.02, 0.015), (0.6, 1.0, 0.7), 0.0007, 0.8, 0.8),
}  # fmt: skip
"""Every kind in `sim.vocab.TRANSIENT_KINDS`: the tyre/floor-feature contact character."""

TRANSIENT_SCALE = 4.4
"""Amplitude per unit of `impacts.impulse_law` of the vertical impulse (wheel drops ring the chassis)."""


def transient(
    kind: str, impulse: float, wheel_speed_mps: float, sample_rate: int, rng: np.random.Generator
) -> np.ndarray:
    """Mono sound of one benign transient at the wheel, float32, starting at the event instant."""
    material = KINDS[kind]
    scale = TRANSIENT_SCALE * material.gain
    v = max(abs(wheel_speed_mps), 0.05)
    if kind == "debris":
        # Crunch: a burst of small grains over 40-100 ms.
        count = int(rng.integers(6, 16))
        span = rng.uniform(0.04, 0.1)
        starts = np.sort(rng.uniform(0.0, span, count))
        weights = rng.exponential(1.0, count)
        weights /= np.sum(weights)
        parts = [struck_response(material, impulse * w, v, sample_rate, rng, scale, 0.3) for w in weights]
        out = np.zeros(int(span * sample_rate) + max(p.size for p in parts), dtype=np.float32)
        for s, p in zip(starts, parts, strict=True):
            add_at(out, int(s * sample_rate), p)
        return out
    first = struck_response(material, impulse, v, sample_rate, rng, scale)
    if kind not in ("cable", "threshold"):
        return first
    # The wheel climbs onto the feature and drops off it: a second, weaker bump one feature-width later.
    width = 0.02 if kind == "cable" else 0.04
    gap = int(width / v * sample_rate)
    second = struck_response(material, 0.6 * impulse, v, sample_rate, rng, scale)
    out = np.zeros(gap + max(first.size, second.size), dtype=np.float32)
    add_at(out, 0, first)
    add_at(out, gap, second)
    return out
