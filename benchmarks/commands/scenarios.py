"""`msvdd-bench scenarios`: presets, obstacle kinds, fault kinds and their parameters."""

from __future__ import annotations

import argparse

from benchmarks.command import Command
from benchmarks.errors import check_seed


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--scenario-seed",
        type=int,
        default=0,
        help="scenario seed each preset is drawn with for this listing (as `simulate --scenario-seed`)",
    )


def _run(args: argparse.Namespace) -> int:
    import sim
    from sim import faults, vocab
    from sim.robot import DRIVE_TRAINS
    from sim.scenario import OBSTACLE_MASS, OBSTACLE_SIZES
    from sim.vocab import TRANSIENT_HEIGHT
    from sim.world import SURFACES

    seed = check_seed(args.scenario_seed, "--scenario-seed")
    usage = "msvdd-bench simulate --scenario NAME --scenario-seed N --out T.npz"
    print(f"presets (scenario seed {seed}; `{usage}`):")
    for name, factory in sim.scenario_presets().items():
        sc = factory(seed)
        extra = ""
        if sc.faults:
            f = sc.faults[0]
            wheel = sc.wheel_names[f.wheel]
            extra = f" fault {f.kind} wheel {wheel} severity {f.severity:.2f} onset {f.onset:.1f} s"
        print(
            f"  {name:<26} {sc.category:<9} {sc.environment:<7} {sc.surface:<8} {sc.robot.model} "
            f"{sc.duration:.0f} s, {len(sc.obstacles)} obstacles, {len(sc.transients)} transients{extra}"
        )
    print("obstacle kinds (material, half-extents m, fixed or free mass):")
    for kind in vocab.OBSTACLE_KINDS:
        size = " x ".join(f"{s:.2f}" for s in OBSTACLE_SIZES[kind])
        mass = (
            f"free {OBSTACLE_MASS[kind]:.0f} kg"
            if kind in OBSTACLE_MASS
            else ("moving (mocap)" if kind == "pedestrian" else "fixed")
        )
        print(f"  {kind:<11} {vocab.OBSTACLE_MATERIAL[kind]:<13} {size:<18} {mass}")
    robot = sim.scenario.Unit()
    from sim.robot import build_robot

    info = build_robot(robot).info
    print("fault kinds (severity 0..1, wheel, onset, duration):")
    for kind in vocab.FAULT_KINDS:
        f0, zeta = faults.RESONANCE[kind]
        order = faults.defect_order(kind, info)
        print(f"  {kind:<18} defect order {order:7.2f}/rev  resonance {f0:6.0f} Hz  damping {zeta:.2f}")
    print(
        f"  (bearing: {faults.BEARING_BALLS} balls, d={faults.BEARING_BALL_DIAMETER * 1e3:.2f} mm, "
        f"D={faults.BEARING_PITCH_DIAMETER * 1e3:.1f} mm, BPFO order {faults.bpfo_order():.3f})"
    )
    print("surfaces (friction, roughness rms m):")
    for name, s in SURFACES.items():
        print(f"  {name:<9} {s.friction:.2f}  {s.roughness:.3f}")
    print("transient kinds (height m): " + ", ".join(f"{k} {h:.3f}" for k, h in TRANSIENT_HEIGHT.items()))
    print(
        "robots: "
        + ", ".join(
            f"{k} (r={d.wheel_radius} m, track {d.track} m, gear {d.gear_ratio})"
            for k, d in DRIVE_TRAINS.items()
        )
    )
    return 0


COMMAND = Command(
    name="scenarios",
    help="list scenario presets, obstacle kinds, fault kinds and their parameters",
    add_arguments=_add_arguments,
    run=_run,
    example="msvdd-bench scenarios --scenario-seed 3",
)
