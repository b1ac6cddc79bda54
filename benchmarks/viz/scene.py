"""The 3D scene: arena, obstacles, the robot's body and turning wheels along its pose, path and contacts.

Entity layout (all under `world/`, z up, metres):
- `world/arena/floor`, `world/arena/bounds`: static floor slab and arena outline;
- `world/obstacles/struck`, `world/obstacles/other`: one box per obstacle, coloured by kind, centres over
  time (pedestrians move); only the obstacles the robot hit show their labels;
- `world/robot`: base pose over time; `world/robot/body`: static body box, labelled; `world/robot/frame`:
  a faint ring on the floor around the robot that the 3D view follows;
  `world/robot/wheels/<name>`: wheel mount (static), `.../tyre`: spin over time, colour turns red while
  a fault on that wheel is active, `.../tyre/spoke`: a bar that shows the spin;
- `world/trajectory`: the whole driven path;
- `world/contacts`: every collision so far, radius growing with the impulse;
- `world/transients`: every benign transient so far.
"""

from __future__ import annotations

import numpy as np
import rerun as rr

from benchmarks.viz import palette
from benchmarks.viz.config import TIMELINE, VizConfig
from benchmarks.viz.signals import display_indices
from sim.trace import Trace


def _times(t: np.ndarray) -> rr.TimeColumn:
    return rr.TimeColumn(TIMELINE, duration=np.asarray(t, dtype=np.float64))


def _yaw_quaternions(yaw: np.ndarray) -> np.ndarray:
    """(n,) yaw -> (n, 4) xyzw quaternions about z."""
    half = 0.5 * np.asarray(yaw, dtype=np.float64)
    return np.stack([np.zeros_like(half), np.zeros_like(half), np.sin(half), np.cos(half)], axis=1)


def _spin_quaternions(angle: np.ndarray) -> np.ndarray:
    """(n,) wheel angle -> (n, 4) xyzw quaternions about the axle (body y)."""
    half = 0.5 * np.asarray(angle, dtype=np.float64)
    return np.stack([np.zeros_like(half), np.sin(half), np.zeros_like(half), np.cos(half)], axis=1)


def log_arena(rec: rr.RecordingStream, trace: Trace) -> None:
    """Floor slab coloured by surface, and the arena outline."""
    hx, hy = (float(v) for v in trace.arena_half_size)
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    rec.log(
        "world/arena/floor",
        rr.Boxes3D(
            centers=[[0.0, 0.0, -0.01]],
            half_sizes=[[hx, hy, 0.01]],
            colors=[palette.SURFACE_COLORS.get(trace.surface, (128, 128, 128, 255))],
            fill_mode=rr.components.FillMode.Solid,
            labels=[f"{trace.environment} / {trace.surface}"],
            show_labels=False,
        ),
        static=True,
    )
    corners = np.array([[-hx, -hy, 0.0], [hx, -hy, 0.0], [hx, hy, 0.0], [-hx, hy, 0.0], [-hx, -hy, 0.0]])
    rec.log("world/arena/bounds", rr.LineStrips3D([corners], colors=[(30, 30, 30, 255)]), static=True)


def log_obstacles(rec: rr.RecordingStream, trace: Trace, config: VizConfig, struck: list[int]) -> None:
    """Obstacle boxes (static shape, colour and label; centres over time at the display rate).

    The obstacles in `struck` go to `world/obstacles/struck` with their labels shown; the others to
    `world/obstacles/other`, labelled on hover only, so that labels do not pile up around the robot.
    """
    obstacles = trace.obstacles
    if not obstacles:
        return
    idx = display_indices(trace.imu_time, config.pose_rate_hz)
    hit = [k for k in struck if 0 <= k < len(obstacles)]
    rest = [k for k in range(len(obstacles)) if k not in hit]
    for name, members, show in (("struck", hit, True), ("other", rest, False)):
        if not members:
            continue
        path = f"world/obstacles/{name}"
        chosen = [obstacles[k] for k in members]
        rec.log(
            path,
            rr.Boxes3D.from_fields(
                half_sizes=np.stack([o.size for o in chosen]),
                quaternions=_yaw_quaternions(np.array([o.yaw for o in chosen])),
                colors=[palette.OBSTACLE_COLORS.get(o.kind, (128, 128, 128, 255)) for o in chosen],
                labels=[f"{o.kind} ({o.material})" for o in chosen],
                fill_mode=rr.components.FillMode.Solid,
                show_labels=show,
            ),
            static=True,
        )
        centres = np.asarray(trace.obstacle_pos)[idx][:, members]
        rec.send_columns(
            path,
            indexes=[_times(trace.imu_time[idx])],
            columns=rr.Boxes3D.columns(centers=centres.reshape(-1, 3)).partition(
                np.full(idx.size, len(members))
            ),
        )


def body_half_size(trace: Trace, config: VizConfig) -> np.ndarray:
    """(3,) half extents of the drawn body box, from the wheel layout (the trace has no body size)."""
    wheels = np.asarray(trace.robot.wheel_pos_body, dtype=np.float64)
    radius = float(np.max(trace.robot.wheel_radius))
    hx = max(float(np.max(np.abs(wheels[:, 0]))) + radius, 1.5 * radius)
    hy = max(float(np.max(np.abs(wheels[:, 1]))) - 0.6 * config.wheel_width_m, radius)
    return np.array([hx, hy, 0.5 * config.body_height_m])


def log_robot(rec: rr.RecordingStream, trace: Trace, config: VizConfig) -> np.ndarray:
    """Robot pose, body, turning wheels (red while faulty); returns the physics indices it logged."""
    idx = display_indices(trace.time, config.pose_rate_hz)
    times = _times(trace.time[idx])
    quat_xyzw = np.roll(np.asarray(trace.base_quat, dtype=np.float64)[idx], -1, axis=1)
    rec.send_columns(
        "world/robot",
        indexes=[times],
        columns=rr.Transform3D.columns(translation=trace.base_pos[idx], quaternion=quat_xyzw),
    )
    wheels = np.asarray(trace.robot.wheel_pos_body, dtype=np.float64)
    half = body_half_size(trace, config)
    body_z = float(np.mean(wheels[:, 2])) + 0.5 * half[2]
    rec.log(
        "world/robot/body",
        rr.Boxes3D(
            centers=[[0.0, 0.0, body_z]],
            half_sizes=[half],
            colors=[palette.BODY],
            labels=[f"robot ({trace.robot.model}, unit {trace.robot.unit_id})"],
            fill_mode=rr.components.FillMode.Solid,
            show_labels=True,
        ),
        static=True,
    )
    rec.log(
        "world/robot/heading",
        rr.Arrows3D(vectors=[[half[0] * 1.4, 0.0, 0.0]], origins=[[0.0, 0.0, body_z + half[2]]]),
        static=True,
    )
    log_camera_frame(rec, config)
    for w, name in enumerate(trace.robot.wheel_names):
        radius = float(trace.robot.wheel_radius[w])
        mount = f"world/robot/wheels/{name}"
        rec.log(mount, rr.Transform3D(translation=wheels[w]), static=True)
        rec.send_columns(
            f"{mount}/tyre",
            indexes=[times],
            columns=rr.Transform3D.columns(quaternion=_spin_quaternions(trace.wheel_angle[idx, w])),
        )
        rec.log(
            f"{mount}/tyre",
            rr.Cylinders3D.from_fields(
                lengths=[config.wheel_width_m],
                radii=[radius],
                rotation_axis_angles=[rr.RotationAxisAngle(axis=[1.0, 0.0, 0.0], degrees=90.0)],
                fill_mode=rr.components.FillMode.Solid,
                labels=[name],
                show_labels=False,  # on hover only: four wheel names would bury the robot's own label
            ),
            static=True,
        )
        change_t, faulty = wheel_fault_changes(trace, w)
        colors = np.array([palette.FAULTY_WHEEL if f else palette.WHEEL for f in faulty], dtype=np.uint8)
        rec.send_columns(
            f"{mount}/tyre", indexes=[_times(change_t)], columns=rr.Cylinders3D.columns(colors=colors)
        )
        rec.log(
            f"{mount}/tyre/spoke",
            rr.Boxes3D(
                centers=[[0.0, 0.0, 0.5 * radius]],
                half_sizes=[[0.1 * radius, 0.55 * config.wheel_width_m, 0.45 * radius]],
                colors=[palette.SPOKE],
                fill_mode=rr.components.FillMode.Solid,
            ),
            static=True,
        )
    return idx


FRAME = "world/robot/frame"
"""A faint ring on the floor around the robot: what the 3D view follows."""


def log_camera_frame(rec: rr.RecordingStream, config: VizConfig) -> None:
    """The 3D view follows an entity by the bounds of what it draws, and the robot's pose draws nothing; the
    body alone would pull the camera to half a metre. A ring of `follow_radius_m` around the robot gives
    it something to follow that keeps nearby obstacles in view: the viewer puts the camera 1.5 times the
    ring's bounding radius away, which is where the blueprint's eye starts too."""
    angle = np.linspace(0.0, 2.0 * np.pi, 65)
    r = config.follow_radius_m
    ring = np.stack([r * np.cos(angle), r * np.sin(angle), np.full_like(angle, 0.01)], axis=1)
    rec.log(FRAME, rr.LineStrips3D([ring], radii=[0.004], colors=[palette.FOLLOW_RING]), static=True)


def wheel_fault_changes(trace: Trace, wheel: int) -> tuple[np.ndarray, np.ndarray]:
    """Times a wheel's fault state changes, and whether it is faulty from each time on (starts at 0 s).

    Overlapping faults on the same wheel are merged: the wheel is faulty while any of them is active.
    """
    t0 = float(trace.time[0]) if len(trace.time) else 0.0
    edges: list[tuple[float, int]] = []
    for f in trace.faults:
        if f.wheel == wheel and f.duration > 0:
            edges += [(float(f.onset), 1), (float(f.onset + f.duration), -1)]
    times, states = [t0], [False]
    active = 0
    for t, step in sorted(edges, key=lambda e: (e[0], -e[1])):
        active += step
        state = active > 0
        if state != states[-1]:
            if t <= times[-1]:
                times[-1], states[-1] = max(t, t0), state
            else:
                times.append(t)
                states.append(state)
    return np.asarray(times, dtype=np.float64), np.asarray(states, dtype=bool)


def log_trajectory(rec: rr.RecordingStream, trace: Trace, config: VizConfig) -> None:
    """The whole driven path as one static line, just above the floor."""
    idx = display_indices(trace.time, config.pose_rate_hz)
    path = np.asarray(trace.base_pos, dtype=np.float64)[idx].copy()
    path[:, 2] = 0.005
    rec.log(
        "world/trajectory", rr.LineStrips3D([path], colors=[palette.TRAJECTORY], radii=[0.01]), static=True
    )


def contact_radii(impulse: np.ndarray, config: VizConfig) -> np.ndarray:
    """Marker radius of contacts: base + k * sqrt(impulse), m."""
    return config.contact_radius_m + config.contact_radius_per_sqrt_ns * np.sqrt(np.maximum(impulse, 0.0))


def _recent(order: np.ndarray, cap: int) -> tuple[np.ndarray, np.ndarray]:
    """For each event k in time order, the last `cap` events up to k (concatenated), and their counts."""
    ends = np.arange(1, order.size + 1)
    starts = np.maximum(ends - cap, 0)
    take = np.concatenate([order[a:b] for a, b in zip(starts, ends, strict=True)])
    return take, ends - starts


def log_contacts(rec: rr.RecordingStream, trace: Trace, config: VizConfig) -> None:
    """Collisions and benign transients: at each event time, the latest events so far (sizes by impulse)."""
    c = trace.contacts
    n = len(c.time)
    if n:
        order = np.argsort(c.time, kind="stable")
        take, lengths = _recent(order, config.max_markers)
        labels = [f"{c.obstacle_kind[i]} {c.impulse[i]:.2f} N s" for i in take]
        rec.log("world/contacts", rr.Points3D.from_fields(show_labels=False), static=True)  # hover only
        rec.send_columns(
            "world/contacts",
            indexes=[_times(np.asarray(c.time)[order])],
            columns=rr.Points3D.columns(
                positions=np.asarray(c.position)[take],
                radii=contact_radii(np.asarray(c.impulse)[take], config),
                colors=np.tile(np.array(palette.CONTACT, dtype=np.uint8), (take.size, 1)),
                labels=labels,
            ).partition(lengths),
        )
    t = trace.transients
    m = len(t.time)
    if m:
        order = np.argsort(t.time, kind="stable")
        take, lengths = _recent(order, config.max_markers)
        rec.send_columns(
            "world/transients",
            indexes=[_times(np.asarray(t.time)[order])],
            columns=rr.Points3D.columns(
                positions=np.asarray(t.position)[take],
                radii=np.full(take.size, 0.5 * config.contact_radius_m),
                colors=np.tile(np.array(palette.TRANSIENT, dtype=np.uint8), (take.size, 1)),
            ).partition(lengths),
        )


def log_scene(
    rec: rr.RecordingStream, trace: Trace, config: VizConfig, struck: list[int] | None = None
) -> None:
    """Everything in the 3D view; `struck` are the obstacles whose labels are shown."""
    log_arena(rec, trace)
    log_obstacles(rec, trace, config, struck or [])
    log_robot(rec, trace, config)
    log_trajectory(rec, trace, config)
    log_contacts(rec, trace, config)
