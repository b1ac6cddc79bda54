"""`msvdd-bench simulate`: run one scenario (a preset or a TOML file) and write its trace."""

from __future__ import annotations

import argparse
import time
from collections import Counter
from pathlib import Path

from benchmarks.command import Command
from benchmarks.errors import UserError, check_seed


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--scenario",
        required=True,
        help="a named scenario preset (`msvdd-bench scenarios`) or a scenario TOML file (assets/scenarios/)",
    )
    p.add_argument(
        "--scenario-seed",
        type=int,
        default=None,
        help="scenario seed: with a named preset, the seed its scenario is drawn with (setting, obstacles, "
        "route, transients, fault) and the simulation's own draws (surface roughness, sensor noise, rattle) "
        "(default: 0); with a TOML file, replaces the file's `seed`, which seeds the simulation's draws only "
        "(default: the file's)",
    )
    p.add_argument("--out", type=Path, required=True, help="where to write the trace (.npz)")


def _run(args: argparse.Namespace) -> int:
    import numpy as np

    import sim

    seed = None if args.scenario_seed is None else check_seed(args.scenario_seed, "--scenario-seed")
    if args.out.suffix != ".npz":
        raise UserError(f"--out = {str(args.out)!r} is invalid; allowed: a path ending in .npz")
    presets = sim.scenario_presets()
    if args.scenario in presets:
        scenario = presets[args.scenario](0 if seed is None else seed)
    elif args.scenario.endswith(".toml"):
        scenario = sim.Scenario.from_toml(Path(args.scenario))
        if seed is not None:
            scenario = scenario.replace(seed=seed)
    else:
        raise UserError(
            f"--scenario = {args.scenario!r} is unknown; allowed: a .toml file or one of {', '.join(presets)}"
        )
    start = time.perf_counter()
    trace = sim.simulate(scenario)
    wall = time.perf_counter() - start
    bad = trace.non_finite_fields()
    if bad:
        raise UserError(f"simulation produced non-finite values in {', '.join(bad)}; nothing written")
    path = trace.save(args.out)
    speed = np.linalg.norm(trace.base_linvel[:, :2], axis=1)
    distance = float(speed.sum() * trace.physics_dt)
    kinds = Counter(trace.contacts.obstacle_kind)
    print(
        f"scenario   {trace.scenario_name} (seed {trace.seed}, {trace.environment}, {trace.surface}, "
        f"robot {trace.robot.model} unit {trace.robot.unit_id})"
    )
    print(
        f"duration   {trace.duration:.2f} s simulated in {wall:.2f} s "
        f"({trace.duration / max(wall, 1e-9):.0f}x real time)"
    )
    print(f"distance   {distance:.1f} m, top speed {speed.max():.2f} m/s")
    print(
        f"contacts   {len(trace.contacts.time)}"
        + (f" ({', '.join(f'{k} x{n}' for k, n in kinds.items())})" if kinds else "")
    )
    for t, k, j, v in zip(
        trace.contacts.time,
        trace.contacts.obstacle_kind,
        trace.contacts.impulse,
        trace.contacts.normal_speed,
        strict=True,
    ):
        print(f"           t={t:7.2f} s  {k:<10} impulse {j:6.2f} N s  approach {v:4.2f} m/s")
    print(
        f"transients {len(trace.transients.time)} wheel hits "
        f"({', '.join(sorted(set(trace.transients.kind))) or 'none'})"
    )
    if trace.faults:
        for f in trace.faults:
            wheel = trace.robot.wheel_names[f.wheel]
            print(
                f"fault      {f.kind} on {wheel}, severity {f.severity:.2f}, from {f.onset:.1f} s for "
                f"{f.duration:.1f} s, order {f.defect_order:.2f}/rev, resonance {f.resonance_hz:.0f} Hz"
            )
    else:
        print("faults     none")
    share = np.bincount(trace.label, minlength=3) / max(len(trace.label), 1)
    print(f"labels     normal {share[0]:.1%}, collision {share[1]:.1%}, mechanical {share[2]:.1%}")
    print(f"wrote {path}")
    return 0


COMMAND = Command(
    name="simulate",
    help="simulate one scenario (preset or TOML) and write its trace (.npz) with a summary",
    add_arguments=_add_arguments,
    run=_run,
    example=(
        "msvdd-bench simulate --scenario collision_wall --scenario-seed 0 --out /tmp/collision.npz\n"
        "msvdd-bench simulate --scenario assets/scenarios/fault_bearing.toml --out /tmp/bearing.npz"
    ),
)
