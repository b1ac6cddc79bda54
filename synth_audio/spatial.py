"""Two-microphone spatialisation: propagation delay (fractional), distance attenuation, mic directivity.

Both microphones are sub-cardioids that face outwards along the line joining them (left mic to the left),
so a source on the robot's left arrives first and louder at the left microphone.
"""

from __future__ import annotations

import numpy as np

from synth_audio.dsp import delay_into

REF_DISTANCE = 0.25
"""Distance at which a source has unit gain, m."""
MIN_DISTANCE = 0.05
"""Distances are clamped to at least this (near field), m."""
DIRECTIVITY = 0.3
"""Sub-cardioid mix: gain = (1 - DIRECTIVITY) + DIRECTIVITY * cos(angle off the mic axis)."""


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) from unit quaternions (..., 4) in (w, x, y, z) order (body -> world)."""
    q = np.asarray(q, dtype=np.float64)
    q = q / np.maximum(np.linalg.norm(q, axis=-1, keepdims=True), 1e-12)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=-1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=-1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=-1),
        ],
        axis=-2,
    )


def mic_axes(mic_pos: np.ndarray) -> np.ndarray:
    """(2, 3) unit facing directions of the left and right mics: outwards along the line joining them."""
    d = np.asarray(mic_pos[0] - mic_pos[1], dtype=np.float64)
    norm = float(np.linalg.norm(d))
    left = d / norm if norm > 1e-9 else np.array([0.0, 1.0, 0.0])
    return np.stack([left, -left])


def point_gains(
    source: np.ndarray, mic_pos: np.ndarray, axes: np.ndarray, sample_rate: int, speed_of_sound: float
) -> tuple[np.ndarray, np.ndarray]:
    """Delays in samples (S, 2) and gains (S, 2) of point sources (S, 3) at two mics (2, 3) in one frame."""
    src = np.atleast_2d(np.asarray(source, dtype=np.float64))
    rel = src[:, None, :] - np.asarray(mic_pos, dtype=np.float64)[None, :, :]
    dist = np.linalg.norm(rel, axis=-1)
    unit = rel / np.maximum(dist, 1e-9)[..., None]
    cos = np.sum(unit * axes[None, :, :], axis=-1)
    gain = ((1.0 - DIRECTIVITY) + DIRECTIVITY * cos) * (REF_DISTANCE / np.maximum(dist, MIN_DISTANCE))
    delay = dist / speed_of_sound * sample_rate
    return delay, gain


def plane_wave_gains(
    direction: np.ndarray, mic_pos: np.ndarray, axes: np.ndarray, sample_rate: int, speed_of_sound: float
) -> tuple[np.ndarray, np.ndarray]:
    """Delays (2,) in samples (>= 1) and gains (2,) of a far source in unit `direction` (mic frame)."""
    u = np.asarray(direction, dtype=np.float64)
    u = u / max(float(np.linalg.norm(u)), 1e-12)
    centre = np.mean(mic_pos, axis=0)
    lead = (np.asarray(mic_pos, dtype=np.float64) - centre) @ u
    delay = (np.max(np.abs(lead)) - lead) / speed_of_sound * sample_rate + 1.0
    gain = (1.0 - DIRECTIVITY) + DIRECTIVITY * (axes @ u)
    return delay, gain


def spatialize_into(
    out: np.ndarray, mono: np.ndarray, delays: np.ndarray, gains: np.ndarray, start: int = 0
) -> None:
    """Add a mono signal to the (2, n) `out` with per-channel fractional delay and gain (in place)."""
    for ch in range(2):
        delay_into(out[ch], mono, float(delays[ch]), float(gains[ch]), start)
