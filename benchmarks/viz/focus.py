"""Where a person should look in an episode: the ground-truth anomaly spans, the first of them, the obstacle
the robot struck, and a score axis that holds both the scores and the threshold (numpy only)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.trace import Trace
from sim.vocab import LABELS, NORMAL


@dataclass(frozen=True)
class AnomalySpan:
    """One run of non-normal ground-truth samples."""

    start: float
    """First anomalous sample, s."""
    end: float
    """First normal sample after it (or the episode end), s."""
    label: str
    """Label name (`collision` or `mechanical`)."""


def anomaly_spans(time: np.ndarray, label: np.ndarray, end_s: float | None = None) -> list[AnomalySpan]:
    """Runs of equal non-normal labels, in time order.

    Args:
        time: (n,) sorted sample times, s.
        label: (n,) label index per sample (see `sim.vocab.LABELS`).
        end_s: end of the last sample's interval, s (default: one sample period after the last sample).
    """
    t = np.asarray(time, dtype=np.float64).reshape(-1)
    lab = np.asarray(label, dtype=np.int64).reshape(-1)
    if t.size != lab.size:
        raise ValueError(f"time has {t.size} samples, label {lab.size}")
    if t.size == 0:
        return []
    if end_s is None:
        end_s = float(t[-1] + (t[-1] - t[-2] if t.size > 1 else 0.0))
    change = np.flatnonzero(lab[1:] != lab[:-1]) + 1
    starts = np.concatenate([[0], change])
    ends = np.concatenate([change, [t.size]])
    spans = []
    for a, b in zip(starts, ends, strict=True):
        if lab[a] == NORMAL:
            continue
        stop = float(t[b]) if b < t.size else float(end_s)
        name = LABELS[lab[a]] if 0 <= lab[a] < len(LABELS) else str(int(lab[a]))
        spans.append(AnomalySpan(float(t[a]), stop, name))
    return spans


def box_distance(point: np.ndarray, centre: np.ndarray, half_size: np.ndarray, yaw: float) -> float:
    """Distance from a point to a box turned by `yaw` about z (0 inside), m."""
    c, s = np.cos(yaw), np.sin(yaw)
    d = np.asarray(point, dtype=np.float64) - centre
    local = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1], d[2]])
    outside = np.maximum(np.abs(local) - half_size, 0.0)
    return float(np.linalg.norm(outside))


def struck_obstacles(trace: Trace) -> list[int]:
    """Indices of the obstacles the robot collided with, in order of first contact.

    A contact names the obstacle's kind and material, not its index: the obstacle of that kind and material
    nearest the contact point at the contact time is taken (the nearest of any kind if none matches).
    """
    contacts = trace.contacts
    obstacles = trace.obstacles
    if not obstacles or len(contacts.time) == 0:
        return []
    positions = np.asarray(trace.obstacle_pos, dtype=np.float64)
    imu_time = np.asarray(trace.imu_time, dtype=np.float64)
    found: list[int] = []
    for i in np.argsort(contacts.time, kind="stable"):
        row = int(np.clip(np.searchsorted(imu_time, contacts.time[i]), 0, max(len(imu_time) - 1, 0)))
        if positions.ndim == 3 and len(positions):
            centres = list(positions[row])
        else:
            centres = [np.asarray(o.position) for o in obstacles]
        distances = np.array(
            [
                box_distance(contacts.position[i], np.asarray(centres[k]), np.asarray(o.size), o.yaw)
                for k, o in enumerate(obstacles)
            ]
        )
        same = np.array(
            [o.kind == contacts.obstacle_kind[i] and o.material == contacts.material[i] for o in obstacles]
        )
        candidates = np.flatnonzero(same) if same.any() else np.arange(len(obstacles))
        best = int(candidates[np.argmin(distances[candidates])])
        if best not in found:
            found.append(best)
    return found


@dataclass(frozen=True)
class ScoreAxis:
    """The y axis of the score plot: the scores and the threshold on top, a strip for the ground truth under
    them (a step from `truth_low`, normal, to `truth_high`, anomalous), so that neither hides the other."""

    bottom: float
    """Lowest value shown."""
    top: float
    """Highest value shown."""
    truth_low: float
    """Ground-truth step level while normal."""
    truth_high: float
    """Ground-truth step level inside an anomaly (below every score and the threshold)."""


def score_axis(score: np.ndarray, threshold: float, margin: float = 0.08, strip: float = 0.3) -> ScoreAxis:
    """The score plot's y axis: every finite score and the threshold with `margin` of their span above and
    below, and under them a ground-truth strip `strip` times their span high."""
    values = np.append(np.asarray(score, dtype=np.float64).reshape(-1), threshold)
    values = values[np.isfinite(values)]
    lo, hi = (float(values.min()), float(values.max())) if values.size else (0.0, 1.0)
    span = hi - lo if hi > lo else max(abs(hi), 1.0)
    floor = lo - margin * span
    bottom = floor - strip * span
    return ScoreAxis(bottom, hi + margin * span, bottom + 0.15 * strip * span, floor - 0.15 * strip * span)
