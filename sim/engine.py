"""The stepping core shared by `simulate`, the Gymnasium and the dm_env environments.

Physics runs in control periods of `CONTROL_STEPS` steps through `sim.stepper` (a compiled `mj_step` loop,
no per-step Python), which also records a row of sensors at every physics step (`sim.world.SensorRows`).
Per period, Python computes the wheel speed commands, the faults' forces for every step of the period
(vectorised) and the pedestrians' mocap positions, and hands them to the stepper as open-loop controls.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from sim.faults import FaultForcing, make_forcings
from sim.scenario import Obstacle, Scenario
from sim.stepper import CONTROL_SPEC, Stepper, sensor_row
from sim.tyre import tyres
from sim.world import World

CONTROL_STEPS = 16
"""Physics steps per control period (16 x 2.5 ms = 40 ms, a 25 Hz controller)."""

SKID_TRACK_FACTOR = 1.75
"""Effective track / geometric track of the skid-steer robot (lateral wheel slip when turning)."""

STEP_BACK = 0.4
"""How far a pedestrian the robot bumps into steps back, away from the robot, m."""
STEP_BACK_TIME = 0.5
"""How long the step back takes, s (then the pedestrian stands)."""


def pedestrian_positions(obstacles: tuple[Obstacle, ...], times: np.ndarray) -> np.ndarray:
    """(n, P, 3) positions of the pedestrians (in obstacle order) at `times`, walking back and forth."""
    peds = [ob for ob in obstacles if ob.kind == "pedestrian"]
    out = np.empty((len(times), len(peds), 3))
    for j, ob in enumerate(peds):
        out[:, j, 2] = ob.size[2]
        pts = np.array([(ob.x, ob.y), *ob.path], dtype=np.float64)
        if len(pts) < 2 or ob.walk_speed <= 0:
            out[:, j, 0], out[:, j, 1] = ob.x, ob.y
            continue
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        total = cum[-1]
        if total <= 0:
            out[:, j, 0], out[:, j, 1] = ob.x, ob.y
            continue
        s = np.mod(times * ob.walk_speed, 2 * total)
        s = np.where(s > total, 2 * total - s, s)
        out[:, j, 0] = np.interp(s, cum, pts[:, 0])
        out[:, j, 1] = np.interp(s, cum, pts[:, 1])
    return out


class Engine:
    """One world stepped period by period; records a row of sensors (`sim.world.SensorRows`) every step."""

    def __init__(self, world: World, scenario: Scenario) -> None:
        self.world = world
        self.scenario = scenario
        m = world.model
        self.model = m
        self.data = mujoco.MjData(m)
        self.dt = float(m.opt.timestep)
        self.ncontrol = mujoco.mj_stateSize(m, int(CONTROL_SPEC))
        self._qfrc0 = m.nu
        self._xfrc0 = m.nu + m.nv
        self._mocap0 = m.nu + m.nv + 6 * m.nbody
        self._control = np.zeros((1, CONTROL_STEPS, self.ncontrol))
        self._steps = self.dt * np.arange(CONTROL_STEPS)  # step offsets in a period, s
        self._wheel_control = self._control[0, :, : m.nu]
        self._base_ipos = np.array(m.body_ipos[world.base_body], dtype=np.float64)
        self._ped_track = np.zeros((0, 0, 3))
        self._stepped_back: dict[int, tuple[int, np.ndarray, np.ndarray]] = {}
        info = world.robot.info
        self.radius = info.wheel_radius
        track = info.track * (SKID_TRACK_FACTOR if info.model == "skid4" else 1.0)
        self.half_track = 0.5 * track
        names = info.wheel_names
        self.side = np.array([-1.0 if ("left" in n) else 1.0 for n in names])
        self._wheel_sides = [
            (bool(side < 0), r) for side, r in zip(self.side, self.radius.tolist(), strict=True)
        ]
        self.forcings: list[FaultForcing] = make_forcings(scenario, info)
        self._geom_pos0 = np.array(m.geom_pos[world.wheel_geom], dtype=np.float64)
        self._sameframe0 = np.array(m.geom_sameframe[world.wheel_geom])
        self.ped_index = np.array([i for i, ob in enumerate(scenario.obstacles) if ob.kind == "pedestrian"])
        self.ped_mocap = (
            np.asarray(world.obstacle_mocap[self.ped_index], dtype=np.int64)
            if len(self.ped_index)
            else np.zeros(0, np.int64)
        )
        self._has_peds = len(self.ped_index) > 0
        self.time = 0.0
        self.reset()
        self.tyres = tyres(world, self.data)  # at the initial state `reset` evaluated
        self._stepper = Stepper(
            world, self.data, (world.sensors.obstacle_contact, len(world.obstacles)), self.tyres
        )

    def reset(self) -> None:
        """Back to the initial state (time 0), with the sensors evaluated."""
        mujoco.mj_resetData(self.model, self.data)
        self._set_mocap(self.data.mocap_pos, np.zeros(1))
        mujoco.mj_forward(self.model, self.data)
        self.sensordata = sensor_row(self.world, self.data)
        self.time = 0.0
        self._ped_track = np.zeros((0, len(self.ped_index), 3))
        self._stepped_back = {}
        self.forcings = make_forcings(self.scenario, self.world.robot.info)
        wheel_geom = self.world.wheel_geom
        self.model.geom_pos[wheel_geom] = self._geom_pos0
        self.model.geom_sameframe[wheel_geom] = self._sameframe0
        self._flats = [f for f in self.forcings if f.record.kind == "flat_spot"]
        self._fault_wrenches = True  # the control's wrench columns may hold a period's (zeroed when unused)
        for forcing in self.forcings:
            if forcing.record.kind in ("out_of_round", "flat_spot"):  # its shape moves in the wheel's frame
                self.model.geom_sameframe[wheel_geom[forcing.wheel]] = mujoco.mjtSameFrame.mjSAMEFRAME_NONE

    def _set_mocap(self, target: np.ndarray, times: np.ndarray) -> None:
        if len(self.ped_index) == 0:
            return
        pos = pedestrian_positions(tuple(self.scenario.obstacles[i] for i in self.ped_index), times)
        target[..., self.ped_mocap, :] = pos[-1] if target.ndim == 2 else pos

    def wheel_commands(self, v: float, w: float) -> list[float]:
        """(W,) wheel speed commands (rad/s) for body speed v (m/s) and yaw rate w (rad/s), as Python floats
        (cheaper to make once per control period than an array; `step` takes either)."""
        turn = w * self.half_track  # (side x w) x half_track: -turn on the left, +turn on the right, exactly
        cmd = [(v - turn if left else v + turn) / r for left, r in self._wheel_sides]
        for forcing in self.forcings:
            cmd[forcing.wheel] *= forcing.speed_factor(self.time)
        return cmd

    def step(self, wheel_cmd: np.ndarray | list[float], out: np.ndarray) -> bool:
        """Run one period of `len(out)` steps with the given wheel commands; sensordata goes to `out`.
        Returns whether the robot touched an obstacle (a contact sensor found a contact) in the period.

        Args:
            wheel_cmd: (W,) wheel speed commands, rad/s.
            out: (k, width of a row of sensors) C-contiguous array receiving the sensors after every step.
        """
        k = out.shape[0]
        if k == CONTROL_STEPS:
            control = self._control
            self._wheel_control[:] = wheel_cmd
        else:
            control = self._control[:, :k]
            self._wheel_control[:k] = wheel_cmd
        if self.forcings:
            self._apply_faults(control[0], self.time + self._steps[:k])
            self._apply_geometry()
        if self._has_peds:
            i0 = round(self.time / self.dt)
            self._ensure_ped_track(i0 + k)
            self._ped_view(control[0])[:, self.ped_mocap, :] = self._ped_track[i0 : i0 + k]
        if self._flats and self._flat_near(k):
            touched = self._step_flat(control, out)
        else:
            touched = self._stepper.run(control[0], out, self.sensordata)  # `data` carries on from here
        self.sensordata = out[k - 1]
        self.time = self.data.time
        return touched

    def _flat_near(self, k: int) -> bool:
        """Whether a flat spot meets the floor during the coming `k` steps (then they run one by one)."""
        sl, sd = self.world.sensors, self.sensordata
        return any(
            f.flat_near(self.time, float(sd[sl.wheel_angle + f.wheel]), float(sd[sl.wheel_speed + f.wheel]),
                        k * self.dt)
            for f in self._flats
        )  # fmt: skip

    def _step_flat(self, control: np.ndarray, out: np.ndarray) -> bool:
        """Run the period's steps one at a time, raising each flat-spotted wheel's collision sphere by its
        flat's lift (`sim.faults.FaultForcing.flat_lift`) at the wheel's angle before every step."""
        sl = self.world.sensors
        touched = False
        for i in range(out.shape[0]):
            sd = self.sensordata
            time = self.data.time
            for f in self._flats:
                theta = float(sd[sl.wheel_angle + f.wheel])
                lift = f.flat_lift(time, theta)
                g = int(self.world.wheel_geom[f.wheel])
                # the chassis' up axis in the wheel's frame (the wheel turns by theta about its y axis)
                self.model.geom_pos[g] = self._geom_pos0[f.wheel] + lift * np.array(
                    [-math.sin(theta), 0.0, math.cos(theta)]
                )
            touched = self._stepper.run(control[0, i : i + 1], out[i : i + 1], sd) or touched
            self.sensordata = out[i]
        return touched

    def _ped_view(self, control: np.ndarray) -> np.ndarray:
        k = control.shape[0]
        return control[:, self._mocap0 : self._mocap0 + 3 * self.model.nmocap].reshape(
            k, self.model.nmocap, 3
        )

    def _ensure_ped_track(self, n: int) -> None:
        """Pedestrian positions at every physics step up to n, computed in blocks (vectorised)."""
        have = len(self._ped_track)
        if n <= have:
            return
        upto = max(n, 2 * have, 4096)
        times = self.dt * np.arange(have, upto)
        peds = tuple(self.scenario.obstacles[i] for i in self.ped_index)
        self._ped_track = np.concatenate([self._ped_track, pedestrian_positions(peds, times)])
        self._apply_step_back(have)

    def step_back(self, obstacle: int, robot_xy: tuple[float, ...]) -> None:
        """The pedestrian `obstacle` (an index into the scenario's obstacles) was bumped: from now on it
        steps back `STEP_BACK` away from the robot over `STEP_BACK_TIME` and stands there."""
        where = np.flatnonzero(self.ped_index == obstacle)
        if where.size == 0 or int(where[0]) in self._stepped_back:
            return
        j = int(where[0])
        i0 = round(self.time / self.dt)
        self._ensure_ped_track(i0 + 1)
        here = self._ped_track[i0, j, :2].copy()
        away = here - np.asarray(robot_xy[:2], dtype=np.float64)
        norm = float(np.linalg.norm(away))
        self._stepped_back[j] = (i0, here, away / norm if norm > 1e-9 else np.array([1.0, 0.0]))
        self._apply_step_back(i0)

    def _apply_step_back(self, start: int) -> None:
        for j, (i0, here, away) in self._stepped_back.items():
            first = max(start, i0)
            u = np.clip((np.arange(first, len(self._ped_track)) - i0) * self.dt / STEP_BACK_TIME, 0.0, 1.0)
            smooth = u * u * (3.0 - 2.0 * u)
            self._ped_track[first:, j, :2] = here + STEP_BACK * smooth[:, None] * away

    def _apply_faults(self, control: np.ndarray, times: np.ndarray) -> None:
        """Fault wrenches for the period: hub forces act on the chassis at the wheel centre (the tyre and
        ground take the wheel's share), motor torques on the wheel joint (reacted by the chassis).

        A period that no fault's window [onset, onset + duration) reaches (before the onset, after the end)
        gets zero wrenches without computing them (what they would sum to, +0.0 in every entry)."""
        k = len(times)
        m = self.model
        first, last = float(times[0]), float(times[-1])
        if all(last < f.record.onset or first >= f.record.onset + f.record.duration for f in self.forcings):
            if self._fault_wrenches:
                control[:, m.nu : m.nu + m.nv] = 0.0
                control[:, self._xfrc0 : self._mocap0] = 0.0
                self._fault_wrenches = False
            return
        self._fault_wrenches = True
        sl = self.world.sensors
        sd = self.sensordata
        forward, lateral = _axes(sd[sl.base_quat : sl.base_quat + 4])
        control[:, m.nu : self._mocap0] = 0.0  # the joint forces, then the body wrenches
        xf = control[:, self._xfrc0 : self._mocap0].reshape(k, m.nbody, 6)
        steps = self._steps[:k]
        base = self.world.base_body
        frame: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # rotation, base position, COM
        for forcing in self.forcings:
            wi = forcing.wheel
            angle = float(sd[sl.wheel_angle + wi])
            omega = float(sd[sl.wheel_speed + wi])
            torque = float(sd[sl.wheel_torque + wi])
            theta = angle + omega * steps
            wrench = np.zeros((k, 6))
            qf = np.zeros(k)
            forcing.apply(times, theta, omega, lateral, torque, wrench, qf, control[:, wi], self.dt)
            # Adding an all-zero wrench or torque is skipped: the columns start at +0.0 and sums that start
            # there never make -0.0, so adding +-0.0 would leave every entry as it is.
            if wrench.any():
                if frame is None:
                    rot = np.stack([forward, lateral, _cross(forward, lateral)], axis=1)
                    base_pos = sd[sl.base_pos : sl.base_pos + 3]
                    frame = rot, base_pos, base_pos + rot @ self._base_ipos
                rot, base_pos, com = frame
                hub = base_pos + rot @ self.world.robot.info.wheel_pos_body[wi]
                xf[:, base, :3] += wrench[:, :3]
                xf[:, base, 3:] += wrench[:, 3:] + _cross(hub - com, wrench[:, :3])
            if qf.any():
                control[:, m.nu + int(self.world.wheel_dof[wi])] += qf

    def _apply_geometry(self) -> None:
        """An out-of-round wheel: its collision shape moved off the axle by the runout, towards the defect's
        angle, for the coming period (the model is read at every step of the period)."""
        for forcing in self.forcings:
            offset = forcing.geometry_offset(self.time)
            if forcing.record.kind != "out_of_round":
                continue
            g = int(self.world.wheel_geom[forcing.wheel])
            phase = forcing.record.phase
            self.model.geom_pos[g] = self._geom_pos0[forcing.wheel] + offset * np.array(
                [math.cos(phase), 0.0, math.sin(phase)]
            )


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product over the last axis, with `np.cross`'s products and differences (the same bits) but
    without its axis handling, which costs more than the arithmetic on the 3-vectors."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def _axes(quat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Forward (x) and left (y) axes of a body with orientation `quat` (w, x, y, z), in the world."""
    qw, qx, qy, qz = quat
    forward = np.array([1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy + qw * qz), 2 * (qx * qz - qw * qy)])
    lateral = np.array([2 * (qx * qy - qw * qz), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz + qw * qx)])
    return forward, lateral


def yaw_of(quat: np.ndarray | tuple[float, float, float, float]) -> float:
    """Heading about z of orientation `quat` (w, x, y, z)."""
    qw, qx, qy, qz = quat
    return math.atan2(2 * (qw * qz + qx * qy), 1 - 2 * (qy * qy + qz * qz))
