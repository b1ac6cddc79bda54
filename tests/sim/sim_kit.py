"""Helpers for the simulator tests: short, straight, deterministic scenarios."""

from __future__ import annotations

from sim.scenario import Fault, Obstacle, Route, Scenario, Unit, Waypoint


def straight(
    duration: float = 6.0,
    speed: float = 1.0,
    faults: tuple[Fault, ...] = (),
    model: str = "skid4",
    obstacles: tuple[Obstacle, ...] = (),
    seed: int = 3,
) -> Scenario:
    """A robot driving along +x at `speed` in a long indoor arena (no transients, nominal unit)."""
    return Scenario(
        name="straight",
        seed=seed,
        duration=duration,
        environment="indoor",
        surface="tile",
        arena=(12.0, 4.0),
        robot=Unit(model=model, unit_id=0, variation=0.0),
        route=Route(start=(-10.0, 0.0, 0.0), waypoints=(Waypoint(11.0, 0.0, speed),), accel=1.0, loop=False),
        obstacles=obstacles,
        faults=faults,
    )
