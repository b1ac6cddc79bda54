"""Physical levels at the robot's microphones: its drive, collisions, benign bumps, measured on simulations.

Every level is dB SPL at the microphones (`AudioConfig`: 0 dBFS = 120 dB SPL; the unit's reference drive
is 68 dB SPL), measured on the stems of a real simulated drive (robot-only stems: no ambience, no room,
no microphone noise):

- the healthy drive on tile at a cruise speed: RMS and peak over 2 s of steady cruise;
- a collision: the robot drives straight into an obstacle at a cruise speed (a wall, a desk, a box, a
  pedestrian...); the peak of the impacts stem over the 0.5 s after the first contact;
- a benign bump: the robot drives over a floor feature laid across its path; the peak of the transients
  stem over 0.5 s from the first wheel's crossing.

The criteria the tests hold (`test_levels.py`): a wheel crossing a 15 mm threshold at 1.3 m/s is a clear
clack (its peak at least 15 dB over the drive's RMS and 6 dB over the drive's own peaks at that speed);
a soft body (a pedestrian) is quieter than a rigid wall met at the same speed; a collision's level
follows its impulse (`synth_audio.impacts`).

`.venv/bin/python tests/synth_audio/level_kit.py` prints the table.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from sim import Trace, simulate
from sim.scenario import OBSTACLE_SIZES, Obstacle, Reflex, Route, Scenario, Transient, Unit, Waypoint
from synth_audio import AudioConfig, render

RATE = 44100
"""Audio sample rate, Hz."""
CONFIG = AudioConfig(ambience=False, rt60_s=0.0, mic_noise_spl_db=float("-inf"), stems=True)
"""Robot-only stems."""
SPEEDS = (0.3, 0.7, 1.3)
"""Cruise speeds tabulated, m/s."""


def spl(amplitude: float) -> float:
    """dB SPL of a digital amplitude (full scale = 1)."""
    return CONFIG.full_scale_spl_db + 20.0 * math.log10(max(float(amplitude), 1e-12))


def _scenario(speed: float, obstacle: str = "", transient: str = "") -> Scenario:
    obstacles = (Obstacle(obstacle, 0.0, 0.0, 0.0, OBSTACLE_SIZES[obstacle]),) if obstacle else ()
    transients = (Transient(transient, 0.0, 0.0, math.pi / 2, 2.0),) if transient else ()
    run_up = max(1.0, 1.5 * speed)  # at 3 m/s^2 the robot reaches its speed in under 0.5 m
    return Scenario(
        name="levels",
        seed=3,
        duration=run_up / speed + 3.0,
        environment="indoor",
        surface="tile",
        arena=(8.0, 4.0),
        robot=Unit(unit_id=0, variation=0.0),
        route=Route(
            start=(-run_up - 0.6, 0.0, 0.0),
            waypoints=(Waypoint(4.0, 0.0, speed, ram=0 if obstacle else -1),),
            accel=3.0,
            loop=False,
            reflex=Reflex(kind="wait", wait=10.0),
        ),
        obstacles=obstacles,
        transients=transients,
    )


@functools.cache
def _run(speed: float, obstacle: str = "", transient: str = "") -> tuple[Trace, dict[str, np.ndarray]]:
    trace = simulate(_scenario(speed, obstacle, transient))
    stems = render(trace, CONFIG, seed=1).stems
    return trace, {k: v.astype(np.float64) for k, v in stems.items()}


def drive_level(speed: float) -> tuple[float, float]:
    """(RMS, peak) dB SPL of the healthy drive (motor, rolling, electronics) over 2 s of cruise."""
    _, stems = _run(speed)
    drive = stems["motor"] + stems["rolling"] + stems["electronics"]
    t0 = 0.6 + max(1.0, 1.5 * speed) * 0.5 / speed
    part = drive[int(t0 * RATE) : int((t0 + 2.0) * RATE)]
    return spl(float(np.sqrt(np.mean(part**2)))), spl(float(np.abs(part).max()))


def hit_level(obstacle: str, speed: float) -> float:
    """Peak dB SPL of the impacts stem when the robot drives into `obstacle` at `speed`."""
    trace, stems = _run(speed, obstacle=obstacle)
    if len(trace.contacts.time) == 0:
        raise RuntimeError(f"no contact with {obstacle} at {speed} m/s")
    i0 = int(float(trace.contacts.time[0]) * RATE)
    return spl(float(np.abs(stems["impacts"][i0 : i0 + RATE // 2]).max()))


def bump_level(kind: str, speed: float) -> float:
    """Peak dB SPL of the transients stem when the robot drives over a `kind` at `speed`."""
    trace, stems = _run(speed, transient=kind)
    if len(trace.transients.time) == 0:
        raise RuntimeError(f"no wheel met the {kind} at {speed} m/s")
    i0 = int(float(trace.transients.time[0]) * RATE)
    return spl(float(np.abs(stems["transients"][i0 : i0 + RATE // 2]).max()))


def main() -> None:
    """Print the table."""
    print("speed m/s        " + "".join(f"{v:>9.1f}" for v in SPEEDS))
    rows = [("drive RMS", lambda v: drive_level(v)[0]), ("drive peak", lambda v: drive_level(v)[1])]
    rows += [(f"hit {k}", functools.partial(hit_level, k)) for k in
             ("wall", "door", "desk", "chair", "box", "luggage", "pedestrian")]  # fmt: skip
    bumps = ("threshold", "cable", "seam", "kerb_ramp")
    rows += [(f"bump {k}", functools.partial(bump_level, k)) for k in bumps]
    for name, f in rows:
        print(f"{name:<17}" + "".join(f"{f(v):>9.1f}" for v in SPEEDS))


if __name__ == "__main__":
    main()
