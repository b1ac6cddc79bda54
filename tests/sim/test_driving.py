"""The route controller's manoeuvres and reflexes, simulated: emergency stops, near misses, reactions."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from benchmarks.audit.signals import forward_speed
from sim import simulate
from sim.engine import STEP_BACK
from sim.scenario import Obstacle, Reflex, Route, Scenario, Unit, Waypoint
from sim.trace import Trace
from sim.world import build_world

GRIP = 1.2 * 9.81
"""More braking than about 1.2 g no tyre on a floor gives, m/s^2."""


def _scenario(
    waypoints: tuple[Waypoint, ...],
    obstacles: tuple[Obstacle, ...] = (),
    reflex: Reflex | None = None,
    duration: float = 8.0,
) -> Scenario:
    reflex = reflex if reflex is not None else Reflex()
    return Scenario(
        name="driving",
        seed=5,
        duration=duration,
        environment="indoor",
        surface="tile",
        arena=(8.0, 4.0),
        robot=Unit(unit_id=0, variation=0.0),
        route=Route(start=(-4.0, 0.0, 0.0), waypoints=waypoints, accel=0.8, loop=False, reflex=reflex),
        obstacles=obstacles,
    )


def _speed(trace: Trace) -> np.ndarray:
    return forward_speed(trace.base_quat, trace.base_linvel)


def _peak_deceleration(trace: Trace) -> float:
    v = np.convolve(_speed(trace), np.ones(16) / 16, mode="same")
    return float(np.max(-np.gradient(v, trace.physics_dt)[50:-50]))


def test_an_emergency_stop_brakes_at_the_limit_and_a_smooth_stop_at_the_route_accel() -> None:
    hard = simulate(_scenario((Waypoint(0.0, 0.0, 1.0, 2.0, hard_stop=True),)))
    smooth = simulate(_scenario((Waypoint(0.0, 0.0, 1.0, 2.0),)))
    assert 2.5 < _peak_deceleration(hard) < GRIP
    assert _peak_deceleration(smooth) < 1.5  # the route's 0.8 m/s^2, plus the servo's overshoot
    for trace in (hard, smooth):  # both stand at the waypoint
        assert abs(float(_speed(trace)[-1])) < 0.02


def _box_face_gap(trace: Trace, face_x: float) -> float:
    reach = 0.325  # skid4: bumper capsule at 0.30 m, radius 0.025 m
    return face_x - float(trace.base_pos[-1, 0]) - reach


def test_a_near_miss_stops_short_without_touching() -> None:
    box = Obstacle("wall", 0.0, 0.0, 0.0, (0.06, 1.5, 0.6))
    leg = Waypoint(0.5, 0.0, 1.0, ram=0, stop_short=0.35)
    trace = simulate(_scenario((leg,), (box,), Reflex(kind="wait", wait=5.0)))
    assert len(trace.contacts.time) == 0
    assert 0.02 < _box_face_gap(trace, -0.06) < 0.35
    assert np.all(trace.label == 0)


def _hit(reflex: Reflex, after: tuple[Waypoint, ...] = ()) -> Trace:
    wall = Obstacle("wall", 0.0, 0.0, 0.0, (0.06, 1.5, 0.6))
    return simulate(_scenario((Waypoint(0.5, 0.0, 0.6, ram=0), *after), (wall,), reflex, duration=10.0))


def _after_contact(trace: Trace, seconds: float) -> np.ndarray:
    t0 = float(trace.contacts.time[0])
    assert t0 + seconds < trace.duration
    return (trace.time > t0) & (trace.time < t0 + seconds)


def _seconds(trace: Trace, mask: np.ndarray) -> float:
    return float(np.sum(mask)) * trace.physics_dt


def test_reflex_reverse_backs_off_for_its_time_and_wait_stands() -> None:
    back = _hit(Reflex(kind="reverse", wait=0.5, reverse_time=1.0, reverse_speed=0.3))
    stand = _hit(Reflex(kind="wait", wait=3.0))
    for trace in (back, stand):
        assert len(trace.contacts.time) >= 1
    reversing = _seconds(back, _after_contact(back, 2.5) & (_speed(back) < -0.1))
    assert reversing == pytest.approx(1.0, abs=0.3)  # plus the ramp to a stop at the route's accel
    assert _seconds(stand, _after_contact(stand, 2.5) & (_speed(stand) < -0.1)) < 0.25  # only the rebound


def test_reflex_push_keeps_the_contact_and_continue_does_not_stop() -> None:
    push = _hit(Reflex(kind="push", push_time=1.5, wait=0.5))
    assert float(np.max(push.contacts.duration)) > 1.2  # stalled against the wall
    glance = _hit(Reflex(kind="continue"), after=(Waypoint(-2.0, 2.5, 0.6),))
    idle = (np.abs(_speed(glance)) < 0.02) & (np.abs(glance.base_angvel[:, 2]) < 0.1)
    # never stands: turns away (pressed to the wall, the pivot takes a moment to build) and drives on
    assert _seconds(glance, _after_contact(glance, 2.0) & idle) < 0.25


def test_a_bumped_pedestrian_steps_back_and_stands() -> None:
    person = Obstacle("pedestrian", 0.0, 0.0, 0.0, (0.2, 0.2, 0.85))
    trace = simulate(_scenario((Waypoint(0.5, 0.0, 0.5, ram=0),), (person,), Reflex(kind="wait", wait=4.0)))
    assert len(trace.contacts.time) >= 1
    moved = trace.obstacle_pos[-1, 0, :2] - np.array([0.0, 0.0])
    assert float(np.linalg.norm(moved)) == pytest.approx(STEP_BACK, abs=0.05)
    assert moved[0] > 0.3  # away from the robot, which came from -x


def _pushed_box(sleep: bool) -> Trace:
    box = Obstacle("box", 0.0, 0.0, 0.0, (0.2, 0.2, 0.2))
    scenario = _scenario((Waypoint(0.5, 0.0, 0.5, ram=0),), (box,), Reflex(kind="push", push_time=1.0), 8.0)
    world = build_world(scenario)
    if not sleep:
        world.model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    return simulate(scenario, world)


def test_a_resting_box_sleeps_until_the_robot_wakes_it_as_if_it_had_been_awake() -> None:
    """MuJoCo's sleeping islands (`sim.world.SLEEP_TOLERANCE`): the box at rest sleeps, the robot never does,
    and the robot's push wakes the box at the same contact, which is then pushed as far as an awake box is."""
    box = Obstacle("box", 1.0, 1.0, 0.0, (0.2, 0.2, 0.2))
    world = build_world(_scenario((Waypoint(-3.0, 0.0, 0.0),), (box,)))
    model, data = world.model, mujoco.MjData(world.model)
    assert model.opt.enableflags & mujoco.mjtEnableBit.mjENBL_SLEEP
    for _ in range(round(0.2 / model.opt.timestep)):  # the robot stands, its motors holding still
        mujoco.mj_step(model, data)
    robot_tree = int(model.body_treeid[world.base_body])
    box_tree = 1 - robot_tree
    assert data.tree_asleep[box_tree] >= 0 and data.tree_asleep[robot_tree] < 0
    asleep, awake = _pushed_box(True), _pushed_box(False)
    for trace in (asleep, awake):
        assert len(trace.contacts.time) >= 1
    first = [float(t.contacts.time[0]) for t in (asleep, awake)]
    assert first[0] == pytest.approx(first[1], abs=asleep.physics_dt)
    moved = [float(np.linalg.norm(np.ptp(t.obstacle_pos[[0, -1], 0, :2], axis=0))) for t in (asleep, awake)]
    assert moved[1] > 0.1  # the push moves the box
    assert moved[0] == pytest.approx(moved[1], rel=0.05)
