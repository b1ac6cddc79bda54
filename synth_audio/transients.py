"""Benign transients (seams, thresholds, cables, kerb ramps, debris) as soft impacts at the wheel.

They excite the tyre and the robot's chassis like a collision does, on the same amplitude scale per N s
(`impacts.IMPACT_SCALE`). What differs is the impulse. A wheel meeting a floor feature exchanges only
the momentum of its corner of the robot turning upward (`strike_impulse`); MuJoCo's vertical impulse on
the feature (`TransientEvents.impulse`) also holds the weight the wheel carries while it sits on it (a
wheel resting 0.15 s on a cable carries ~7 N s of weight and makes no sound doing so), so the audio
does not use it. A loud bump is a fast wheel on a tall feature; a cable at walking pace is a soft thud.
"""

from __future__ import annotations

import numpy as np

from synth_audio.dsp import add_at
from synth_audio.impacts import IMPACT_SCALE, Material, struck_response

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

GRAVITY = 9.81
"""m/s^2."""


def strike_impulse(
    kind: str, height: float, wheel_speed_mps: float, wheel_radius: float, corner_mass: float
) -> float:
    """Vertical momentum a wheel exchanges with a floor feature, N s.

    A wheel of radius r rolling at v into a step of height h first touches it at angle
    theta = acos(1 - h / r) ahead of its lowest point, and its centre's velocity turns through theta:
    dv_z = v sin(theta). The kerb ramp is climbed gently (slope h / 0.3 m), and its far edge is a drop of
    h: dv_z = sqrt(2 g h). The robot has no suspension, so the moving mass is the wheel's corner of the
    robot, `corner_mass` (total mass / wheels).
    """
    h = float(height)
    v = abs(float(wheel_speed_mps))
    if kind == "kerb_ramp":
        dv = max(v * h / 0.3, float(np.sqrt(2.0 * GRAVITY * h)))
    else:
        theta = float(np.arccos(max(1.0 - h / float(wheel_radius), -1.0)))
        dv = v * float(np.sin(theta))
    return float(corner_mass) * dv


def transient(
    kind: str, impulse: float, wheel_speed_mps: float, sample_rate: int, rng: np.random.Generator
) -> np.ndarray:
    """Mono sound of one benign transient at the wheel, float32, starting at the event instant.

    `impulse` is the strike impulse (`strike_impulse`), N s.
    """
    material = KINDS[kind]
    scale = IMPACT_SCALE * material.gain
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
