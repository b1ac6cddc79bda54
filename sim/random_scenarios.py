"""Randomised, valid scenarios (nominal, collision, fault) and the named presets built on them.

Everything is drawn from one `np.random.Generator` seeded by the caller's seed, so the same arguments
give the same scenario. Routes wander inside the arena through free space (checked against every
obstacle with a clearance margin) and loop, so long episodes keep driving sensibly; every category gets
the same manoeuvres (emergency stops, back-outs, near misses) and a drawn reflex; benign transients are
laid across the route's legs so that nominal driving meets them.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numba import njit

from sim import vocab
from sim.scenario import (
    MAX_WHEEL_SPEED,
    OBSTACLE_SIZES,
    Fault,
    Obstacle,
    Reflex,
    Route,
    Scenario,
    ScenarioError,
    Transient,
    Unit,
    Waypoint,
    wheel_names,
)

CATEGORIES: tuple[str, ...] = ("nominal", "collision", "fault")
"""Scenario categories of `draw_scenario`."""

MAX_LEG = 4.5
"""Longest leg of a wandering route, m (shorter legs mean more turns)."""

CLEARANCE = 0.75
"""Free space kept between a nominal route and any obstacle, m."""

_CLUTTER = {
    "indoor": ("desk", "chair", "box", "luggage", "door", "wall"),
    "outdoor": ("curb", "box", "luggage", "wall", "chair"),
}
OBSTACLE_ENVIRONMENTS: dict[str, tuple[str, ...]] = {
    "door": ("indoor",),
    "desk": ("indoor",),
    "curb": ("outdoor",),
}
"""Where an obstacle kind belongs when it is not everywhere (doors and desks indoors, curbs outdoors)."""
_TRANSIENTS = {
    "indoor": ("seam", "threshold", "cable", "debris"),
    "outdoor": ("seam", "kerb_ramp", "cable", "debris"),
}


@njit(cache=True, nogil=True)
def _nearest_box(points: np.ndarray, boxes: np.ndarray) -> float:  # pragma: no cover - compiled
    """Smallest distance from points (n, 2) to footprints (K, 6: centre x, y, cos and sin of the yaw, half
    length, half width: rotated rectangles), inf without either; element by element the arithmetic numpy
    did over the (n, K) array before (the scenario sampler's hottest loop: thousands of calls of a few
    points each, which numpy spent in call overhead)."""
    best = math.inf
    for i in range(points.shape[0]):
        px, py = points[i, 0], points[i, 1]
        for k in range(boxes.shape[0]):
            rel_x = px - boxes[k, 0]
            rel_y = py - boxes[k, 1]
            c, s = boxes[k, 2], boxes[k, 3]
            excess_x = max(abs(rel_x * c + rel_y * s) - boxes[k, 4], 0.0)
            excess_y = max(abs(-rel_x * s + rel_y * c) - boxes[k, 5], 0.0)
            best = min(best, math.sqrt(excess_x * excess_x + excess_y * excess_y))
    return best


@njit(cache=True, nogil=True)
def _nearest_point(points: np.ndarray, others: np.ndarray) -> float:  # pragma: no cover - compiled
    """Smallest distance between points (n, 2) and points (m, 2), inf without either (numpy's
    `norm(points[:, None] - others, axis=-1).min()`, the same arithmetic element by element)."""
    best = math.inf
    for i in range(points.shape[0]):
        for j in range(others.shape[0]):
            dx = points[i, 0] - others[j, 0]
            dy = points[i, 1] - others[j, 1]
            best = min(best, math.sqrt(dx * dx + dy * dy))
    return best


_FOOTPRINTS_KEPT = 256
"""Lists of obstacles whose footprints `_footprints` keeps (the sampler asks about a few lists, often)."""
_Walked = list[tuple[np.ndarray, float]]
"""Pedestrians' walked points (m, 2) and radii."""
_footprints_made: dict[tuple[int, ...], tuple[list[Obstacle], np.ndarray, _Walked]] = {}
_footprints_lock = threading.Lock()


def _footprints(obstacles: list[Obstacle]) -> tuple[np.ndarray, _Walked]:
    """The obstacles' footprints as `_nearest_box` reads them (K, 6), and each pedestrian's walked points
    (its path's waypoints, and the line from its start to the last one every 0.2 m) with its radius.

    Made once per list of obstacle objects and kept (`_FOOTPRINTS_KEPT` lists, the oldest dropped first),
    keyed by the objects' identities: an entry holds its objects, so no other object takes their identity
    while it is kept. Obstacles are frozen; a list that changes is another key."""
    key = tuple(map(id, obstacles))
    made = _footprints_made.get(key)  # one dictionary lookup: atomic; the lock orders the writes
    if made is not None:
        return made[1], made[2]
    boxes = np.array(
        [(ob.x, ob.y, math.cos(ob.yaw), math.sin(ob.yaw), ob.size[0], ob.size[1]) for ob in obstacles]
    ).reshape(len(obstacles), 6)
    walked: _Walked = []
    for ob in obstacles:
        if ob.path:
            line = _sample_segment(np.array([ob.x, ob.y]), np.array(ob.path[-1]), 0.2)
            points = np.concatenate([np.array(ob.path, dtype=np.float64).reshape(-1, 2), line])
            walked.append((points, ob.size[0]))
    with _footprints_lock:
        if len(_footprints_made) >= _FOOTPRINTS_KEPT:
            del _footprints_made[next(iter(_footprints_made))]
        _footprints_made[key] = (list(obstacles), boxes, walked)
    return boxes, walked


def _clearance(points: np.ndarray, obstacles: list[Obstacle]) -> float:
    """Smallest distance from any of `points` (n, 2) to any obstacle (pedestrian paths included)."""
    if not obstacles:
        return math.inf
    boxes, walked = _footprints(obstacles)
    points = np.asarray(points, dtype=np.float64)
    best = _nearest_box(points, boxes)
    for path, radius in walked:
        best = min(best, _nearest_point(points, path) - radius)
    return best


def _length(d: np.ndarray) -> float:
    """Length of a vector: `np.linalg.norm`'s sqrt(d . d), without its argument checks (the sampler measures
    tens of thousands of 2-vectors)."""
    return math.sqrt(d.dot(d))


def _sample_segment(a: np.ndarray, b: np.ndarray, step: float) -> np.ndarray:
    """Points from a to b (2-vectors) at most `step` apart, both ends included."""
    d = b - a
    n = max(2, math.ceil(_length(d) / step) + 1)
    return np.asarray(a + _unit_steps(n) * d)


@functools.lru_cache(maxsize=1024)
def _unit_steps(n: int) -> np.ndarray:
    """(n, 1) read-only `np.linspace(0, 1, n)`, made once per n (the route sampler asks for few n, often)."""
    u = np.linspace(0.0, 1.0, n)[:, None]
    u.flags.writeable = False
    return u


def _segment_clear(a: np.ndarray, b: np.ndarray, obstacles: list[Obstacle], margin: float) -> bool:
    return _clearance(_sample_segment(a, b, 0.1), obstacles) > margin


@dataclass(frozen=True)
class ScenarioOptions:
    """What `draw_scenario` draws a scenario with, besides its seed and category (None: drawn)."""

    duration: float
    """Episode length, s (2 .. 3600)."""
    environment: str | None = None
    """`indoor` or `outdoor`; None: drawn among the obstacle kind's environments (`OBSTACLE_ENVIRONMENTS`)."""
    obstacle_kind: str | None = None
    """Obstacle kind a collision episode hits (`sim.vocab.OBSTACLE_KINDS`); None: drawn."""
    fault_kind: str | None = None
    """Fault kind of a fault episode (`sim.vocab.FAULT_KINDS`); None: drawn."""
    wheel: int | None = None
    """Faulty wheel of a fault episode; None: drawn."""
    severity: tuple[float, float] = (0.3, 1.0)
    """(low, high) range the fault severity is drawn from, 0 .. 1."""
    unit_id: int | None = None
    """Robot unit; None: drawn among 0 .. 7."""
    transient_density: float = 1.0
    """Benign transients per 8 s of driving (0 = none, at most 10)."""
    robot_model: str = "skid4"
    """`skid4` or `diff2`."""
    surface: str | None = None
    """Floor surface, one of the environment's (`sim.vocab.INDOOR_SURFACES`, `OUTDOOR_SURFACES`; needs an
    `environment`); None: drawn."""


def _check_options(seed: int, category: str, options: ScenarioOptions) -> None:
    """Raise ScenarioError naming the first argument that is invalid (before anything is drawn)."""

    def bad(name: str, value: object, allowed: str) -> ScenarioError:
        return ScenarioError(f"{name} = {value!r} is invalid; allowed: {allowed}")

    o = options
    if category not in CATEGORIES:
        raise bad("category", category, ", ".join(CATEGORIES))
    if not (
        isinstance(o.duration, int | float) and math.isfinite(o.duration) and 2.0 <= o.duration <= 3600.0
    ):
        raise bad("duration", o.duration, "2 .. 3600 s")
    if o.environment is not None and o.environment not in vocab.ENVIRONMENTS:
        raise bad("environment", o.environment, ", ".join(vocab.ENVIRONMENTS))
    if o.obstacle_kind is not None and o.obstacle_kind not in vocab.OBSTACLE_KINDS:
        raise bad("obstacle_kind", o.obstacle_kind, ", ".join(vocab.OBSTACLE_KINDS))
    if o.fault_kind is not None and o.fault_kind not in vocab.FAULT_KINDS:
        raise bad("fault_kind", o.fault_kind, ", ".join(vocab.FAULT_KINDS))
    if o.robot_model not in ("skid4", "diff2"):
        raise bad("robot_model", o.robot_model, "skid4, diff2")
    n_wheels = len(wheel_names(o.robot_model))
    if o.wheel is not None and (not isinstance(o.wheel, int) or not 0 <= o.wheel < n_wheels):
        raise bad("wheel", o.wheel, f"0 .. {n_wheels - 1} for {o.robot_model}")
    lo, hi = o.severity
    if not (0.0 <= lo <= hi <= 1.0):
        raise bad("severity", o.severity, "(low, high) with 0 <= low <= high <= 1")
    if not (math.isfinite(o.transient_density) and 0.0 <= o.transient_density <= 10.0):
        raise bad("transient_density", o.transient_density, "0 .. 10")
    _check_surface(o.surface, o.environment)
    if not isinstance(seed, int) or seed < 0:
        raise ScenarioError(f"seed = {seed!r} is invalid; allowed: an integer >= 0")


def _check_surface(surface: str | None, environment: str | None) -> None:
    """Refuse a surface given without an environment, or not of its environment."""
    if surface is None:
        return
    if environment is None:
        raise ScenarioError(f"surface = {surface!r} needs an environment; allowed: indoor, outdoor")
    allowed = vocab.INDOOR_SURFACES if environment == "indoor" else vocab.OUTDOOR_SURFACES
    if surface not in allowed:
        raise ScenarioError(
            f"surface = {surface!r} is invalid for environment {environment!r}; allowed: {', '.join(allowed)}"
        )


def draw_scenario(seed: int, category: str, options: ScenarioOptions) -> Scenario:
    """A valid randomised scenario of a category drawn with `options`; every draw depends only on the
    arguments.

    Args:
        seed: seed of every draw (also the scenario's seed).
        category: `nominal` (a route with turns, stops, back-outs, emergency stops, near misses and benign
            transients), `collision` (the same driving, whose first leg meets an unseen obstacle of
            `options.obstacle_kind`), or `fault` (the same driving with one fault of `options.fault_kind`
            whose onset is inside the episode).
        options: the episode's length and what is given rather than drawn (`ScenarioOptions`).

    The draws come in a fixed order from one generator seeded by the seed and category: the setting
    (obstacle kind, environment, surface, arena, unit), the obstacles, the route and the robot's driving,
    the transients, then the fault.
    """
    _check_options(seed, category, options)
    rng = np.random.default_rng([seed, CATEGORIES.index(category), 0x5CE])
    setting = _draw_setting(rng, category, options)
    obstacles = _draw_obstacles(rng, category, setting)
    waypoints, start = _route_with_retries(rng, category, obstacles, setting.arena, options.duration)
    route = Route(
        start=start,
        waypoints=tuple(waypoints),
        accel=float(rng.uniform(0.5, 1.2)),
        yaw_rate=float(rng.uniform(0.8, 1.5)),
        loop=True,
        reflex=_reflex(rng),
    )
    transients = _transients(
        rng, setting.environment, setting.arena, start, waypoints, options.duration, options.transient_density
    )
    faults = _draw_faults(rng, category, options)
    return Scenario(
        name=_scenario_name(category, setting, faults),
        seed=seed,
        duration=float(options.duration),
        environment=setting.environment,
        surface=setting.surface,
        arena=setting.arena,
        robot=setting.unit,
        route=route,
        obstacles=tuple(obstacles),
        transients=transients,
        faults=faults,
        category=category,
    )


@dataclass(frozen=True)
class _Setting:
    """Where a scenario happens and with which robot: drawn first, before any obstacle."""

    obstacle_kind: str | None
    """The obstacle a collision episode hits (None for the other categories unless given)."""
    environment: str
    """`indoor` or `outdoor`."""
    surface: str
    """Floor surface."""
    arena: tuple[float, float]
    """Half extents of the arena, m."""
    unit: Unit
    """The robot."""


def _draw_setting(rng: np.random.Generator, category: str, options: ScenarioOptions) -> _Setting:
    """Draw what the options leave open of the obstacle kind, environment, surface and unit, and the arena."""
    obstacle_kind = options.obstacle_kind
    if category == "collision" and obstacle_kind is None:
        obstacle_kind = str(rng.choice(vocab.OBSTACLE_KINDS))
    where = OBSTACLE_ENVIRONMENTS.get(obstacle_kind or "", vocab.ENVIRONMENTS)
    environment = options.environment
    if environment is None:
        environment = str(rng.choice(where))
    elif category == "collision" and environment not in where:
        raise ScenarioError(
            f"environment = {environment!r} is invalid for obstacle_kind {obstacle_kind!r}; "
            f"allowed: {', '.join(where)}"
        )
    surfaces = vocab.INDOOR_SURFACES if environment == "indoor" else vocab.OUTDOOR_SURFACES
    drawn = str(rng.choice(surfaces))  # drawn even when given, so the other draws stay the same
    if environment == "indoor":
        arena = (float(rng.uniform(5.0, 7.5)), float(rng.uniform(4.0, 5.5)))
    else:
        arena = (float(rng.uniform(8.0, 12.0)), float(rng.uniform(6.5, 9.0)))
    unit_id = int(rng.integers(0, 8)) if options.unit_id is None else options.unit_id
    return _Setting(
        obstacle_kind=obstacle_kind,
        environment=environment,
        surface=drawn if options.surface is None else options.surface,
        arena=arena,
        unit=Unit(model=options.robot_model, unit_id=unit_id),
    )


def _draw_obstacles(rng: np.random.Generator, category: str, setting: _Setting) -> list[Obstacle]:
    """A collision episode's target (obstacle 0), then 3-6 pieces of the environment's clutter (those
    that fit)."""
    obstacles: list[Obstacle] = []
    if category == "collision":
        assert setting.obstacle_kind is not None
        _place(rng, setting.obstacle_kind, setting.arena, obstacles, target=True)
        if not obstacles:
            raise ScenarioError(
                f"obstacle_kind = {setting.obstacle_kind!r}: could not be placed in the arena {setting.arena}"
            )
    for kind in rng.choice(_CLUTTER[setting.environment], size=int(rng.integers(3, 7))):
        _place(rng, str(kind), setting.arena, obstacles, target=False)
    return obstacles


def _route_with_retries(
    rng: np.random.Generator,
    category: str,
    obstacles: list[Obstacle],
    arena: tuple[float, float],
    duration: float,
) -> tuple[list[Waypoint], tuple[float, float, float]]:
    """`_route`, dropping the last clutter obstacle from `obstacles` (in place) and drawing again while
    the arena is too crowded for a route."""
    for _ in range(8):
        try:
            return _route(rng, category, obstacles, arena, duration)
        except ScenarioError:
            if len(obstacles) <= (1 if category == "collision" else 0):
                raise
            obstacles.pop()  # crowded: drop the last clutter obstacle and draw again
    return _route(rng, category, obstacles, arena, duration)


def _draw_faults(rng: np.random.Generator, category: str, options: ScenarioOptions) -> tuple[Fault, ...]:
    """A fault episode's one fault (what the options leave open drawn; onset at 15-50 % of the episode);
    none for the other categories."""
    if category != "fault":
        return ()
    kind = options.fault_kind if options.fault_kind is not None else str(rng.choice(vocab.FAULT_KINDS))
    n_wheels = len(wheel_names(options.robot_model))
    which = options.wheel if options.wheel is not None else int(rng.integers(0, n_wheels))
    sev = float(rng.uniform(options.severity[0], options.severity[1]))
    onset = float(rng.uniform(0.15, 0.5) * options.duration)
    return (Fault(kind=kind, wheel=which, severity=sev, onset=onset),)


def _scenario_name(category: str, setting: _Setting, faults: tuple[Fault, ...]) -> str:
    """`<category>_<environment>`, then the obstacle kind of a collision, or the fault kind and wheel."""
    name = f"{category}_{setting.environment}"
    if category == "collision":
        name += f"_{setting.obstacle_kind}"
    if faults:
        name += f"_{faults[0].kind}_w{faults[0].wheel}"
    return name


def _place(
    rng: np.random.Generator, kind: str, arena: tuple[float, float], obstacles: list[Obstacle], target: bool
) -> None:
    """Place one obstacle of `kind` without overlapping the others (gives up quietly if crowded)."""
    hx, hy = arena
    size = OBSTACLE_SIZES[kind]
    for _ in range(60):
        if kind == "door":
            side = int(rng.integers(0, 4))
            along = float(rng.uniform(-0.6, 0.6))
            if side < 2:
                x = (hx - size[0]) * (1 if side == 0 else -1)
                y = along * (hy - 1.0)
                yaw = 0.0
            else:
                x = along * (hx - 1.0)
                y = (hy - size[0]) * (1 if side == 2 else -1)
                yaw = math.pi / 2
        else:
            margin = max(size[0], size[1]) + 1.6
            x = float(rng.uniform(-hx + margin, hx - margin))
            y = float(rng.uniform(-hy + margin, hy - margin))
            yaw = (
                float(rng.uniform(-math.pi, math.pi)) if kind in ("box", "luggage", "chair", "desk") else 0.0
            )
            if kind in ("wall", "curb"):
                yaw = float(rng.choice([0.0, math.pi / 2]))
        path: tuple[tuple[float, float], ...] = ()
        walk = 1.0
        if kind == "pedestrian":
            heading = float(rng.uniform(-math.pi, math.pi))
            length = float(rng.uniform(1.5, 3.0))
            end = (x + length * math.cos(heading), y + length * math.sin(heading))
            if abs(end[0]) > hx - 1.0 or abs(end[1]) > hy - 1.0:
                continue
            path = (end,)
            walk = float(rng.uniform(0.3, 0.8))
        candidate = Obstacle(kind, x, y, yaw, size, path, walk)
        probe = _sample_segment(np.array([x, y]), np.array(path[-1] if path else (x, y)), 0.2)
        spacing = 1.9 if target else 1.4
        if obstacles and _clearance(probe, obstacles) < spacing + max(size[:2]):
            continue
        obstacles.append(candidate)
        return


def _free_point(
    rng: np.random.Generator, arena: tuple[float, float], obstacles: list[Obstacle], margin: float = 0.9
) -> np.ndarray | None:
    hx, hy = arena
    for _ in range(80):
        p = np.array([rng.uniform(-hx + margin, hx - margin), rng.uniform(-hy + margin, hy - margin)])
        if _clearance(p[None], obstacles) > CLEARANCE + 0.1:
            return p
    return None


BACK_OUT_SHARE = 0.3
"""Share of route waypoints the robot leaves by backing out (reversing 0.6-1.5 m) before driving on."""
ESTOP_SHARE = 0.12
"""Share of legs on which the robot makes an emergency stop (braking at the torque limit) midway."""
NEAR_MISS_EVERY = 10.0
"""Mean driving time between near misses (legs at an obstacle that the safety field stops short), s."""
BRAKE_DECEL = 3.0
"""Deceleration a safety stop is planned with, m/s^2 (the robot brakes harder: it stops short)."""
SETTLE_S = 2.0
"""The first seconds of an episode, in which the robot leaves its start: datasets cut no window from them
(an episode's first window finds the robot under way, whatever the category)."""
FIRST_HIT = (0.05, 0.3)
"""Range of the planned time of a collision episode's first hit after `SETTLE_S`, as fractions of its
duration."""
REFLEX_WEIGHTS: dict[str, float] = {"reverse": 0.4, "wait": 0.25, "push": 0.2, "continue": 0.15}
"""How often each reflex is drawn (every category draws one: nominal near misses use it too)."""


def _reflex(rng: np.random.Generator) -> Reflex:
    """A robot's reflex after a contact or a safety stop, drawn with `REFLEX_WEIGHTS`."""
    kinds = list(REFLEX_WEIGHTS)
    kind = str(rng.choice(kinds, p=np.array([REFLEX_WEIGHTS[k] for k in kinds])))
    return Reflex(
        kind=kind,
        delay=float(rng.uniform(0.0, 0.3)),
        wait=float(rng.uniform(0.0, 1.5)),
        reverse_time=float(rng.uniform(0.4, 1.5)),
        reverse_speed=float(rng.uniform(0.15, 0.35)),
        push_time=float(rng.uniform(0.3, 2.5)) if kind == "push" else 0.0,
    )


def _leg_speed(rng: np.random.Generator) -> float:
    """Cruise speed of a leg, m/s (every leg, nominal or driving at an obstacle, draws from this)."""
    return float(rng.uniform(0.3, 1.4))


DWELL_SHARE = 0.45
"""Share of waypoints the robot stops at (waiting for people, at doors, at its tasks), for 0.5-4 s."""


def _dwell(rng: np.random.Generator) -> float:
    """Stop at a waypoint: `DWELL_SHARE` of them, 0.5-4 s."""
    return float(rng.uniform(0.5, 4.0)) if rng.random() < DWELL_SHARE else 0.0


def _route(
    rng: np.random.Generator,
    category: str,
    obstacles: list[Obstacle],
    arena: tuple[float, float],
    duration: float,
) -> tuple[list[Waypoint], tuple[float, float, float]]:
    """The episode's waypoints and start pose: the same wandering route with the same manoeuvres in
    every category; a collision episode's route starts with a leg that drives at obstacle 0 without
    seeing it (the start is drawn so that the hit comes at `FIRST_HIT` of the episode)."""
    if category != "collision":
        waypoints, start = _wander(rng, arena, obstacles, duration)
        return _decorate(rng, waypoints, start, obstacles, arena, duration), start
    hx, hy = arena
    for _ in range(200):
        legs = _legs_at(rng, obstacles[0], 0, obstacles[1:], arena, hit=True)
        if legs is None:
            continue
        approach = np.array([legs[0].x, legs[0].y])
        aim = np.array([legs[1].x, legs[1].y])
        if _clearance(approach[None], obstacles) < 0.6:
            continue
        first = SETTLE_S + rng.uniform(*FIRST_HIT) * duration
        reach = float(np.clip(legs[0].speed * first, 1.2, MAX_LEG))
        along = math.atan2(aim[1] - approach[1], aim[0] - approach[0])
        for _ in range(30):
            angle = along + float(rng.uniform(-1.0, 1.0))
            begin = approach - reach * np.array([math.cos(angle), math.sin(angle)])
            if abs(begin[0]) > hx - 0.8 or abs(begin[1]) > hy - 0.8:
                continue
            if _clearance(begin[None], obstacles) > CLEARANCE and _segment_clear(
                begin, approach, obstacles, 0.6
            ):
                break
        else:
            continue
        stand = aim + (approach - aim) * min(1.0, 0.9 / max(_length(approach - aim), 1e-9))
        try:
            rest, _ = _wander(rng, arena, obstacles, duration, begin=stand)
        except ScenarioError:
            continue
        heading = math.atan2(approach[1] - begin[1], approach[0] - begin[0])
        start = (float(begin[0]), float(begin[1]), heading + float(rng.uniform(-0.3, 0.3)))
        after = (float(stand[0]), float(stand[1]), along + math.pi)
        waypoints = legs + _decorate(rng, rest, after, obstacles, arena, duration)
        n_more = min(2, int(duration // 60.0))
        if n_more:
            waypoints = _insert_legs_at_obstacles(
                rng, waypoints, obstacles, arena, n_more, start, duration, target=0
            )
        return waypoints, start
    raise ScenarioError(
        f"obstacle_kind = {obstacles[0].kind!r}: no clear approach found in this arena; try another seed"
    )


def _decorate(
    rng: np.random.Generator,
    waypoints: list[Waypoint],
    start: tuple[float, float, float],
    obstacles: list[Obstacle],
    arena: tuple[float, float],
    duration: float,
) -> list[Waypoint]:
    """A route with the manoeuvres of nominal driving: emergency stops, back-outs and near misses."""
    out = _manoeuvres(rng, start, waypoints, obstacles, arena)
    n_near = int(rng.poisson(duration / NEAR_MISS_EVERY))
    if n_near:
        out = _insert_legs_at_obstacles(rng, out, obstacles, arena, n_near, start, duration)
    return out


def _wander(
    rng: np.random.Generator,
    arena: tuple[float, float],
    obstacles: list[Obstacle],
    duration: float,
    begin: np.ndarray | None = None,
) -> tuple[list[Waypoint], tuple[float, float, float]]:
    """A looping route through free space long enough for `duration` (from `begin` when given)."""
    start = begin if begin is not None else _free_point(rng, arena, obstacles)
    if start is None:
        raise ScenarioError("arena too crowded: no free start point (reduce obstacles)")
    # The first leg may leave a point closer to an obstacle than CLEARANCE (where a hit left the robot).
    first_margin = min(CLEARANCE, _clearance(start[None], obstacles) - 0.05)
    points = [start]
    waypoints: list[Waypoint] = []
    planned = 0.0
    attempts = 0
    while (
        planned < duration + 10.0 or not _segment_clear(points[-1], start, obstacles, CLEARANCE)
    ) and attempts < 600:
        attempts += 1
        p = _free_point(rng, arena, obstacles)
        if p is None or not 1.2 <= _length(p - points[-1]) <= MAX_LEG:
            continue
        if not _segment_clear(points[-1], p, obstacles, CLEARANCE if len(points) > 1 else first_margin):
            continue
        speed = _leg_speed(rng)
        dwell = _dwell(rng)
        waypoints.append(Waypoint(float(p[0]), float(p[1]), speed, dwell))
        planned += _length(p - points[-1]) / speed + dwell + 1.5
        points.append(p)
        if len(waypoints) > 400:
            break
    if not waypoints:
        raise ScenarioError("arena too crowded: no route found (reduce obstacles)")
    if not _segment_clear(points[-1], start, obstacles, CLEARANCE):
        waypoints.append(Waypoint(float(points[-2][0]), float(points[-2][1]), 0.6, 0.0))
        for q in reversed(points[1:-2]):
            waypoints.append(Waypoint(float(q[0]), float(q[1]), 0.8, 0.0))
    yaw = math.atan2(points[1][1] - start[1], points[1][0] - start[0]) if len(points) > 1 else 0.0
    return waypoints, (float(start[0]), float(start[1]), yaw + float(rng.uniform(-0.5, 0.5)))


def _manoeuvres(
    rng: np.random.Generator,
    start: tuple[float, float, float],
    waypoints: list[Waypoint],
    obstacles: list[Obstacle],
    arena: tuple[float, float],
) -> list[Waypoint]:
    """Emergency stops midway along some legs and back-outs (a reversing leg) after some waypoints."""
    hx, hy = arena
    out: list[Waypoint] = []
    here = np.array(start[:2])
    for i, wp in enumerate(waypoints):
        there = np.array([wp.x, wp.y])
        nxt = waypoints[(i + 1) % len(waypoints)]
        if wp.ram >= 0 or nxt.ram >= 0:  # legs at an obstacle and their approach stay as planned
            out.append(wp)
            here = there
            continue
        if rng.random() < ESTOP_SHARE and _length(there - here) > 1.5:
            mid = here + float(rng.uniform(0.3, 0.7)) * (there - here)
            out.append(
                Waypoint(float(mid[0]), float(mid[1]), wp.speed, float(rng.uniform(0.3, 3.0)), hard_stop=True)
            )
        out.append(wp)
        if rng.random() < BACK_OUT_SHARE:
            heading = math.atan2(there[1] - here[1], there[0] - here[0]) + math.pi
            for _ in range(6):
                angle = heading + float(rng.uniform(-0.6, 0.6))
                back = there + float(rng.uniform(0.6, 1.5)) * np.array([math.cos(angle), math.sin(angle)])
                inside = abs(back[0]) <= hx - 0.6 and abs(back[1]) <= hy - 0.6
                if (
                    inside
                    and _segment_clear(there, back, obstacles, 0.5)
                    and _segment_clear(back, np.array([nxt.x, nxt.y]), obstacles, 0.5)
                ):
                    out.append(
                        Waypoint(
                            float(back[0]),
                            float(back[1]),
                            float(rng.uniform(0.2, 0.5)),
                            _dwell(rng),
                            reverse=True,
                        )
                    )
                    break
        here = there
    return out


def _insert_legs_at_obstacles(
    rng: np.random.Generator,
    waypoints: list[Waypoint],
    obstacles: list[Obstacle],
    arena: tuple[float, float],
    count: int,
    start: tuple[float, float, float],
    duration: float,
    target: int | None = None,
) -> list[Waypoint]:
    """Insert `count` legs that drive at an obstacle: near misses (any obstacle, stopped short by the
    safety field) or, with `target`, hits on that obstacle (not seen: stop_short 0).

    The legs go in at planned times drawn over the episode. Each is an approach point (an ordinary
    waypoint) and the leg at the obstacle; after the reflex the robot drives on to the route's next
    waypoint.
    """
    out = list(waypoints)
    pts = np.array([(start[0], start[1])] + [(w.x, w.y) for w in out])
    leg_time = 1.8 * np.linalg.norm(np.diff(pts, axis=0), axis=1) / np.array([max(w.speed, 0.1) for w in out])
    arrive = np.concatenate([[0.0], np.cumsum(leg_time + np.array([w.dwell for w in out]) + 2.5)])
    wanted = np.sort(rng.uniform(0.05, 0.85, size=count)) * duration
    inserted: list[tuple[int, list[Waypoint]]] = []
    used: set[int] = set()
    for t in wanted:
        slot0 = max(0, int(np.searchsorted(arrive, t)) - 1)
        for slot in range(slot0, len(pts) - 1):
            if slot in used or out[slot].reverse or out[slot].hard_stop or out[slot].ram >= 0:
                continue
            which = (
                target if target is not None else int(rng.integers(0, len(obstacles))) if obstacles else -1
            )
            if which < 0:
                break
            legs = _try_leg_at(rng, pts[slot], pts[slot + 1], obstacles, which, arena, hit=target is not None)
            if legs is not None:
                inserted.append((slot, legs))
                used.add(slot)
                break
    for slot, legs in sorted(inserted, key=lambda x: -x[0]):
        out[slot:slot] = legs
    return out


def _try_leg_at(
    rng: np.random.Generator,
    prev: np.ndarray,
    nxt: np.ndarray,
    obstacles: list[Obstacle],
    which: int,
    arena: tuple[float, float],
    hit: bool,
) -> list[Waypoint] | None:
    """Approach and obstacle legs between route points prev and nxt whose connecting legs are clear."""
    others = [ob for i, ob in enumerate(obstacles) if i != which]
    for _ in range(15):
        legs = _legs_at(rng, obstacles[which], which, others, arena, hit)
        if legs is None:
            continue
        approach = np.array([legs[0].x, legs[0].y])
        aim = np.array([legs[1].x, legs[1].y])
        # Where the robot stands when the reflex has run: about its length short of the aim point.
        stand = aim + (approach - aim) * min(1.0, 0.9 / max(_length(approach - aim), 1e-9))
        if (
            _length(approach - prev) <= MAX_LEG
            and _segment_clear(prev, approach, obstacles, 0.6)
            and _segment_clear(approach, nxt, obstacles, 0.6)
            and _segment_clear(
                stand, nxt, obstacles if obstacles[which].kind != "pedestrian" else others, 0.35
            )
        ):
            return legs
    return None


def _legs_at(
    rng: np.random.Generator,
    target: Obstacle,
    index: int,
    others: list[Obstacle],
    arena: tuple[float, float],
    hit: bool,
) -> list[Waypoint] | None:
    """An approach point and a leg at a face of `target` (speed and angle drawn like any leg), or None.

    A hit drives 0.4 m past the face; a near miss plans the safety stop so that braking at
    `BRAKE_DECEL` ends 0.05-0.4 m short of the face.
    """
    hx, hy = arena
    speed = _leg_speed(rng)
    angle = float(rng.uniform(-0.7, 0.7))
    run = float(rng.uniform(1.2, 2.5))
    c, s = math.cos(target.yaw), math.sin(target.yaw)
    if target.kind == "pedestrian":
        mid = (
            np.array([target.x, target.y])
            + np.array(target.path[-1] if target.path else (target.x, target.y))
        ) / 2
        heading = float(rng.uniform(-math.pi, math.pi))
        face = mid
        direction = np.array([math.cos(heading), math.sin(heading)])
    else:
        faces = [(1, 0), (-1, 0), (0, 1), (0, -1)]
        fx, fy = faces[int(rng.integers(0, 4))]
        if target.kind == "door":
            # A door stands against a border wall; only its face looking into the arena can be reached.
            if abs(target.yaw) < 1e-9:
                normal_world = np.array([-math.copysign(1.0, target.x), 0.0])
            else:
                normal_world = np.array([0.0, -math.copysign(1.0, target.y)])
            half_n, half_t = target.size[0], target.size[1]
        else:
            normal_world = np.array([fx * c - fy * s, fx * s + fy * c])
            half_n = target.size[0] if fx != 0 else target.size[1]
            half_t = target.size[1] if fx != 0 else target.size[0]
        tangent = np.array([-normal_world[1], normal_world[0]])
        face = (
            np.array([target.x, target.y]) + normal_world * half_n + tangent * rng.uniform(-0.5, 0.5) * half_t
        )
        ca, sa = math.cos(angle), math.sin(angle)
        inward = -normal_world
        direction = np.array([inward[0] * ca - inward[1] * sa, inward[0] * sa + inward[1] * ca])
    approach = face - direction * run
    if abs(approach[0]) > hx - 0.8 or abs(approach[1]) > hy - 0.8:
        return None
    if others and not _segment_clear(approach, face, others, 0.5):
        return None
    aim = face + direction * 0.4
    aim = np.clip(aim, [-hx + 0.31, -hy + 0.31], [hx - 0.31, hy - 0.31])
    stop_short = 0.0 if hit else float(rng.uniform(0.05, 0.4)) + speed**2 / (2.0 * BRAKE_DECEL)
    return [
        Waypoint(float(approach[0]), float(approach[1]), _leg_speed(rng), _dwell(rng)),
        Waypoint(float(aim[0]), float(aim[1]), speed, 0.0, ram=index, stop_short=stop_short),
    ]


MAX_TRANSIENTS = 120
"""Most benign transients laid in one scenario."""
DEBRIS_SPAN = 0.4
"""Width across a leg within which a debris piece counts as met, m (about the robot's track)."""


def _segments_cross(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> bool:
    """Whether segments ab and cd cross (2-D, proper crossing)."""

    def side(p: np.ndarray, q: np.ndarray, r: np.ndarray) -> float:
        return float((q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]))

    return side(a, b, c) * side(a, b, d) < 0 and side(c, d, a) * side(c, d, b) < 0


def _crossings(transient: Transient, legs: list[tuple[np.ndarray, np.ndarray]]) -> int:
    """How many of the route's legs run over a transient (a strip, or debris across the track)."""
    half = (DEBRIS_SPAN if transient.kind == "debris" else transient.length) / 2
    d = np.array([math.cos(transient.yaw), math.sin(transient.yaw)]) * half
    centre = np.array([transient.x, transient.y])
    return sum(_segments_cross(centre - d, centre + d, a, b) for a, b in legs)


def _driven_legs(
    start: tuple[float, float, float], waypoints: list[Waypoint], duration: float
) -> list[tuple[np.ndarray, np.ndarray]]:
    """The route's legs (ram legs left out) that start within the episode, by the planner's timing."""
    legs: list[tuple[np.ndarray, np.ndarray]] = []
    here, t = np.array(start[:2]), 0.0
    for w in waypoints:
        there = np.array([w.x, w.y])
        if t < duration - 1.0 and w.ram < 0:
            legs.append((here, there))
        t += _length(there - here) / w.speed + w.dwell + 1.5
        here = there
    return legs


def _transients(
    rng: np.random.Generator,
    environment: str,
    arena: tuple[float, float],
    start: tuple[float, float, float],
    waypoints: list[Waypoint],
    duration: float,
    density: float,
) -> tuple[Transient, ...]:
    """Benign transients laid across the route's legs (so the wheels roll over them).

    The route meets about `density` transients per 8 s of driving, whatever the episode's length: strips
    are laid until the route's crossings of them (every leg that runs over a strip counts, including legs
    that cross strips laid on other legs) reach `density * duration / 8`. Counting strips instead let a
    long route, crisscrossing a small arena, meet several times more bumps per second than a short one.
    """
    if density <= 0:
        return ()
    hx, hy = arena
    legs = _driven_legs(start, waypoints, duration)
    lengths = np.array([_length(b - a) for a, b in legs])
    usable = lengths > 1.0
    if not usable.any():
        return ()
    weights = np.where(usable, lengths, 0.0)
    weights = weights / weights.sum()
    target = max(2, round(density * duration / 8.0))
    out: list[Transient] = []
    met = 0
    while (met < target or len(out) < 2) and len(out) < MAX_TRANSIENTS:
        i = int(rng.choice(len(legs), p=weights))
        a, b = legs[i]
        u = float(rng.uniform(0.2, 0.8))
        p = a + u * (b - a)
        heading = math.atan2(b[1] - a[1], b[0] - a[0])
        kind = str(rng.choice(_TRANSIENTS[environment]))
        yaw = heading + math.pi / 2 + float(rng.uniform(-0.35, 0.35))
        length = float(rng.uniform(0.9, 2.5))
        # keep the strip's ends inside the arena
        ends = np.abs(np.array([math.cos(yaw), math.sin(yaw)])) * length / 2
        room = np.array([hx - 0.05, hy - 0.05]) - np.abs(p)
        scale = float(np.min(np.where(ends > 0, room / np.maximum(ends, 1e-9), np.inf)))
        length = max(0.3, length * min(1.0, scale))
        transient = Transient(kind, float(p[0]), float(p[1]), float(yaw), length)
        out.append(transient)
        met += max(1, _crossings(transient, legs))
    return tuple(out)


PRESET_DURATION = 40.0
"""Episode length of the named presets, s."""


def scenario_presets() -> dict[str, Callable[[int], Scenario]]:
    """Named scenario factories (name -> factory taking a seed)."""
    presets: dict[str, Callable[[int], Scenario]] = {}

    def make(name: str, category: str, options: ScenarioOptions) -> Callable[[int], Scenario]:
        def factory(seed: int) -> Scenario:
            return draw_scenario(seed, category, options).replace(name=name)

        given = ", ".join(
            f"{f.name}={getattr(options, f.name)}"
            for f in dataclasses.fields(options)
            if f.name != "duration" and getattr(options, f.name) != f.default
        )
        factory.__doc__ = f"Preset {name}: {category} scenario ({given})."
        return factory

    d = PRESET_DURATION
    presets["nominal_indoor"] = make("nominal_indoor", "nominal", ScenarioOptions(d, environment="indoor"))
    presets["nominal_outdoor"] = make("nominal_outdoor", "nominal", ScenarioOptions(d, environment="outdoor"))
    presets["nominal_diff2"] = make(
        "nominal_diff2", "nominal", ScenarioOptions(d, environment="indoor", robot_model="diff2")
    )
    for kind in vocab.OBSTACLE_KINDS:
        presets[f"collision_{kind}"] = make(
            f"collision_{kind}", "collision", ScenarioOptions(d, obstacle_kind=kind)
        )
    for kind in vocab.FAULT_KINDS:
        presets[f"fault_{kind}"] = make(f"fault_{kind}", "fault", ScenarioOptions(d, fault_kind=kind))
    return presets


SPEED_SCALE_RANGE: tuple[float, float] = (0.5, 2.0)
"""Allowed factors of `scale_speeds` (slower than half speed, a collision episode may end before its hit)."""


def scale_speeds(scenario: Scenario, drive: float = 1.0, approach: float = 1.0) -> Scenario:
    """The scenario with its cruise speeds times `drive` and its obstacle legs' speeds times `approach`.

    `drive` scales every forward leg that does not drive at an obstacle; `approach` scales the legs that do
    (a collision episode's hit and every near miss). Speeds are capped at `MAX_WHEEL_SPEED`; back-out legs
    and the reflex keep their speeds. A near miss keeps its margin: its safety stop distance is planned
    again for the new speed (braking at `BRAKE_DECEL`, as `draw_scenario` plans it). Factors of 1 return
    the scenario unchanged (the same object).
    """
    low, high = SPEED_SCALE_RANGE
    for name, factor in (("drive", drive), ("approach", approach)):
        if not low <= factor <= high:
            raise ScenarioError(f"{name} speed factor = {factor!r} is invalid; allowed: {low} to {high}")
    if drive == 1.0 and approach == 1.0:
        return scenario

    def scaled(w: Waypoint) -> Waypoint:
        if w.reverse:
            return w
        speed = min(w.speed * (approach if w.ram >= 0 else drive), MAX_WHEEL_SPEED)
        stop_short = w.stop_short
        if w.stop_short > 0:
            stop_short = w.stop_short + (speed**2 - w.speed**2) / (2.0 * BRAKE_DECEL)
        return dataclasses.replace(w, speed=speed, stop_short=stop_short)

    route = dataclasses.replace(scenario.route, waypoints=tuple(scaled(w) for w in scenario.route.waypoints))
    return dataclasses.replace(scenario, route=route)
