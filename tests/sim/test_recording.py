"""`simulate`'s fast recording path gives the same trace, bit for bit, as the plain one.

`run_route` records through a cache-sized buffer moved block by block, keeps contact force and centroid only
in blocks with a contact and builds the wheel commands as Python floats; each must give exactly what one
(n, row width) array of every step and the numpy formula give. Likewise the shortcuts in the faults'
forcing, the obstacle velocities and the IMU's decimation.
"""

from __future__ import annotations

import numpy as np
import pytest

from sim import scenario_presets
from sim.engine import CONTROL_STEPS, Engine
from sim.imu import decimate
from sim.rollout import RECORD_PERIODS, _velocities, assemble_trace, run_route
from sim.trace import _flatten
from sim.world import build_world


@pytest.mark.parametrize("preset", ["collision_box", "fault_loose_wheel"])
def test_recording_matches_one_array_of_every_step(preset: str, monkeypatch: pytest.MonkeyPatch) -> None:
    scenario = scenario_presets()[preset](0)
    world = build_world(scenario)
    engine = Engine(world, scenario)
    periods: list[tuple[np.ndarray, int]] = []
    step = engine.step

    def step_and_keep(wheel_cmd: list[float], out: np.ndarray) -> None:
        periods.append((np.array(wheel_cmd, dtype=np.float64), out.shape[0]))
        step(wheel_cmd, out)

    monkeypatch.setattr(engine, "step", step_and_keep)
    trace = assemble_trace(scenario, world, run_route(engine, scenario), engine.dt)
    replay = Engine(world, scenario)
    full = np.empty((sum(k for _, k in periods), world.sensors.width))
    start = 0
    for wheel_cmd, k in periods:
        replay.step(wheel_cmd, full[start : start + k])
        start += k
    assert len(periods) > 2 * RECORD_PERIODS  # several blocks moved
    expected = _flatten(assemble_trace(scenario, world, full, replay.dt))
    got = _flatten(trace)
    assert got.keys() == expected.keys()
    for key, value in expected.items():
        assert value.dtype == got[key].dtype and np.array_equal(value, got[key]), key
    if preset.startswith("collision"):
        assert len(trace.contacts.time) > 0  # the sparse contact arrays were exercised


def test_wheel_commands_are_the_numpy_formula_bit_for_bit() -> None:
    for preset in ("nominal_indoor", "nominal_diff2", "fault_motor_degradation"):
        scenario = scenario_presets()[preset](1)
        engine = Engine(build_world(scenario), scenario)
        rng = np.random.default_rng(2)
        for v, w in [(0.0, 0.0), (-0.0, 0.0), (0.0, -0.0), *rng.normal(size=(200, 2)).tolist()]:
            expected = (v + engine.side * w * engine.half_track) / engine.radius
            for forcing in engine.forcings:
                expected[forcing.wheel] *= forcing.speed_factor(engine.time)
            got = np.array(engine.wheel_commands(v, w))
            assert np.array_equal(got, expected) and np.array_equal(np.signbit(got), np.signbit(expected))


@pytest.mark.parametrize("preset", ["collision_box", "collision_pedestrian", "collision_wall"])
def test_obstacle_velocities_are_np_gradient_bit_for_bit(preset: str) -> None:
    """Velocities are differentiated for the free and mocap obstacles only: a fixed one's recorded position
    never changes, so np.gradient's +0.0 is what it gets."""
    scenario = scenario_presets()[preset](0)
    world = build_world(scenario)
    engine = Engine(world, scenario)
    record = run_route(engine, scenario)
    k = len(world.obstacles)
    pos = record.cols(world.sensors.obstacle_pos, 3 * k).reshape(record.n, k, 3)
    movable = world.obstacle_free | (world.obstacle_mocap >= 0)
    assert movable.any() and not movable.all()
    expected = np.gradient(pos, engine.dt, axis=0)
    assert _velocities(pos, engine.dt, movable).tobytes() == expected.tobytes()


def test_faults_outside_their_window_leave_zero_wrenches() -> None:
    """Periods before a fault's onset skip its forcing; the wrenches are the +0.0 it would have summed to."""
    scenario = scenario_presets()["fault_loose_wheel"](0)
    engine = Engine(build_world(scenario), scenario)
    onset = engine.forcings[0].record.onset
    out = np.empty((CONTROL_STEPS, engine.world.sensors.width))
    wrenches = slice(engine.model.nu, engine.ncontrol)
    while engine.time + CONTROL_STEPS * engine.dt < onset:
        engine.step(engine.wheel_commands(0.5, 0.0), out)
        assert not np.signbit(engine._control[0, :, wrenches]).any()
        assert not engine._control[0, :, wrenches].any()
    while engine.time < onset + 1.0:
        engine.step(engine.wheel_commands(0.5, 0.0), out)
    assert engine._control[0, :, wrenches].any()  # the fault pushes once it acts


@pytest.mark.parametrize("factor", [1, 2])
def test_one_and_two_step_decimation_is_numpy_mean_bit_for_bit(factor: int) -> None:
    """`decimate`'s (a + b + 0.0) / 2, and a step's own value, against numpy's mean, signed zeros, NaNs,
    infinities and subnormals included, on contiguous and strided columns."""
    special = [0.0, -0.0, 1.0, -1.0, 5e-324, -5e-324, np.inf, -np.inf, np.nan, -np.nan, 1e308, -1e308, -2.2]
    pairs = np.array([[a, b] for a in special for b in special]).ravel()
    columns = np.stack([pairs, pairs[::-1], -pairs], axis=1)
    noise = np.random.default_rng(0).normal(size=(4001, 3))
    with np.errstate(all="ignore"):
        for x in (pairs, pairs[:-1], columns, columns[:, 2], noise, noise[:, 1]):
            n = x.shape[0] // factor * factor
            expected = x[:n].reshape(n // factor, factor, *x.shape[1:]).mean(axis=1)
            got = decimate(x, factor)
            assert got.shape == expected.shape and got.tobytes() == expected.tobytes()
