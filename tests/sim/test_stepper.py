"""The compiled step loop against MuJoCo's own Python bindings: the same steps, bit for bit."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from sim_kit import straight

from sim.scenario import Obstacle
from sim.stepper import CONTROL_SPEC, Stepper
from sim.tyre import Tyres, tyres
from sim.world import World, build_world


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


def test_steps_equal_a_python_mj_step_loop_bit_for_bit() -> None:
    scenario = straight(duration=2.0, obstacles=(Obstacle("box", -9.0, 0.0),))
    world = build_world(scenario)
    model = world.model
    controls = _controls(model, 300, seed=4)
    data = mujoco.MjData(model)
    contacts = (world.sensors.obstacle_contact, len(world.obstacles))
    stepper = Stepper(model, data, contacts, _tyres(world, data))
    got = np.empty((len(controls), model.nsensordata))
    touched = [stepper.run(controls[i : i + 20], got[i : i + 20]) for i in range(0, len(controls), 20)]

    reference = mujoco.MjData(model)  # the model's flags as the stepper left them (no automatic reset)
    grip = Stepper(model, reference, contacts, _tyres(world, reference))  # its tyres, stepped from Python
    want = np.empty_like(got)
    for i, row in enumerate(controls):
        mujoco.mj_setState(model, reference, row, int(CONTROL_SPEC))
        grip.add_tyre_forces()
        mujoco.mj_step(model, reference)
        want[i] = reference.sensordata
    np.testing.assert_array_equal(got, want)
    assert data.time == reference.time and np.array_equal(data.qpos, reference.qpos)
    found = want[:, world.sensors.obstacle_contact :: 7][:, : len(world.obstacles)]
    assert touched == [bool(found[i : i + 20].any()) for i in range(0, len(controls), 20)]
    assert any(touched) and not all(touched)  # the robot drove into the box within the two seconds


def test_a_diverged_step_raises_instead_of_resetting() -> None:
    world = build_world(straight(duration=1.0))
    model = world.model
    data = mujoco.MjData(model)
    stepper = Stepper(model, data)
    data.qvel[:] = np.nan
    out = np.empty((4, model.nsensordata))
    with pytest.raises(FloatingPointError, match="diverged"):
        stepper.run(_controls(model, 4, seed=1), out)
    assert np.isnan(data.qvel).any()  # MuJoCo did not put the robot back at its start


def test_rows_of_the_wrong_width_are_refused() -> None:
    world = build_world(straight(duration=1.0))
    model = world.model
    stepper = Stepper(model, mujoco.MjData(model))
    controls = _controls(model, 4, seed=2)
    with pytest.raises(ValueError, match="wide"):
        stepper.run(controls[:, :-1], np.empty((4, model.nsensordata)))
    with pytest.raises(ValueError, match="wide"):
        stepper.run(controls[:2], np.empty((4, model.nsensordata)))
