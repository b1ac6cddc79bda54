"""The compiled step loop against MuJoCo's own Python bindings and sensors: the same steps and values, bit
for bit."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest
from sim_kit import straight

from sim.scenario import Obstacle, Scenario, Transient
from sim.stepper import CONTROL_SPEC, Stepper, add_tyre_forces, sensor_row
from sim.tyre import Tyres, tyres
from sim.world import World, build_world, reference_model


def _controls(model: mujoco.MjModel, steps: int, seed: int) -> np.ndarray:
    """(steps, ncontrol) rows: wheel speeds and pushes on the chassis that change every step."""
    rng = np.random.default_rng(seed)
    ncontrol = mujoco.mj_stateSize(model, int(CONTROL_SPEC))
    rows = np.zeros((steps, ncontrol))
    rows[:, : model.nu] = 12.0 + rng.normal(0.0, 2.0, (steps, model.nu))
    xfrc = model.nu + model.nv
    base = 1  # the robot's base, the first body after the world's
    rows[:, xfrc + 6 * base : xfrc + 6 * base + 3] = rng.normal(0.0, 20.0, (steps, 3))
    return rows


def _tyres(world: World, data: mujoco.MjData) -> Tyres:
    mujoco.mj_forward(world.model, data)
    return tyres(world, data)


def _scenario(surface: str) -> Scenario:
    """Straight at a box (free, pushed when hit) past a cable and a pedestrian, beside a wall."""
    obstacles = (Obstacle("box", -9.0, 0.0), Obstacle("wall", -9.5, 1.2), Obstacle("pedestrian", -8.0, -1.5))
    base = straight(duration=2.0, obstacles=obstacles)
    environment = "indoor" if surface == "tile" else "outdoor"
    cable = Transient("cable", -9.75, 0.0, 1.5708)
    arena = base.arena if surface == "tile" else (12.0, 5.0)
    return dataclasses.replace(
        base, environment=environment, surface=surface, arena=arena, transients=(cable,)
    )


@pytest.mark.parametrize("surface", ["tile", "grass"])
def test_rows_equal_mujocos_own_sensors_of_a_python_mj_step_loop_bit_for_bit(surface: str) -> None:
    """The step loop's rows (copies of the data, contact sensors of its own) against a world with a MuJoCo
    sensor for every value, stepped from Python: the same values, bit for bit, through a robot running
    over a cable into a box it pushes (contacts in both orders of their geoms), on a flat and a rough
    floor."""
    scenario = _scenario(surface)
    world = build_world(scenario)
    model = world.model
    controls = _controls(model, 300, seed=4)
    data = mujoco.MjData(model)
    contacts = (world.sensors.obstacle_contact, len(world.obstacles))
    stepper = Stepper(world, data, contacts, _tyres(world, data))
    got = np.empty((len(controls), world.sensors.width))
    previous = sensor_row(world, data)
    touched = []
    for i in range(0, len(controls), 20):
        touched.append(stepper.run(controls[i : i + 20], got[i : i + 20], previous))
        previous = got[i + 19]

    reference_model_ = reference_model(scenario)
    reference_model_.opt.disableflags = model.opt.disableflags  # as the stepper left them (no auto reset)
    reference = mujoco.MjData(reference_model_)
    grip = _tyres(world, reference)
    assert reference_model_.nsensordata == world.sensors.width
    want = np.empty_like(got)
    last = reference.sensordata.copy()
    for i, row in enumerate(controls):
        mujoco.mj_setState(reference_model_, reference, row, int(CONTROL_SPEC))
        add_tyre_forces(reference_model_, reference, grip, last)
        mujoco.mj_step(reference_model_, reference)
        want[i] = last = reference.sensordata
    np.testing.assert_array_equal(got, want)
    assert data.time == reference.time and np.array_equal(data.qpos, reference.qpos)
    sl = world.sensors
    found = want[:, sl.obstacle_contact :: 7][:, : len(world.obstacles)]
    assert touched == [bool(found[i : i + 20].any()) for i in range(0, len(controls), 20)]
    assert any(touched) and not all(touched)  # the robot drove into the box within the two seconds
    assert want[:, sl.transient_contact : sl.tyre_contact : 7].any()  # and over the cable
    on_floor = want[:, sl.tyre_contact :: 7]
    assert (on_floor >= 1).any()
    assert (on_floor.max() > 1) == (surface == "grass")  # a heightfield meets a tyre at several points


def test_a_row_of_the_initial_state_is_mujocos_sensors_after_mj_forward() -> None:
    scenario = _scenario("tile")
    world = build_world(scenario)
    data = mujoco.MjData(world.model)
    mujoco.mj_forward(world.model, data)
    reference_model_ = reference_model(scenario)
    reference = mujoco.MjData(reference_model_)
    mujoco.mj_forward(reference_model_, reference)
    np.testing.assert_array_equal(sensor_row(world, data), reference.sensordata)


def test_a_diverged_step_raises_instead_of_resetting() -> None:
    world = build_world(straight(duration=1.0))
    model = world.model
    data = mujoco.MjData(model)
    stepper = Stepper(world, data)
    data.qvel[:] = np.nan
    out = np.empty((4, world.sensors.width))
    with pytest.raises(FloatingPointError, match="diverged"):
        stepper.run(_controls(model, 4, seed=1), out, np.zeros(world.sensors.width))
    assert np.isnan(data.qvel).any()  # MuJoCo did not put the robot back at its start


def test_rows_of_the_wrong_width_are_refused() -> None:
    world = build_world(straight(duration=1.0))
    model = world.model
    stepper = Stepper(world, mujoco.MjData(model))
    controls = _controls(model, 4, seed=2)
    previous = np.zeros(world.sensors.width)
    with pytest.raises(ValueError, match="wide"):
        stepper.run(controls[:, :-1], np.empty((4, world.sensors.width)), previous)
    with pytest.raises(ValueError, match="wide"):
        stepper.run(controls[:2], np.empty((4, world.sensors.width)), previous)
    with pytest.raises(ValueError, match="previous row"):
        stepper.run(controls, np.empty((4, world.sensors.width)), previous[:-1])
