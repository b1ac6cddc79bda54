"""Physics oracles: commanded speed, differential-drive yaw rate, collision impulse = momentum change."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from sim_kit import straight

from sim import simulate, vocab
from sim.engine import CONTROL_STEPS, Engine
from sim.events import contact_events
from sim.scenario import Obstacle, Scenario, Unit
from sim.stepper import sensor_row
from sim.world import build_world


def _constant_drive(scenario: Scenario, v: float, w: float, seconds: float) -> tuple[Engine, np.ndarray]:
    world = build_world(scenario)
    engine = Engine(world, scenario)
    n = round(seconds / engine.dt / CONTROL_STEPS) * CONTROL_STEPS
    out = np.empty((n, world.sensors.width))
    for start in range(0, n, CONTROL_STEPS):
        engine.step(np.array(engine.wheel_commands(v, w)), out[start : start + CONTROL_STEPS])
    return engine, out


@pytest.mark.parametrize("model", ["skid4", "diff2"])
def test_straight_driving_reaches_commanded_speed(model: str) -> None:
    trace = simulate(straight(duration=6.0, speed=1.0, model=model))
    late = trace.time > 3.0
    speed = np.linalg.norm(trace.base_linvel[late, :2], axis=1)
    assert abs(speed.mean() - 1.0) < 0.04  # a P velocity servo per wheel: small steady-state droop
    assert abs(trace.base_pos[-1, 1]) < 0.1  # stayed on the line
    # wheels roll without slip: surface speed = body speed
    rolling = trace.wheel_speed[late].mean(axis=0) * trace.robot.wheel_radius
    np.testing.assert_allclose(rolling, speed.mean(), rtol=0.03)


def test_diff2_rolls_steadily_on_its_frictionless_caster() -> None:
    """On a flat floor at a constant command nothing forces a pitch: the rear ball caster touches without
    friction (a contact of dimension 1), so the chassis neither pitches nor bounces (a caster that dragged
    with the floor's friction bounced on it, the harder the longer the physics step)."""
    trace = simulate(straight(duration=4.0, speed=1.0, model="diff2"))
    late = trace.time > 2.0
    assert np.abs(trace.base_angvel[late]).max() < 1e-3
    assert np.ptp(trace.base_pos[late, 2]) < 1e-5
    world = build_world(straight(model="diff2"))
    m, d = world.model, mujoco.MjData(world.model)
    caster = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "diff2/caster_back")
    for _ in range(200):
        mujoco.mj_step(m, d)
    dims = {int(c.dim) for c in d.contact[: d.ncon] if caster in (c.geom1, c.geom2)}
    assert dims == {1}


def test_diff2_yaw_rate_matches_differential_drive_kinematics() -> None:
    scenario = straight(model="diff2")
    engine, out = _constant_drive(scenario, 0.4, 0.6, 4.0)
    sl = engine.world.sensors
    late = slice(out.shape[0] // 2, None)
    omega = out[late, sl.wheel_speed : sl.wheel_speed + 2].mean(axis=0)
    r = engine.world.robot.info.wheel_radius
    track = engine.world.robot.info.track
    kinematic = (omega[1] * r[1] - omega[0] * r[0]) / track
    measured = out[late, sl.base_angvel + 2].mean()
    assert measured == pytest.approx(kinematic, rel=0.08)
    assert measured == pytest.approx(0.6, rel=0.15)  # and the controller's command is met


def test_skid4_yaw_rate_matches_kinematics_with_effective_track() -> None:
    engine, out = _constant_drive(straight(model="skid4"), 0.4, 0.6, 4.0)
    measured = out[out.shape[0] // 2 :, engine.world.sensors.base_angvel + 2].mean()
    assert measured == pytest.approx(0.6, rel=0.15)


def test_collision_impulse_matches_momentum_change() -> None:
    """Coasting (motors off) into a fixed wall: wall impulse = m dv + sum(I dw / r) over the event."""
    scenario = straight(obstacles=(Obstacle("wall", -8.6, 0.0, size=(0.06, 1.5, 0.6)),))
    world = build_world(scenario)
    m = world.model
    m.actuator_gainprm[:, 0] = 0.0
    m.actuator_biasprm[:, :3] = 0.0
    engine = Engine(world, scenario)
    info = world.robot.info
    v0 = 1.0
    engine.data.qvel[world.root_dof] = v0
    engine.data.qvel[world.wheel_dof] = v0 / info.wheel_radius
    mujoco.mj_forward(m, engine.data)  # the engine steps on from its data
    engine.sensordata = sensor_row(world, engine.data)  # and its sensors
    n = 40 * CONTROL_STEPS
    out = np.empty((n, world.sensors.width))
    for start in range(0, n, CONTROL_STEPS):
        engine.step(np.zeros(world.n_wheels), out[start : start + CONTROL_STEPS])
    sl = world.sensors
    k = len(world.obstacles)
    hits = out[:, sl.obstacle_contact : sl.obstacle_contact + 7 * k].reshape(n, k, 7)
    vel = out[:, sl.base_linvel : sl.base_linvel + 3]
    events, runs = contact_events(
        hits[:, :, 0], hits[:, :, 1:4], hits[:, :, 4:7], vel, np.zeros((n, k, 3)), world.obstacles, engine.dt
    )
    assert len(events.time) == 1 and events.obstacle_kind == ("wall",)
    start, stop, _ = runs[0]
    dv = vel[stop, 0] - vel[start - 1, 0]
    wheel_speed = out[:, sl.wheel_speed : sl.wheel_speed + world.n_wheels]
    dw = wheel_speed[stop] - wheel_speed[start - 1]
    inertia = m.dof_armature[world.wheel_dof] + m.body_inertia[world.wheel_body, 1]
    expected = abs(info.mass * dv + np.sum(inertia * dw / info.wheel_radius))
    assert events.impulse[0] == pytest.approx(expected, rel=0.15)
    assert events.impulse[0] > 0.5 * info.mass * v0
    assert events.normal[0, 0] == pytest.approx(-1.0, abs=0.1)  # from the wall (ahead, +x) towards the robot
    assert events.normal_speed[0] == pytest.approx(vel[start - 1, 0], rel=0.05)


def test_nominal_run_has_transients_but_no_collisions() -> None:
    from sim import ScenarioOptions, draw_scenario

    scenario = draw_scenario(
        4, "nominal", ScenarioOptions(duration=25.0, environment="indoor", transient_density=3.0)
    )
    trace = simulate(scenario)
    assert len(trace.contacts.time) == 0
    assert len(trace.transients.time) >= 4
    assert np.all(trace.transients.impulse > 0)
    assert set(trace.transients.kind) <= {t.kind for t in scenario.transients}
    assert np.all(trace.label == 0)


def test_collision_run_labels_the_contact() -> None:
    from sim import ScenarioOptions, draw_scenario

    trace = simulate(draw_scenario(1, "collision", ScenarioOptions(duration=25.0, obstacle_kind="box")))
    assert "box" in trace.contacts.obstacle_kind
    t0 = trace.contacts.time[0]
    at = np.searchsorted(trace.imu_time, t0 + 0.01)
    assert trace.label[at] == 1
    assert trace.sub_kind[at] == vocab.sub_kind_index("box")
    assert trace.contacts.material[0] == "cardboard"


def test_unit_variation_changes_the_robot() -> None:
    a = build_world(straight().replace(robot=Unit(unit_id=1))).robot.info
    b = build_world(straight().replace(robot=Unit(unit_id=2))).robot.info
    assert not np.allclose(a.wheel_radius, b.wheel_radius)
    assert a.gear_ratio != b.gear_ratio
    assert np.all(np.abs(a.wheel_radius / 0.08 - 1) < 0.02)
    assert 19.0 < a.mass < 22.0
