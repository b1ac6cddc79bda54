"""Post-processing of recorded sensors: contact events, transient events and per-sample labels.

All vectorised over the episode's physics-rate arrays; MuJoCo's `contact` sensors give, per step, the
number of robot-obstacle (or wheel-transient) contacts and their net force in the world frame.
"""

from __future__ import annotations

import numpy as np

from sim import vocab
from sim.scenario import Scenario
from sim.trace import ContactEvents, FaultRecord, ObstacleRecord, TransientEvents
from sim.vocab import TRANSIENT_HEIGHT

MERGE_GAP = 0.05
"""Contacts separated by less than this are one event, s."""


def merge_gap_steps(dt: float) -> int:
    """`MERGE_GAP` in physics steps of `dt` (at least 1): the longest gap inside one contact event."""
    return max(1, round(MERGE_GAP / dt))


LABEL_MARGIN_BEFORE = 0.02
"""A collision label starts this long before first contact, s."""
LABEL_MARGIN_AFTER = 0.25
"""A collision label lasts this long after the contact ends (the impact rings on), s."""


def runs(mask: np.ndarray, gap: int) -> list[tuple[int, int]]:
    """[start, stop) index runs where `mask` is true, merging runs separated by < `gap` samples."""
    found: list[tuple[int, int]] = []
    extend_runs(found, np.flatnonzero(mask), gap)
    return found


def extend_runs(found: list[tuple[int, int]], idx: np.ndarray, gap: int) -> None:
    """Add the true indices `idx` (ascending, after every index already in `found`) to the runs `found`,
    merging as `runs` does: the same result as `runs` over the whole mask, one chunk at a time (the
    Gymnasium environment labels each step this way)."""
    if len(idx) == 0:
        return
    breaks = np.flatnonzero(np.diff(idx) > gap)
    starts = np.concatenate([[idx[0]], idx[breaks + 1]]).tolist()
    stops = (np.concatenate([idx[breaks], [idx[-1]]]) + 1).tolist()
    new = list(zip(starts, stops, strict=True))
    if found and new[0][0] - (found[-1][1] - 1) <= gap:
        found[-1] = (found[-1][0], new[0][1])
        new = new[1:]
    found.extend(new)


def contact_events(
    found: np.ndarray,
    force: np.ndarray,
    pos: np.ndarray,
    base_linvel: np.ndarray,
    obstacle_vel: np.ndarray,
    obstacles: tuple[ObstacleRecord, ...],
    dt: float,
) -> tuple[ContactEvents, list[tuple[int, int, int]]]:
    """Robot-obstacle events from per-step contact sensors.

    Args:
        found: (n, K) contact counts.
        force: (n, K, 3) net force of the robot on each obstacle, world frame, N.
        pos: (n, K, 3) contact centroids.
        base_linvel: (n, 3) robot velocity, world frame.
        obstacle_vel: (n, K, 3) obstacle velocities, world frame.
        obstacles: the K obstacle records.
        dt: physics step, s.

    Returns:
        The events (sorted by time) and their (start, stop, obstacle) index runs.
    """
    gap = merge_gap_steps(dt)
    rows: list[tuple[float, np.ndarray, np.ndarray, float, float, float, int, tuple[int, int]]] = []
    for k in range(found.shape[1]):
        for start, stop in runs(found[:, k] > 0, gap):
            impulse_vec = -force[start:stop, k].sum(axis=0) * dt
            magnitude = float(np.linalg.norm(impulse_vec))
            if magnitude > 0:
                normal = impulse_vec / magnitude
            else:
                rel = base_linvel[start] - obstacle_vel[start, k]
                normal = -rel / max(float(np.linalg.norm(rel)), 1e-9)
            before = max(start - 1, 0)
            rel_v = base_linvel[before] - obstacle_vel[before, k]
            approach = max(0.0, float(-rel_v @ normal))
            rows.append(
                (
                    start * dt + dt,
                    pos[start, k].copy(),
                    normal,
                    magnitude,
                    approach,
                    (stop - start) * dt,
                    k,
                    (start, stop),
                )
            )
    rows.sort(key=lambda r: (r[0], r[6]))
    kinds = tuple(obstacles[r[6]].kind for r in rows)
    events = ContactEvents(
        time=np.array([r[0] for r in rows], dtype=np.float64),
        position=np.array([r[1] for r in rows], dtype=np.float64).reshape(-1, 3),
        normal=np.array([r[2] for r in rows], dtype=np.float64).reshape(-1, 3),
        impulse=np.array([r[3] for r in rows], dtype=np.float64),
        normal_speed=np.array([r[4] for r in rows], dtype=np.float64),
        duration=np.array([r[5] for r in rows], dtype=np.float64),
        obstacle_kind=kinds,
        material=tuple(vocab.OBSTACLE_MATERIAL[k] for k in kinds),
    )
    return events, [(r[7][0], r[7][1], r[6]) for r in rows]


def transient_events(
    found: np.ndarray, force: np.ndarray, pos: np.ndarray, scenario: Scenario, dt: float
) -> TransientEvents:
    """Wheel-over-transient events from per-wheel contact sensors.

    Args:
        found: (n, W) contact counts of each wheel with the transients.
        force: (n, W, 3) net force of the wheel on the transients, world frame.
        pos: (n, W, 3) contact centroids.
        scenario: the scenario (transient kinds and positions).
        dt: physics step, s.
    """
    gap = max(1, round(0.02 / dt))
    centres = np.array([(t.x, t.y) for t in scenario.transients]).reshape(-1, 2)
    rows: list[tuple[float, np.ndarray, int, float, str]] = []
    for w in range(found.shape[1]):
        for start, stop in runs(found[:, w] > 0, gap):
            p = pos[start, w].copy()
            impulse = float(-force[start:stop, w, 2].sum() * dt)
            kind = "seam"
            if len(centres):
                nearest = int(np.argmin(_distance_to_transients(p[:2], scenario)))
                kind = scenario.transients[nearest].kind
            rows.append((start * dt + dt, p, w, abs(impulse), kind))
    rows.sort(key=lambda r: (r[0], r[2]))
    return TransientEvents(
        time=np.array([r[0] for r in rows], dtype=np.float64),
        position=np.array([r[1] for r in rows], dtype=np.float64).reshape(-1, 3),
        wheel=np.array([r[2] for r in rows], dtype=np.int64),
        impulse=np.array([r[3] for r in rows], dtype=np.float64),
        kind=tuple(r[4] for r in rows),
        height=np.array([TRANSIENT_HEIGHT[r[4]] for r in rows], dtype=np.float64),
    )


def _distance_to_transients(p: np.ndarray, scenario: Scenario) -> np.ndarray:
    """Distance from point p to each transient's centre line, m."""
    out = np.empty(len(scenario.transients))
    for i, t in enumerate(scenario.transients):
        d = np.array([np.cos(t.yaw), np.sin(t.yaw)])
        rel = p - np.array([t.x, t.y])
        along = float(np.clip(rel @ d, -t.length / 2, t.length / 2)) if t.kind != "debris" else 0.0
        out[i] = float(np.linalg.norm(rel - along * d))
    return out


def labels(
    imu_time: np.ndarray,
    event_runs: list[tuple[int, int, int]],
    obstacles: tuple[ObstacleRecord, ...],
    faults: tuple[FaultRecord, ...],
    dt: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-IMU-sample label, sub-kind and wheel; a collision takes precedence over a fault."""
    m = len(imu_time)
    label = np.zeros(m, dtype=np.int8)
    sub = np.zeros(m, dtype=np.int16)
    wheel = np.full(m, -1, dtype=np.int8)
    for f in faults:
        if f.severity <= 0:
            continue
        on = (imu_time >= f.onset) & (imu_time < f.onset + f.duration)
        label[on] = vocab.MECHANICAL
        sub[on] = vocab.sub_kind_index(f.kind)
        wheel[on] = f.wheel
    for start, stop, k in event_runs:
        t0 = start * dt - LABEL_MARGIN_BEFORE
        t1 = stop * dt + LABEL_MARGIN_AFTER
        on = (imu_time >= t0) & (imu_time < t1)
        label[on] = vocab.COLLISION
        sub[on] = vocab.sub_kind_index(obstacles[k].kind)
        wheel[on] = -1
    return label, sub, wheel
