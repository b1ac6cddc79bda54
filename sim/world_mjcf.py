"""The world as a dm_control.mjcf element tree: the reference `sim.world.build_world`'s text is checked by.

`build_world` writes the world's MJCF text directly (fast); this module builds the same world through
dm_control's element tree, as the simulator did before, and tests/sim checks that `mjcf_world(scenario)
.to_xml_string()` equals `sim.world.world_xml(scenario)[0]` character for character over scenarios that use
every element (robot models, floors, obstacle kinds, pedestrians, transients).
"""

from __future__ import annotations

import numpy as np
from dm_control import mjcf

from sim.robot import BuiltRobot, build_robot
from sim.scenario import OBSTACLE_MASS, Obstacle, Scenario
from sim.vocab import TRANSIENT_HEIGHT
from sim.world import (
    COLORS,
    FREE_OBSTACLE_BITS,
    HFIELD_BITS,
    PHYSICS_DT,
    PLANE_BITS,
    ROBOT_AFFINITY,
    SLEEP_TOLERANCE,
    SURFACES,
    border_walls,
    heightfield,
    quat_mul,
)


def mjcf_world(scenario: Scenario) -> mjcf.RootElement:
    """The scenario's world as a dm_control.mjcf tree (its heightfield's data is not in it: see
    `sim.world.heightfield`)."""
    robot = build_robot(scenario.robot)
    arena = _arena(scenario)
    rough = _add_floor(arena, scenario)
    obstacles = list(scenario.obstacles) + border_walls(scenario)
    obstacle_bodies = [_add_obstacle(arena, i, ob) for i, ob in enumerate(obstacles)]
    if rough:
        _keep_obstacles_off_heightfield(robot, obstacles, obstacle_bodies)
    _add_transients(arena, scenario)
    _attach_robot(arena, robot, scenario.route.start)
    _add_tyre_pairs(arena, robot)
    _add_sensors(arena, robot)
    return arena


def _add_tyre_pairs(arena: mjcf.RootElement, robot: BuiltRobot) -> None:
    """Each wheel meets the floor through an explicit pair solved for its normal force only (`sim.tyre`
    gives the grip); the contacts MuJoCo would generate between them are excluded."""
    floor = arena.worldbody.find("geom", "floor")
    for name in robot.info.wheel_names:
        arena.contact.add("exclude", body1="world", body2=robot.model.find("body", f"wheel_{name}"))
    for name in robot.info.wheel_names:
        arena.contact.add("pair", geom1=floor, geom2=robot.model.find("geom", name), condim=1)


def _keep_obstacles_off_heightfield(
    robot: BuiltRobot, obstacles: list[Obstacle], obstacle_bodies: list[mjcf.Element]
) -> None:
    """Collision bits on a rough floor: free obstacles rest on a flat collision plane, not on the
    heightfield (box-heightfield contacts are many and costly); the robot touches the heightfield and the
    obstacles."""
    for ob, body in zip(obstacles, obstacle_bodies, strict=True):
        if ob.kind in OBSTACLE_MASS:
            for geom in body.find_all("geom"):
                geom.contype, geom.conaffinity = FREE_OBSTACLE_BITS
    for geom in robot.model.find_all("geom"):
        if geom.dclass is None or geom.dclass.dclass != "visual":
            geom.conaffinity = ROBOT_AFFINITY


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


def _add_sensors(arena: mjcf.RootElement, robot: BuiltRobot) -> None:
    """MuJoCo's sensors of the world (`sim.world._sensors_xml`): the base's velocity, the IMU, the count of
    the step's contacts."""
    base = robot.model.find("body", "base")
    imu = robot.model.find("site", "imu")
    sensor = arena.sensor
    sensor.add("framelinvel", name="base_linvel", objtype="xbody", objname=base)
    sensor.add("gyro", name="gyro", site=imu)
    sensor.add("accelerometer", name="acc", site=imu)
    sensor.add("velocimeter", name="vel", site=imu)
    sensor.add("contact", name="contacts", data="found", num=1)


def _arena(scenario: Scenario) -> mjcf.RootElement:
    arena = mjcf.RootElement(model=f"arena_{scenario.environment}")
    arena.compiler.angle = "radian"
    arena.option.timestep = PHYSICS_DT
    arena.option.integrator = "implicitfast"
    arena.option.cone = "elliptic"
    arena.option.noslip_iterations = 0
    arena.option.sleep_tolerance = SLEEP_TOLERANCE
    arena.option.flag.sleep = "enable"
    arena.size.memory = "8M"
    return arena


def _add_floor(arena: mjcf.RootElement, scenario: Scenario) -> bool:
    """The floor: a plane, or on a rough surface a heightfield and a flat plane for the free obstacles.
    Returns whether the floor is rough."""
    surface = SURFACES[scenario.surface]
    hx, hy = scenario.arena
    friction = [surface.friction, 0.02, 0.002]
    field = heightfield(scenario)
    if field is None:
        arena.worldbody.add(
            "geom", name="floor", type="plane", size=[hx + 1, hy + 1, 0.1], friction=friction,
            solref=list(surface.solref), rgba=[0.55, 0.55, 0.5, 1],
        )  # fmt: skip
        return False
    arena.asset.add("hfield", name="ground", nrow=field.nrow, ncol=field.ncol, size=list(field.size))
    arena.worldbody.add(
        "geom", name="floor", type="hfield", hfield="ground", pos=[0, 0, -3 * surface.roughness],
        friction=friction, solref=list(surface.solref), rgba=[0.45, 0.5, 0.35, 1],
        contype=HFIELD_BITS[0], conaffinity=HFIELD_BITS[1],
    )  # fmt: skip
    arena.worldbody.add(
        "geom", name="obstacle_floor", type="plane", size=[hx + 1, hy + 1, 0.1], friction=friction,
        contype=PLANE_BITS[0], conaffinity=PLANE_BITS[1], rgba=[0, 0, 0, 0], group=3,
    )  # fmt: skip
    return True


def _add_obstacle(arena: mjcf.RootElement, i: int, ob: Obstacle) -> mjcf.Element:
    sx, sy, sz = ob.size
    quat = [np.cos(ob.yaw / 2), 0.0, 0.0, np.sin(ob.yaw / 2)]
    rgba = COLORS[ob.kind]
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
        q = quat_mul(q_yaw, q_tilt)
        parent.add(
            "geom", name=name, type="box", size=[length / 2, 0.15 / np.cos(pitch), 0.004],
            pos=[x, y, h / 2 - 0.004], quat=list(q), rgba=[0.5, 0.5, 0.45, 1],
        )  # fmt: skip
    else:
        parent.add("geom", name=name, type="sphere", size=[h], pos=[x, y, 0.0], rgba=[0.4, 0.35, 0.3, 1])
