"""`simulate`'s fast recording path gives the same trace, bit for bit, as the plain one.

`run_route` records through a cache-sized buffer moved block by block, keeps contact force and centroid only
in blocks with a contact and builds the wheel commands as Python floats; each must give exactly what one
(n, nsensordata) array of every step and the numpy formula give.
"""

from __future__ import annotations

import numpy as np
import pytest

from sim import scenario_presets
from sim.engine import Engine
from sim.rollout import RECORD_PERIODS, assemble_trace, run_route
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
    full = np.empty((sum(k for _, k in periods), world.model.nsensordata))
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
