"""The Scenario: a frozen, validated description of one simulated episode (loadable from TOML).

Every field is checked when the dataclass is built; an invalid value raises `ScenarioError` naming the
field, the value and what is allowed, before any simulation runs. `Scenario.to_dict()` is JSON-able and
`Scenario.from_dict(scenario.to_dict()) == scenario`.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sim import vocab
from sim.trace import STRUCK_MASS

ROBOT_MODELS: tuple[str, ...] = ("skid4", "diff2")
"""Robot models shipped in assets/: four-wheel skid steer and two wheels with casters."""

MAX_WHEEL_SPEED = 1.8
"""Largest route speed a scenario may ask for, m/s."""


class ScenarioError(ValueError):
    """A scenario field is invalid; the message names the field, the value and what is allowed."""


class ScenarioNotFoundError(ScenarioError, FileNotFoundError):
    """The scenario file named does not exist."""


def _fail(name: str, value: Any, allowed: str) -> typing.NoReturn:
    raise ScenarioError(f"{name} = {value!r} is invalid; allowed: {allowed}")


def _finite(name: str, value: float) -> None:
    if not isinstance(value, int | float) or isinstance(value, bool) or not math.isfinite(value):
        _fail(name, value, "a finite number")


def _in_range(name: str, value: float, lo: float, hi: float) -> None:
    _finite(name, value)
    if not lo <= value <= hi:
        _fail(name, value, f"{lo:g} .. {hi:g}")


def _one_of(name: str, value: Any, allowed: tuple[str, ...]) -> None:
    if value not in allowed:
        _fail(name, value, ", ".join(allowed))


def wheel_names(robot_model: str) -> tuple[str, ...]:
    """Driven wheel names of a robot model, in trace order."""
    return vocab.WHEELS_SKID4 if robot_model == "skid4" else vocab.WHEELS_DIFF2


OBSTACLE_SIZES: dict[str, tuple[float, float, float]] = {
    "wall": (0.06, 1.5, 0.6),
    "door": (0.03, 0.45, 1.0),
    "curb": (0.08, 1.2, 0.07),
    "desk": (0.4, 0.7, 0.37),
    "chair": (0.24, 0.24, 0.22),
    "box": (0.2, 0.2, 0.18),
    "luggage": (0.12, 0.25, 0.33),
    "pedestrian": (0.2, 0.2, 0.85),
}
"""Default box half-extents (x, y, z) of each obstacle kind, m."""

OBSTACLE_MASS: dict[str, float] = {kind: STRUCK_MASS[kind] for kind in ("box", "luggage")}
"""Obstacle kinds that are free bodies (pushed when hit) and their mass, kg (`sim.trace.STRUCK_MASS`); the
others are fixed (a pedestrian is moved kinematically)."""

@dataclass(frozen=True)
class Obstacle:
    """One obstacle in the arena."""

    kind: str
    """Obstacle kind (see `sim.vocab.OBSTACLE_KINDS`)."""
    x: float
    """Centre x in the world, m."""
    y: float
    """Centre y in the world, m."""
    yaw: float = 0.0
    """Heading about z, rad."""
    size: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Box half-extents, m; zeros take the kind's default from `OBSTACLE_SIZES`."""
    path: tuple[tuple[float, float], ...] = ()
    """Pedestrian only: walking path (x, y) points, walked back and forth; empty = standing still."""
    walk_speed: float = 1.0
    """Pedestrian only: walking speed, m/s."""

    def __post_init__(self) -> None:
        _one_of("obstacle.kind", self.kind, vocab.OBSTACLE_KINDS)
        for name in ("x", "y", "yaw", "walk_speed"):
            _finite(f"obstacle.{name}", getattr(self, name))
        if len(self.size) != 3 or any(not math.isfinite(s) or s < 0 for s in self.size):
            _fail("obstacle.size", self.size, "three half-extents >= 0 (zeros = default size)")
        if all(s == 0 for s in self.size):
            object.__setattr__(self, "size", OBSTACLE_SIZES[self.kind])
        elif any(s <= 0 for s in self.size):
            _fail("obstacle.size", self.size, "three half-extents > 0, or all zero for the default")
        object.__setattr__(self, "size", tuple(float(s) for s in self.size))
        object.__setattr__(self, "path", tuple((float(p[0]), float(p[1])) for p in self.path))
        if self.path and self.kind != "pedestrian":
            _fail("obstacle.path", self.path, "a path only for kind 'pedestrian'")
        _in_range("obstacle.walk_speed", self.walk_speed, 0.0, 2.5)

    @property
    def material(self) -> str:
        """Impact material of this obstacle's kind."""
        return vocab.OBSTACLE_MATERIAL[self.kind]


@dataclass(frozen=True)
class Fault:
    """One wheel fault, modelled in the physics."""

    kind: str
    """Fault kind (see `sim.vocab.FAULT_KINDS`)."""
    wheel: int
    """Index of the faulty wheel in the robot's wheel order."""
    severity: float
    """0 (no effect) .. 1 (severe)."""
    onset: float
    """Start time, s (inside the episode)."""
    duration: float = math.inf
    """Length, s; inf = until the end of the episode."""

    def __post_init__(self) -> None:
        _one_of("fault.kind", self.kind, vocab.FAULT_KINDS)
        if not isinstance(self.wheel, int) or isinstance(self.wheel, bool) or not 0 <= self.wheel <= 3:
            _fail("fault.wheel", self.wheel, "0, 1, 2, 3 (skid4) or 0, 1 (diff2)")
        _in_range("fault.severity", self.severity, 0.0, 1.0)
        _in_range("fault.onset", self.onset, 0.0, math.inf)
        if not self.duration > 0 or math.isnan(self.duration):
            _fail("fault.duration", self.duration, "> 0 s (inf = until the end)")


@dataclass(frozen=True)
class Waypoint:
    """One point of the route: drive to it at `speed`, then wait `dwell` seconds."""

    x: float
    """Target x, m."""
    y: float
    """Target y, m."""
    speed: float = 0.8
    """Cruise speed on the leg that ends here, m/s."""
    dwell: float = 0.0
    """Stop at this point for this long, s (0 = drive through)."""
    ram: int = -1
    """Index of an obstacle this leg drives at, -1 = none; the leg targets the obstacle's live centre
    and ends at contact or at the safety stop (`stop_short`), where the route's reflex takes over, or
    after a timeout."""
    stop_short: float = 0.0
    """On a `ram` leg: the safety field stops the robot (braking at the torque limit) when its bumper is
    this close to the obstacle, m (a near miss); 0 = the obstacle is not seen and the robot hits it."""
    reverse: bool = False
    """Drive this leg backwards (backing out of a dead end, docking, a three-point turn)."""
    hard_stop: bool = False
    """Stop at this point by braking at the torque limit (an emergency stop), not by a smooth ramp."""

    def __post_init__(self) -> None:
        for name in ("x", "y"):
            _finite(f"route.waypoint.{name}", getattr(self, name))
        _in_range("route.waypoint.speed", self.speed, 0.0, MAX_WHEEL_SPEED)
        _in_range("route.waypoint.dwell", self.dwell, 0.0, 600.0)
        _in_range("route.waypoint.stop_short", self.stop_short, 0.0, 3.0)
        if not isinstance(self.ram, int) or isinstance(self.ram, bool) or self.ram < -1:
            _fail("route.waypoint.ram", self.ram, "-1 or an obstacle index")
        if self.stop_short > 0 and self.ram < 0:
            _fail("route.waypoint.stop_short", self.stop_short, "0 on a leg without `ram`")
        for name in ("reverse", "hard_stop"):
            if not isinstance(getattr(self, name), bool):
                _fail(f"route.waypoint.{name}", getattr(self, name), "true or false")
        if self.reverse and self.ram >= 0:
            _fail("route.waypoint.reverse", self.reverse, "false on a `ram` leg")


REFLEX_KINDS: tuple[str, ...] = ("reverse", "wait", "push", "continue")
"""How the robot reacts to a contact or a safety stop: brake then back off; brake then stand; keep pushing
(stall) before braking; glance off and go on to the next waypoint without braking."""


@dataclass(frozen=True)
class Reflex:
    """The robot's reaction to touching an obstacle, or to its safety field stopping it (near miss)."""

    kind: str = "reverse"
    """One of `REFLEX_KINDS` (a safety stop always brakes: `push` and `continue` then stand like `wait`)."""
    delay: float = 0.0
    """Reaction time: the command in force carries on this long before the reflex acts, s."""
    wait: float = 0.0
    """Standstill after braking, motors holding, s."""
    reverse_time: float = 0.7
    """How long `reverse` backs off, s."""
    reverse_speed: float = 0.25
    """Backing-off speed of `reverse`, m/s."""
    push_time: float = 0.0
    """How long `push` keeps driving into the obstacle (wheels stalled at the torque limit), s."""

    def __post_init__(self) -> None:
        _one_of("route.reflex.kind", self.kind, REFLEX_KINDS)
        _in_range("route.reflex.delay", self.delay, 0.0, 2.0)
        _in_range("route.reflex.wait", self.wait, 0.0, 30.0)
        _in_range("route.reflex.reverse_time", self.reverse_time, 0.0, 10.0)
        _in_range("route.reflex.reverse_speed", self.reverse_speed, 0.0, MAX_WHEEL_SPEED)
        _in_range("route.reflex.push_time", self.push_time, 0.0, 10.0)


@dataclass(frozen=True)
class Route:
    """The route and speed profile the driving controller follows."""

    start: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Initial (x, y, yaw) of the robot, m and rad."""
    waypoints: tuple[Waypoint, ...] = ()
    """Waypoints in order; empty = stand still."""
    accel: float = 0.8
    """Longitudinal acceleration and braking limit, m/s^2."""
    yaw_rate: float = 1.2
    """Largest yaw rate the controller commands, rad/s."""
    loop: bool = True
    """Start again from the first waypoint when the last is reached."""
    reflex: Reflex = field(default_factory=Reflex)
    """Reaction to a contact or a safety stop."""

    def __post_init__(self) -> None:
        if len(self.start) != 3:
            _fail("route.start", self.start, "(x, y, yaw)")
        for i, v in enumerate(self.start):
            _finite(f"route.start[{i}]", v)
        object.__setattr__(self, "start", tuple(float(v) for v in self.start))
        wps = tuple(Waypoint(**w) if isinstance(w, dict) else w for w in self.waypoints)
        object.__setattr__(self, "waypoints", wps)
        if isinstance(self.reflex, dict):
            object.__setattr__(self, "reflex", Reflex(**self.reflex))
        _in_range("route.accel", self.accel, 0.05, 5.0)
        _in_range("route.yaw_rate", self.yaw_rate, 0.05, 4.0)


@dataclass(frozen=True)
class Transient:
    """One benign transient on the floor (the wheels roll over it)."""

    kind: str
    """Transient kind (see `sim.vocab.TRANSIENT_KINDS`)."""
    x: float
    """Centre x, m."""
    y: float
    """Centre y, m."""
    yaw: float = 0.0
    """Direction of the strip's long axis about z, rad."""
    length: float = 1.0
    """Length of the strip, m (debris: ignored)."""

    def __post_init__(self) -> None:
        _one_of("transient.kind", self.kind, vocab.TRANSIENT_KINDS)
        for name in ("x", "y", "yaw"):
            _finite(f"transient.{name}", getattr(self, name))
        _in_range("transient.length", self.length, 0.02, 40.0)


@dataclass(frozen=True)
class Unit:
    """The robot unit: model and per-unit manufacturing variation (like a DCASE machine id)."""

    model: str = "skid4"
    """Robot model (see `ROBOT_MODELS`)."""
    unit_id: int = 0
    """Unit id: seeds the per-unit wheel radius, gear ratio and mass distribution."""
    variation: float = 1.0
    """Scale of the per-unit tolerances (0 = nominal robot, 1 = realistic tolerances)."""

    def __post_init__(self) -> None:
        _one_of("robot.model", self.model, ROBOT_MODELS)
        if not isinstance(self.unit_id, int) or isinstance(self.unit_id, bool) or self.unit_id < 0:
            _fail("robot.unit_id", self.unit_id, "an integer >= 0")
        _in_range("robot.variation", self.variation, 0.0, 3.0)


@dataclass(frozen=True)
class Sensors:
    """IMU settings; noise and bias are added by the simulator (MuJoCo's `noise` does nothing)."""

    imu_rate: float = 200.0
    """IMU sample rate, Hz (the paper's 200)."""
    acc_noise: float = 0.03
    """Accelerometer white-noise standard deviation per sample, m/s^2."""
    gyro_noise: float = 0.004
    """Gyroscope white-noise standard deviation per sample, rad/s."""
    vel_noise: float = 0.004
    """z-velocity white-noise standard deviation per sample, m/s."""
    acc_bias: float = 0.05
    """Standard deviation of the constant accelerometer bias per axis, m/s^2."""
    gyro_bias: float = 0.003
    """Standard deviation of the constant gyroscope bias per axis, rad/s."""
    vel_bias: float = 0.002
    """Standard deviation of the constant z-velocity bias, m/s."""
    bias_walk: float = 0.0005
    """Random-walk step of every bias per sample, in units of that sensor's noise."""

    def __post_init__(self) -> None:
        if self.imu_rate != 200.0:
            _fail("sensors.imu_rate", self.imu_rate, "200 Hz")
        for f in dataclasses.fields(self):
            if f.name != "imu_rate":
                _in_range(f"sensors.{f.name}", getattr(self, f.name), 0.0, 10.0)


ARENA_LIMITS: dict[str, tuple[float, float]] = {"indoor": (3.0, 12.0), "outdoor": (5.0, 30.0)}
"""Allowed arena half-size range (m) per environment."""


@dataclass(frozen=True)
class Scenario:
    """One episode: world, robot, route, obstacles, faults and sensors. Validated when built."""

    name: str
    """Scenario name (recorded in the trace)."""
    seed: int
    """Seed of every random draw (surface roughness, sensor noise, rattle)."""
    duration: float
    """Episode length, s."""
    environment: str = "indoor"
    """`indoor` or `outdoor`."""
    surface: str = "tile"
    """Floor surface (indoor: tile, carpet, concrete; outdoor: concrete, asphalt, gravel, grass)."""
    arena: tuple[float, float] = (6.0, 4.5)
    """Half-size of the arena in x and y, m (walls on its border)."""
    robot: Unit = field(default_factory=Unit)
    """The robot unit."""
    route: Route = field(default_factory=Route)
    """Route and speed profile."""
    obstacles: tuple[Obstacle, ...] = ()
    """Obstacles inside the arena."""
    transients: tuple[Transient, ...] = ()
    """Benign transients on the floor."""
    faults: tuple[Fault, ...] = ()
    """Wheel faults."""
    sensors: Sensors = field(default_factory=Sensors)
    """IMU settings."""
    category: str = "nominal"
    """What the scenario is for: nominal, collision or fault (informational)."""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            _fail("name", self.name, "a non-empty string")
        if not isinstance(self.seed, int) or isinstance(self.seed, bool) or self.seed < 0:
            _fail("seed", self.seed, "an integer >= 0")
        _in_range("duration", self.duration, 0.05, 3600.0)
        _one_of("environment", self.environment, vocab.ENVIRONMENTS)
        _one_of("surface", self.surface, vocab.SURFACES)
        allowed = vocab.INDOOR_SURFACES if self.environment == "indoor" else vocab.OUTDOOR_SURFACES
        _one_of(f"surface (for {self.environment})", self.surface, allowed)
        _one_of("category", self.category, ("nominal", "collision", "fault"))
        lo, hi = ARENA_LIMITS[self.environment]
        if len(self.arena) != 2:
            _fail("arena", self.arena, "(half_x, half_y)")
        for i, a in enumerate(self.arena):
            _in_range(f"arena[{i}]", a, lo, hi)
        object.__setattr__(self, "arena", (float(self.arena[0]), float(self.arena[1])))
        self._check_inside()
        n_wheels = len(wheel_names(self.robot.model))
        for i, fault in enumerate(self.faults):
            if fault.wheel >= n_wheels:
                _fail(f"faults[{i}].wheel", fault.wheel, f"0 .. {n_wheels - 1} for robot {self.robot.model}")
            if fault.onset >= self.duration:
                _fail(f"faults[{i}].onset", fault.onset, f"0 .. {self.duration:g} s (before the end)")
        for i, wp in enumerate(self.route.waypoints):
            if wp.ram >= len(self.obstacles):
                _fail(f"route.waypoints[{i}].ram", wp.ram, f"-1 .. {len(self.obstacles) - 1}")

    def _check_inside(self) -> None:
        hx, hy = self.arena
        margin = 0.3

        def inside(name: str, x: float, y: float, m: float = margin) -> None:
            if abs(x) > hx - m or abs(y) > hy - m:
                _fail(name, (x, y), f"inside the arena |x| <= {hx - m:g}, |y| <= {hy - m:g} m")

        for i, ob in enumerate(self.obstacles):
            inside(f"obstacles[{i}].position", ob.x, ob.y, 0.0)
            for j, p in enumerate(ob.path):
                inside(f"obstacles[{i}].path[{j}]", p[0], p[1], 0.0)
        for i, tr in enumerate(self.transients):
            inside(f"transients[{i}].position", tr.x, tr.y, 0.0)
        inside("route.start", self.route.start[0], self.route.start[1])
        for i, wp in enumerate(self.route.waypoints):
            inside(f"route.waypoints[{i}]", wp.x, wp.y)

    @property
    def wheel_names(self) -> tuple[str, ...]:
        """Driven wheel names of the scenario's robot."""
        return wheel_names(self.robot.model)

    # ----------------------------------------------------------------------------------------- I/O
    def to_dict(self) -> dict[str, Any]:
        """JSON-able nested dict; `Scenario.from_dict(s.to_dict()) == s` (inf durations become strings)."""
        return typing.cast(dict[str, Any], _to_plain(self))

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Scenario:
        """Build from a nested dict (as written by `to_dict` or read from TOML); unknown keys refused."""
        return typing.cast(Scenario, _from_plain(cls, data, ""))

    @classmethod
    def from_toml(cls, path: str | Path) -> Scenario:
        """Load a scenario TOML file; a ScenarioError names the problem (ScenarioNotFoundError: no file)."""
        source = Path(path)
        if not source.is_file():
            raise ScenarioNotFoundError(f"scenario file not found: {source}")
        try:
            data = tomllib.loads(source.read_text(encoding="utf-8"))
        except tomllib.TOMLDecodeError as exc:
            raise ScenarioError(f"{source}: not valid TOML ({exc})") from exc
        try:
            return cls.from_dict(data)
        except ScenarioError as exc:
            raise ScenarioError(f"{source}: {exc}") from exc

    def replace(self, **changes: Any) -> Scenario:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)


def _to_plain(obj: Any) -> Any:
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: _to_plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, tuple | list):
        return [_to_plain(v) for v in obj]
    if isinstance(obj, float) and math.isinf(obj):
        return "inf" if obj > 0 else "-inf"
    return obj


def _from_plain(cls: type, data: Any, where: str) -> Any:
    label = where or "scenario"
    if not isinstance(data, dict):
        _fail(label, data, "a table of fields")
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls)]
    unknown = sorted(set(data) - set(names))
    if unknown:
        _fail(f"{label} key", unknown[0], ", ".join(names))
    kwargs: dict[str, Any] = {}
    for name in names:
        if name in data:
            kwargs[name] = _convert(hints[name], data[name], f"{where}.{name}" if where else name)
    try:
        return cls(**kwargs)
    except TypeError as exc:
        raise ScenarioError(f"{label}: {exc}") from exc


def _convert(hint: Any, value: Any, where: str) -> Any:
    origin = typing.get_origin(hint)
    if dataclasses.is_dataclass(hint):
        return _from_plain(typing.cast(type, hint), value, where)
    if origin is tuple:
        if not isinstance(value, list | tuple):
            _fail(where, value, "a list")
        args = typing.get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(args[0], v, f"{where}[{i}]") for i, v in enumerate(value))
        if len(value) != len(args):
            _fail(where, value, f"a list of {len(args)} values")
        return tuple(
            _convert(a, v, f"{where}[{i}]") for i, (a, v) in enumerate(zip(args, value, strict=True))
        )
    if hint is float:
        if isinstance(value, str) and value in ("inf", "-inf"):
            return float(value)
        if isinstance(value, bool) or not isinstance(value, int | float):
            _fail(where, value, "a number")
        return float(value)
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            _fail(where, value, "an integer")
        return value
    if hint is bool:
        if not isinstance(value, bool):
            _fail(where, value, "true or false")
        return value
    if hint is str:
        if not isinstance(value, str):
            _fail(where, value, "a string")
        return value
    return value
