"""Simulation speed: real-time factor of `sim.simulate` on one core, and its cost against a bare loop.

`sim_rtf` = simulated seconds / CPU seconds of `simulate(scenario)` (world building, stepping with the
controller, faults and sensors, trace assembly: the whole call). `sim_overhead_vs_bare` = that CPU time /
the CPU time of the bare physics over the same compiled model and the same number of steps: the compiled
step loop (`sim.stepper`: `mj_step` and the tyres' grip, the row of sensors filled) called once per control
period as the simulator calls it, into one period's rows (which stay in the CPU's cache, as the simulator's
recording buffer does), replaying the episode's wheel speeds as commands (so the robot drives a similar
path), with no controller, faults or trace between the periods. CPU time (`time.process_time`) is used so
that other processes on the machine do not count; each figure is the best of a few repeats, the two
measured in turn.
"""

from __future__ import annotations

import time

import numpy as np

from benchmarks.perf.base import PerfStage


def _measure(quick: bool) -> dict[str, float]:
    import mujoco

    import sim
    from sim.engine import CONTROL_STEPS
    from sim.stepper import CONTROL_SPEC, Stepper, sensor_row
    from sim.tyre import tyres
    from sim.world import build_world

    duration = 4.0 if quick else 60.0
    repeats = 1 if quick else 5
    scenario = sim.scenario_presets()["nominal_indoor"](0).replace(duration=duration)
    trace = sim.simulate(scenario)  # the bare loop replays its wheel speeds
    world = build_world(scenario)
    model = world.model
    controls = np.zeros((len(trace.time), mujoco.mj_stateSize(model, int(CONTROL_SPEC))))
    controls[:, : model.nu] = trace.wheel_speed
    out = np.empty((CONTROL_STEPS, world.sensors.width))
    best_sim = best_bare = np.inf
    for _ in range(repeats):  # one of each in turn: a stretch of load on the machine slows both alike
        start = time.process_time()
        trace = sim.simulate(scenario)
        best_sim = min(best_sim, time.process_time() - start)
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        stepper = Stepper(world, data, tyres=tyres(world, data))
        previous = sensor_row(world, data)
        start = time.process_time()
        for first in range(0, len(controls), CONTROL_STEPS):
            rows = controls[first : first + CONTROL_STEPS]
            stepper.run(rows, out[: len(rows)], previous)
            previous = out[len(rows) - 1]
        best_bare = min(best_bare, time.process_time() - start)
    steps = len(trace.time)
    return {
        "sim_rtf": trace.duration / best_sim,
        "sim_overhead_vs_bare": best_sim / best_bare,
        "sim_us_per_step": 1e6 * best_sim / steps,
        "sim_bare_us_per_step": 1e6 * best_bare / steps,
        "sim_bare_rtf": trace.duration / best_bare,
    }


STAGE = PerfStage(
    name="sim",
    measure=_measure,
    describe={
        "sim_rtf": "simulated s per CPU s of simulate() on one core, nominal_indoor 60 s (target >= 150)",
        "sim_overhead_vs_bare": "simulate() CPU time / the bare compiled physics (mj_step and the tyres), "
        "same model, steps (target <= 1.10)",
        "sim_us_per_step": "simulate() CPU microseconds per 2.5 ms physics step",
        "sim_bare_us_per_step": "bare compiled physics CPU microseconds per physics step",
        "sim_bare_rtf": "real-time factor of the bare compiled physics (the ceiling for sim_rtf)",
    },
    ratios={"sim_overhead_vs_bare": "lower"},
)
