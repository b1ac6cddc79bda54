"""The tyres' grip (`sim.tyre`) against its law computed from MuJoCo's own kinematics, and against Coulomb's
law for a sliding robot."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from sim_kit import straight

from sim.engine import CONTROL_STEPS, Engine
from sim.scenario import Scenario
from sim.stepper import add_tyre_forces, sensor_row
from sim.tyre import TYRE_SLIP_SPEED
from sim.world import SURFACES, World, build_world


def _settled(scenario: Scenario) -> tuple[World, Engine]:
    """The robot at rest on its tyres (it starts 2 mm above the floor), motors holding still."""
    world = build_world(scenario)
    engine = Engine(world, scenario)
    out = np.empty((CONTROL_STEPS, world.sensors.width))
    for _ in range(8):
        engine.step(np.zeros(world.n_wheels), out)
    return world, engine


def test_the_grip_is_the_regularised_coulomb_law_at_each_contact_point() -> None:
    scenario = straight(duration=1.0)
    world, engine = _settled(scenario)
    model, data = world.model, engine.data
    rng = np.random.default_rng(3)
    data.qvel[world.root_dof : world.root_dof + 6] = rng.normal(0.0, [0.5, 0.5, 0.0, 0.0, 0.0, 1.0])
    data.qvel[world.wheel_dof] = rng.normal(0.0, 10.0, world.n_wheels)
    mujoco.mj_forward(model, data)
    data.xfrc_applied[:] = 0.0
    row = sensor_row(world, data)
    add_tyre_forces(model, data, engine.tyres, row)
    table = engine.tyres.table
    dt = model.opt.timestep
    velocity = np.zeros(6)
    for w in range(world.n_wheels):
        body = int(world.wheel_body[w])
        s = world.sensors.tyre_contact + 7 * w
        assert row[s] >= 1  # the wheel stands on the floor
        force, point = row[s + 1 : s + 4], row[s + 4 : s + 7]
        normal_force = np.linalg.norm(force)
        n = force / normal_force * np.sign(force[2])
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, body, velocity, 0)
        v = velocity[3:] + np.cross(velocity[:3], point - data.xpos[body])
        slip = v - (v @ n) * n
        mu, inverse_mass = table[w, 4], table[w, 5]
        t = np.tanh(np.linalg.norm(slip) / TYRE_SLIP_SPEED)
        stiffness = mu * normal_force / TYRE_SLIP_SPEED * (1 - t * t)
        want = -mu * normal_force * t / (1 + dt * inverse_mass * stiffness) * slip / np.linalg.norm(slip)
        np.testing.assert_allclose(data.xfrc_applied[body, :3], want, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(
            data.xfrc_applied[body, 3:], np.cross(point - data.xipos[body], want), rtol=1e-9, atol=1e-12
        )
        assert mu == SURFACES[scenario.surface].friction  # the floor's, the larger of the two geoms'


def test_a_robot_sliding_on_locked_wheels_decelerates_at_mu_g() -> None:
    """Wheels held at rest (their servos are stronger than the tyres' grip) under a robot moving at 2 m/s:
    every tyre slides, and the floor's friction mu N over the robot's weight decelerates it at mu g."""
    scenario = straight(duration=1.0)
    world, engine = _settled(scenario)
    engine.data.qvel[world.root_dof] = 2.0
    mujoco.mj_forward(world.model, engine.data)
    engine.sensordata = sensor_row(world, engine.data)
    out = np.empty((5 * CONTROL_STEPS, world.sensors.width))
    for start in range(0, len(out), CONTROL_STEPS):
        engine.step(np.zeros(world.n_wheels), out[start : start + CONTROL_STEPS])
    speed = out[:, world.sensors.base_linvel]
    rim = np.abs(out[:, world.sensors.wheel_speed : world.sensors.wheel_speed + world.n_wheels]).max()
    assert rim * world.robot.info.wheel_radius.max() < 0.1 * speed.min()  # the tyres slide throughout
    deceleration = -np.polyfit(engine.dt * np.arange(len(out)), speed, 1)[0]
    assert deceleration == pytest.approx(SURFACES[scenario.surface].friction * 9.81, rel=0.03)


def test_each_wheel_meets_the_floor_through_its_normal_only_pair() -> None:
    world = build_world(straight(duration=1.0))
    model = world.model
    data = mujoco.MjData(model)
    for _ in range(50):
        mujoco.mj_step(model, data)
    floor = model.geom("floor").id
    wheel_contacts = [c for c in data.contact[: data.ncon] if floor in (c.geom1, c.geom2)]
    assert sorted(int(c.geom2) for c in wheel_contacts) == sorted(world.wheel_geom.tolist())
    assert {int(c.dim) for c in wheel_contacts} == {1}
