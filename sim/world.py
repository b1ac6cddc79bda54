"""World building with dm_control.mjcf: arena, floor surface, transients, obstacles and the robot.

`build_world(scenario)` returns a compiled `mujoco.MjModel` plus the index tables the rollout needs
(sensor slices, body and mocap ids). Sensors are MuJoCo's own: wheel joint angle/speed, actuator
torque, base pose and velocity, IMU accelerometer/gyro/velocimeter, microphone sites, and one
`contact` sensor per obstacle (robot subtree vs obstacle) and per wheel (wheel vs transients).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import mujoco
import numpy as np
from dm_control import mjcf
from scipy import ndimage

from sim.robot import BuiltRobot, build_robot
from sim.scenario import OBSTACLE_MASS, Obstacle, Scenario
from sim.trace import ObstacleRecord
from sim.vocab import TRANSIENT_HEIGHT

PHYSICS_DT = 0.0025
"""Physics time step, s: two steps per 5 ms IMU sample."""

WALL_HALF_THICKNESS = 0.1
"""Half thickness of the arena's border walls, m."""


@dataclass(frozen=True)
class Surface:
    """Physical parameters of a floor surface."""

    friction: float
    """Sliding friction coefficient."""
    roughness: float
    """RMS height of the heightfield roughness, m (0 = flat plane)."""
    correlation: float
    """Correlation length of the roughness, m."""
    solref: tuple[float, float]
    """Contact time constant and damping ratio (soft floors are slower)."""


SURFACES: dict[str, Surface] = {
    "tile": Surface(0.75, 0.0, 0.0, (0.008, 1.0)),
    "carpet": Surface(0.95, 0.0, 0.0, (0.02, 1.0)),
    "concrete": Surface(0.85, 0.0, 0.0, (0.008, 1.0)),
    "asphalt": Surface(0.9, 0.0, 0.0, (0.01, 1.0)),
    "gravel": Surface(0.7, 0.005, 0.1, (0.012, 1.0)),
    "grass": Surface(0.6, 0.006, 0.2, (0.025, 1.0)),
}
"""Floor surfaces: friction, heightfield roughness and contact softness."""


@dataclass(frozen=True)
class SensorSlices:
    """Where each quantity lives in `MjData.sensordata` (start offsets; widths are fixed)."""

    wheel_angle: int
    """W joint angles."""
    wheel_speed: int
    """W joint speeds."""
    wheel_torque: int
    """W actuator torques."""
    base_pos: int
    """3: base position."""
    base_quat: int
    """4: base orientation."""
    base_linvel: int
    """3: base linear velocity, world frame."""
    base_angvel: int
    """3: base angular velocity, base frame (gyro at the IMU site)."""
    acc: int
    """3: accelerometer."""
    vel: int
    """3: velocimeter (IMU frame)."""
    mic: int
    """6: left then right microphone positions."""
    obstacle_pos: int
    """K x 3: obstacle body positions."""
    obstacle_contact: int
    """K x 7: per obstacle: found (contact count), net force of robot on obstacle (3, world), centroid (3)."""
    transient_contact: int
    """W x 7: per wheel: found, net force of wheel on transients (3, world), centroid (3)."""


@dataclass(frozen=True)
class World:
    """A compiled world and the tables needed to drive and record it."""

    model: mujoco.MjModel
    """The compiled model."""
    robot: BuiltRobot
    """The robot (its `info.mass` is the compiled mass)."""
    sensors: SensorSlices
    """Sensor offsets."""
    n_wheels: int
    """Number of driven wheels."""
    wheel_body: np.ndarray
    """(W,) body id of each wheel."""
    wheel_dof: np.ndarray
    """(W,) dof index of each wheel joint."""
    wheel_geom: np.ndarray
    """(W,) geom id of each wheel's collision shape (an out-of-round wheel's is moved off its axle)."""
    base_body: int
    """Body id of the robot base."""
    root_dof: int
    """First dof of the robot's free joint (3 linear, then 3 angular velocities)."""
    obstacles: tuple[ObstacleRecord, ...]
    """Obstacles (the scenario's, then the four border walls)."""
    obstacle_body: np.ndarray
    """(K,) body id of each obstacle."""
    obstacle_mocap: np.ndarray
    """(K,) mocap id of each obstacle, -1 for non-mocap bodies."""
    obstacle_free: np.ndarray
    """(K,) True for free bodies (pushed when hit)."""
    transient_height: np.ndarray
    """(T,) height of each transient, m."""
    bumper_reach: float
    """Distance from the robot's centre to the front of its front bumper, m (for the safety field)."""


def build_world(scenario: Scenario) -> World:
    """Build and compile the scenario's world."""
    robot = build_robot(scenario.robot)
    arena = _arena(scenario)
    hfield_data = _add_floor(arena, scenario, SURFACES[scenario.surface])
    obstacles = list(scenario.obstacles) + _border_walls(scenario)
    obstacle_bodies = [_add_obstacle(arena, i, ob) for i, ob in enumerate(obstacles)]
    if hfield_data is not None:
        _keep_obstacles_off_heightfield(robot, obstacles, obstacle_bodies)
    transients = _add_transients(arena, scenario)
    _attach_robot(arena, robot, scenario.route.start)
    _add_sensors(arena, robot, obstacle_bodies, transients)
    model = mujoco.MjModel.from_xml_string(arena.to_xml_string(), arena.get_assets())
    if hfield_data is not None:
        model.hfield_data[:] = hfield_data
    w = len(robot.info.wheel_names)
    slices = _sensor_slices(w, len(obstacles))
    if model.nsensordata != slices.transient_contact + 7 * w:
        raise RuntimeError(f"sensor layout mismatch: {model.nsensordata} values")
    return _world(model, robot, scenario, obstacles, slices)


def _keep_obstacles_off_heightfield(
    robot: BuiltRobot, obstacles: list[Obstacle], obstacle_bodies: list[mjcf.Element]
) -> None:
    """Collision bits on a rough floor: free obstacles rest on a flat collision plane, not on the
    heightfield (box-heightfield contacts are many and costly); the robot touches the heightfield and the
    obstacles."""
    for ob, body in zip(obstacles, obstacle_bodies, strict=True):
        if ob.kind in OBSTACLE_MASS:
            for geom in body.find_all("geom"):
                geom.contype, geom.conaffinity = _FREE_OBSTACLE_BITS
    for geom in robot.model.find_all("geom"):
        if geom.dclass is None or geom.dclass.dclass != "visual":
            geom.conaffinity = _ROBOT_AFFINITY


def _add_transients(arena: mjcf.RootElement, scenario: Scenario) -> mjcf.Element:
    """The `transients` body holding every transient's geom (a site keeps it when there are none)."""
    transients = arena.worldbody.add("body", name="transients")
    for i, tr in enumerate(scenario.transients):
        _add_transient(transients, i, tr.kind, tr.x, tr.y, tr.yaw, tr.length)
    if not scenario.transients:
        transients.add("site", name="transients_empty", pos=[0, 0, -1])
    return transients


def _attach_robot(arena: mjcf.RootElement, robot: BuiltRobot, start: tuple[float, float, float]) -> None:
    """Attach the robot on a free joint at the route's start pose (x, y, yaw), its wheels just above the
    floor."""
    x0, y0, yaw0 = start
    frame = arena.attach(robot.model)
    frame.pos = [x0, y0, float(robot.info.wheel_radius.mean()) + 0.002]
    frame.quat = [np.cos(yaw0 / 2), 0.0, 0.0, np.sin(yaw0 / 2)]
    frame.add("freejoint", name="root")


def _add_sensors(
    arena: mjcf.RootElement, robot: BuiltRobot, obstacle_bodies: list[mjcf.Element], transients: mjcf.Element
) -> None:
    """Every sensor, in the order `_sensor_slices` lays out: wheels, base, IMU, mics, obstacles, contacts."""
    base = robot.model.find("body", "base")
    wheels = robot.info.wheel_names
    sensor = arena.sensor
    for name in wheels:
        sensor.add("jointpos", name=f"angle_{name}", joint=robot.model.find("joint", name))
    for name in wheels:
        sensor.add("jointvel", name=f"speed_{name}", joint=robot.model.find("joint", name))
    for name in wheels:
        sensor.add("actuatorfrc", name=f"torque_{name}", actuator=robot.model.find("actuator", name))
    imu = robot.model.find("site", "imu")
    sensor.add("framepos", name="base_pos", objtype="xbody", objname=base)
    sensor.add("framequat", name="base_quat", objtype="xbody", objname=base)
    sensor.add("framelinvel", name="base_linvel", objtype="xbody", objname=base)
    sensor.add("gyro", name="gyro", site=imu)
    sensor.add("accelerometer", name="acc", site=imu)
    sensor.add("velocimeter", name="vel", site=imu)
    sensor.add("framepos", name="mic_left", objtype="site", objname=robot.model.find("site", "mic_left"))
    sensor.add("framepos", name="mic_right", objtype="site", objname=robot.model.find("site", "mic_right"))
    for i, body in enumerate(obstacle_bodies):
        sensor.add("framepos", name=f"obstacle_pos_{i}", objtype="xbody", objname=body)
    for i, body in enumerate(obstacle_bodies):
        sensor.add(
            "contact", name=f"hit_{i}", subtree1=base, body2=body, data="found force pos",
            reduce="netforce", num=1,
        )  # fmt: skip
    for name in wheels:
        sensor.add(
            "contact", name=f"bump_{name}", geom1=robot.model.find("geom", name), body2=transients,
            data="found force pos", reduce="netforce", num=1,
        )  # fmt: skip


def _sensor_slices(w: int, k: int) -> SensorSlices:
    """Offsets of `_add_sensors`'s sensors for `w` wheels and `k` obstacles."""
    return SensorSlices(
        wheel_angle=0, wheel_speed=w, wheel_torque=2 * w, base_pos=3 * w, base_quat=3 * w + 3,
        base_linvel=3 * w + 7, base_angvel=3 * w + 10, acc=3 * w + 13, vel=3 * w + 16, mic=3 * w + 19,
        obstacle_pos=3 * w + 25, obstacle_contact=3 * w + 25 + 3 * k, transient_contact=3 * w + 25 + 10 * k,
    )  # fmt: skip


def _world(
    model: mujoco.MjModel,
    robot: BuiltRobot,
    scenario: Scenario,
    obstacles: list[Obstacle],
    slices: SensorSlices,
) -> World:
    """The World of a compiled model: ids of the robot's bodies and dofs, obstacle tables, the robot's
    compiled mass."""
    prefix = robot.model.model + "/"
    wheels = robot.info.wheel_names
    base_id = model.body(prefix + "base").id
    ob_body = np.array([model.body(f"obstacle_{i}").id for i in range(len(obstacles))])
    info = dataclasses.replace(robot.info, mass=float(model.body_subtreemass[base_id]))
    return World(
        model=model,
        robot=dataclasses.replace(robot, info=info),
        sensors=slices,
        n_wheels=len(wheels),
        wheel_body=np.array([model.body(f"{prefix}wheel_{n}").id for n in wheels]),
        wheel_dof=np.array([model.jnt_dofadr[model.joint(prefix + n).id] for n in wheels]),
        wheel_geom=np.array([model.geom(prefix + n).id for n in wheels]),
        base_body=int(base_id),
        root_dof=int(model.jnt_dofadr[model.joint(prefix + "root/").id]),
        obstacles=_obstacle_records(obstacles),
        obstacle_body=ob_body,
        obstacle_mocap=np.asarray(model.body_mocapid[ob_body], dtype=np.int64),
        obstacle_free=np.array([ob.kind in OBSTACLE_MASS for ob in obstacles], dtype=bool),
        transient_height=np.array([TRANSIENT_HEIGHT[t.kind] for t in scenario.transients]),
        bumper_reach=_bumper_reach(model, prefix),
    )


def _obstacle_records(obstacles: list[Obstacle]) -> tuple[ObstacleRecord, ...]:
    """What the trace records of each obstacle (position at its centre height)."""
    return tuple(
        ObstacleRecord(
            kind=ob.kind,
            material=ob.material,
            position=np.array([ob.x, ob.y, ob.size[2]]),
            size=np.asarray(ob.size, dtype=np.float64),
            yaw=float(ob.yaw),
        )
        for ob in obstacles
    )


def _bumper_reach(model: mujoco.MjModel, prefix: str) -> float:
    """Front of the robot's front bumper (a capsule across the robot) from the base centre, m."""
    bumper = model.geom(prefix + "bumper_front")
    return float(bumper.pos[0] + bumper.size[0])


def _arena(scenario: Scenario) -> mjcf.RootElement:
    arena = mjcf.RootElement(model=f"arena_{scenario.environment}")
    arena.compiler.angle = "radian"
    arena.option.timestep = PHYSICS_DT
    arena.option.integrator = "implicitfast"
    arena.option.cone = "elliptic"
    arena.option.noslip_iterations = 0
    arena.size.memory = "8M"
    return arena


def _add_floor(arena: mjcf.RootElement, scenario: Scenario, surface: Surface) -> np.ndarray | None:
    hx, hy = scenario.arena
    friction = [surface.friction, 0.02, 0.002]
    if surface.roughness <= 0:
        arena.worldbody.add(
            "geom", name="floor", type="plane", size=[hx + 1, hy + 1, 0.1], friction=friction,
            solref=list(surface.solref), rgba=[0.55, 0.55, 0.5, 1],
        )  # fmt: skip
        return None
    spacing = max(0.1, 2 * max(hx, hy) / 400)
    ncol = int(np.ceil(2 * (hx + 1) / spacing)) + 1
    nrow = int(np.ceil(2 * (hy + 1) / spacing)) + 1
    rng = np.random.default_rng([scenario.seed, 0xF100])
    field = ndimage.gaussian_filter(
        rng.standard_normal((nrow, ncol)), surface.correlation / spacing, mode="wrap"
    )
    field *= surface.roughness / max(float(field.std()), 1e-12)
    top = 6 * surface.roughness
    data = np.clip((field + 3 * surface.roughness) / top, 0.0, 1.0)
    arena.asset.add("hfield", name="ground", nrow=nrow, ncol=ncol, size=[hx + 1, hy + 1, top, 0.1])
    arena.worldbody.add(
        "geom", name="floor", type="hfield", hfield="ground", pos=[0, 0, -3 * surface.roughness],
        friction=friction, solref=list(surface.solref), rgba=[0.45, 0.5, 0.35, 1],
        contype=_HFIELD_BITS[0], conaffinity=_HFIELD_BITS[1],
    )  # fmt: skip
    arena.worldbody.add(
        "geom", name="obstacle_floor", type="plane", size=[hx + 1, hy + 1, 0.1], friction=friction,
        contype=_PLANE_BITS[0], conaffinity=_PLANE_BITS[1], rgba=[0, 0, 0, 0], group=3,
    )  # fmt: skip
    return np.asarray(data, dtype=np.float32).ravel()


_HFIELD_BITS = (4, 4)
_PLANE_BITS = (2, 2)
_FREE_OBSTACLE_BITS = (2, 3)
_ROBOT_AFFINITY = 5
"""Collision bits on rough floors: robot (1, 5) touches heightfield (4, 4), obstacles and transients;
free obstacles (2, 3) touch the robot and the flat plane (2, 2) but not the heightfield."""


def _border_walls(scenario: Scenario) -> list[Obstacle]:
    hx, hy = scenario.arena
    t = WALL_HALF_THICKNESS
    return [
        Obstacle("wall", hx + t, 0.0, 0.0, (t, hy + 2 * t, 0.6)),
        Obstacle("wall", -hx - t, 0.0, 0.0, (t, hy + 2 * t, 0.6)),
        Obstacle("wall", 0.0, hy + t, 0.0, (hx, t, 0.6)),
        Obstacle("wall", 0.0, -hy - t, 0.0, (hx, t, 0.6)),
    ]


_COLORS: dict[str, list[float]] = {
    "wall": [0.9, 0.9, 0.85, 1],
    "door": [0.55, 0.35, 0.2, 1],
    "curb": [0.6, 0.6, 0.6, 1],
    "desk": [0.7, 0.5, 0.3, 1],
    "chair": [0.3, 0.3, 0.35, 1],
    "box": [0.75, 0.6, 0.4, 1],
    "luggage": [0.2, 0.3, 0.6, 1],
    "pedestrian": [0.8, 0.6, 0.5, 1],
}


def _add_obstacle(arena: mjcf.RootElement, i: int, ob: Obstacle) -> mjcf.Element:
    sx, sy, sz = ob.size
    quat = [np.cos(ob.yaw / 2), 0.0, 0.0, np.sin(ob.yaw / 2)]
    rgba = _COLORS[ob.kind]
    if ob.kind == "pedestrian":
        body = arena.worldbody.add("body", name=f"obstacle_{i}", mocap=True, pos=[ob.x, ob.y, sz], quat=quat)
        radius = min(sx, sy)
        body.add("geom", type="capsule", size=[radius, sz - radius], rgba=rgba, solref=[0.03, 1.0])
        return body
    body = arena.worldbody.add("body", name=f"obstacle_{i}", pos=[ob.x, ob.y, sz], quat=quat)
    if ob.kind in OBSTACLE_MASS:
        body.add("freejoint")
        body.add(
            "geom",
            type="box",
            size=[sx, sy, sz],
            mass=OBSTACLE_MASS[ob.kind],
            rgba=rgba,
            friction=[0.5, 0.01, 0.001],
        )
    elif ob.kind == "chair":
        leg = 0.012
        for dx in (-1, 1):
            for dy in (-1, 1):
                body.add(
                    "geom", type="capsule", size=[leg, sz - 0.02],
                    pos=[dx * (sx - leg), dy * (sy - leg), -0.02], rgba=rgba,
                )  # fmt: skip
        body.add("geom", type="box", size=[sx, sy, 0.02], pos=[0, 0, sz - 0.02], rgba=rgba)
    else:
        body.add("geom", type="box", size=[sx, sy, sz], rgba=rgba)
    return body


def _add_transient(
    parent: mjcf.Element, i: int, kind: str, x: float, y: float, yaw: float, length: float
) -> None:
    h = TRANSIENT_HEIGHT[kind]
    quat = [np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]
    name = f"transient_{i}"
    rgba = [0.3, 0.3, 0.3, 1]
    if kind in ("seam", "threshold"):  # a low strip across the path; a threshold is wider
        half_width = 0.01 if kind == "seam" else 0.04
        parent.add(
            "geom",
            name=name,
            type="box",
            size=[length / 2, half_width, h / 2],
            pos=[x, y, h / 2],
            quat=quat,
            rgba=rgba,
        )
    elif kind == "cable":
        half = length / 2
        c, s = np.cos(yaw), np.sin(yaw)
        ends = [x - c * half, y - s * half, h / 2, x + c * half, y + s * half, h / 2]
        parent.add("geom", name=name, type="capsule", size=[h / 2], fromto=ends, rgba=[0.1, 0.1, 0.1, 1])
    elif kind == "kerb_ramp":
        # A plate tilted about its long axis: rises from the floor to `h` over 0.3 m, then drops.
        pitch = float(np.arctan2(h, 0.3))
        q_yaw = np.array(quat)
        q_tilt = np.array([np.cos(pitch / 2), np.sin(pitch / 2), 0.0, 0.0])
        q = _quat_mul(q_yaw, q_tilt)
        parent.add(
            "geom", name=name, type="box", size=[length / 2, 0.15 / np.cos(pitch), 0.004],
            pos=[x, y, h / 2 - 0.004], quat=list(q), rgba=[0.5, 0.5, 0.45, 1],
        )  # fmt: skip
    else:
        parent.add("geom", name=name, type="sphere", size=[h], pos=[x, y, 0.0], rgba=[0.4, 0.35, 0.3, 1])


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ]
    )
