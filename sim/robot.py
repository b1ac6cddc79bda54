"""Robot models from assets/ with per-unit variation (wheel radius, gear ratio, mass distribution), and each
unit's part of a world's MJCF text (`robot_mjcf`, made once per unit)."""

from __future__ import annotations

import functools
import importlib
import importlib.resources
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from dm_control import mjcf

from sim.scenario import Unit, wheel_names
from sim.trace import RobotInfo


@dataclass(frozen=True)
class DriveTrain:
    """Nominal drive-train constants of a robot model (per-unit values vary around them)."""

    wheel_radius: float
    """Nominal wheel radius, m."""
    gear_ratio: float
    """Motor revolutions per wheel revolution."""
    motor_torque: float
    """Motor torque limit at the motor shaft, N m (wheel torque limit = this x gear ratio)."""
    pinion_teeth: int
    """Teeth on the motor pinion."""
    motor_pole_pairs: int
    """Pole pairs of the motor."""
    pwm_hz: float
    """PWM carrier frequency, Hz."""
    tread_blocks: int
    """Tread blocks per tyre circumference."""
    track: float
    """Left-right wheel distance, m."""
    wheelbase: float
    """Front-back axle distance, m (0 for two wheels)."""


DRIVE_TRAINS: dict[str, DriveTrain] = {
    "skid4": DriveTrain(0.08, 18.0, 0.5, 11, 4, 20000.0, 28, 0.45, 0.36),
    "diff2": DriveTrain(0.08, 18.0, 0.78, 11, 4, 20000.0, 28, 0.45, 0.0),
}
"""Drive-train constants of each robot model."""


@dataclass(frozen=True)
class BuiltRobot:
    """A robot MJCF model with the unit's variation applied, and its trace metadata."""

    model: mjcf.RootElement
    """The robot's MJCF tree (attach it to an arena)."""
    info: RobotInfo
    """Geometry and drive-train constants for the trace (mass is filled in once compiled)."""
    torque_limit: float
    """Wheel torque limit, N m."""


def asset_path(name: str) -> str:
    """Path of a file shipped in the `assets` namespace package.

    `importlib.resources.files("assets")` fails on Python 3.11 for a namespace package installed in
    editable mode (its path then holds a non-directory hook entry), so the package's directories are
    searched directly, falling back to `importlib.resources` for other installs.
    """
    package = importlib.import_module("assets")
    for entry in getattr(package, "__path__", []):
        candidate = Path(entry) / name
        if candidate.is_file():
            return str(candidate)
    found = importlib.resources.files("assets").joinpath(name)
    if not found.is_file():
        raise FileNotFoundError(f"asset not found: {name} (looked in the assets package)")
    return str(found)


def build_robot(unit: Unit) -> BuiltRobot:
    """Load the unit's robot model and apply its per-unit tolerances (seeded by `unit.unit_id`)."""
    model = mjcf.from_path(asset_path(f"robot_{unit.model}.xml"))
    drive = DRIVE_TRAINS[unit.model]
    rng = np.random.default_rng([0x5EED, unit.unit_id])
    s = unit.variation
    names = wheel_names(unit.model)
    radius = (
        drive.wheel_radius
        * (1.0 + s * rng.uniform(-0.012, 0.012))
        * (1.0 + s * rng.normal(0, 0.002, len(names)))
    )
    gear = drive.gear_ratio * (1.0 + s * rng.uniform(-0.02, 0.02))
    mass_scale = 1.0 + s * rng.uniform(-0.05, 0.05)
    battery_shift = s * rng.uniform(-0.03, 0.03, size=2)
    torque_limit = drive.motor_torque * gear
    wheel_pos = []
    for i, name in enumerate(names):
        body = model.find("body", f"wheel_{name}")
        geom = model.find("geom", name)
        geom.size = [float(radius[i])]
        body.pos = [body.pos[0], body.pos[1], float(radius[i] - drive.wheel_radius)]
        wheel_pos.append([body.pos[0], body.pos[1], body.pos[2]])
        act = model.find("actuator", name)
        act.forcerange = [-torque_limit, torque_limit]
    for geom_name in ("chassis", "battery"):
        g = model.find("geom", geom_name)
        g.mass = float(g.mass * mass_scale)
    battery = model.find("geom", "battery")
    battery.pos = [
        float(battery.pos[0] + battery_shift[0]),
        float(battery.pos[1] + battery_shift[1]),
        battery.pos[2],
    ]
    site = {
        n: np.asarray(model.find("site", n).pos, dtype=np.float64) for n in ("imu", "mic_left", "mic_right")
    }
    info = RobotInfo(
        model=unit.model,
        unit_id=unit.unit_id,
        mass=0.0,
        wheel_names=names,
        wheel_radius=np.asarray(radius, dtype=np.float64),
        wheel_pos_body=np.asarray(wheel_pos, dtype=np.float64),
        mic_pos_body=np.stack([site["mic_left"], site["mic_right"]]),
        imu_pos_body=site["imu"],
        gear_ratio=float(gear),
        pinion_teeth=drive.pinion_teeth,
        motor_pole_pairs=drive.motor_pole_pairs,
        pwm_hz=drive.pwm_hz,
        tread_blocks=drive.tread_blocks,
        track=drive.track,
        wheelbase=drive.wheelbase,
    )
    return BuiltRobot(model=model, info=info, torque_limit=float(torque_limit))


@dataclass(frozen=True)
class RobotMJCF:
    """A robot unit's part of a world's MJCF text, as dm_control.mjcf writes it when the robot is attached
    to an arena on a free joint named `root` (see `sim.world.world_xml`)."""

    robot: BuiltRobot
    """The robot (its tree is attached to a throwaway arena: read it, do not attach it again)."""
    defaults: str
    """The robot's default classes (lines inside the world's top `<default>`, after its `/` class)."""
    body: str
    """Inside the attachment frame's `<body>`: the free joint and the robot's bodies, with the frame's
    closing tag (the frame's opening line, which holds the start pose, is the world's)."""
    actuators: str
    """The robot's actuators (lines inside `<actuator>`)."""


@functools.lru_cache(maxsize=64)
def robot_mjcf(unit: Unit, conaffinity: int | None) -> RobotMJCF:
    """The unit's MJCF text, made once per unit and collision setting (through dm_control.mjcf, which costs
    more than writing the rest of a world's text and compiling it).

    Args:
        unit: the robot unit.
        conaffinity: the collision affinity of every geom outside the `visual` class (None: the model's).
    """
    robot = build_robot(unit)
    if conaffinity is not None:
        for geom in robot.model.find_all("geom"):
            if geom.dclass is None or geom.dclass.dclass != "visual":
                geom.conaffinity = conaffinity
    arena = mjcf.RootElement(model="robot")
    arena.attach(robot.model).add("freejoint", name="root")
    text = arena.to_xml_string()
    head = '  <default>\n    <default class="/"/>\n'
    frame = f'    <body name="{robot.model.model}/">\n'
    start, end = text.index(head) + len(head), text.index("\n  </default>\n") + 1
    body_start, body_end = text.index(frame) + len(frame), text.index("\n  </worldbody>\n") + 1
    act_start = text.index("\n  <actuator>\n") + len("\n  <actuator>\n")
    act_end = text.index("\n  </actuator>\n") + 1
    return RobotMJCF(
        robot=robot,
        defaults=text[start:end],
        body=text[body_start:body_end],
        actuators=text[act_start:act_end],
    )
