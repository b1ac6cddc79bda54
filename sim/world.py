"""World building: arena, floor surface, transients, obstacles and the robot, as MJCF text.

The text is written directly, in the form dm_control.mjcf gives the same world (`sim.world_mjcf` builds it
through dm_control's element tree, the reference tests/sim checks it against); the robot's part is
dm_control's, made once per robot unit (`sim.robot.robot_mjcf`). `build_world(scenario)` returns a
compiled `mujoco.MjModel` plus the index tables the rollout needs (sensor slices, body and mocap ids).
Sensors are MuJoCo's own: wheel joint angle/speed, actuator torque, base pose and velocity, IMU
accelerometer/gyro/velocimeter, microphone sites, and one `contact` sensor per obstacle (robot subtree vs
obstacle) and per wheel (wheel vs transients).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from scipy import ndimage

from sim.robot import BuiltRobot, robot_mjcf
from sim.scenario import OBSTACLE_MASS, Obstacle, Scenario
from sim.trace import ObstacleRecord
from sim.vocab import TRANSIENT_HEIGHT

PHYSICS_DT = 0.0025
"""Physics time step, s: two steps per 5 ms IMU sample.

Every contact's time constant (MuJoCo's `solref`: the higher-priority geom's, else the two geoms' mean) is at
least two steps, MuJoCo's condition for a stable soft contact. A 5 ms step would halve the simulation's cost
and keep that condition; the tyres' grip (`sim.tyre`) turns the robot the same at 1.25, 2.5 and 5 ms (MuJoCo's
contact friction rang the chassis in the turns the harder the longer the step), and at 5 ms the velocity
servos' torque limit needs care (docs/speed.md)."""

SLEEP_TOLERANCE = 1e-3
"""Speed under which a movable obstacle counts as at rest, m/s (MuJoCo's default `sleep_tolerance`).

The world enables MuJoCo's sleeping islands: an obstacle whose every velocity (rotations times its size)
has stayed under this for MuJoCo's `mjMINAWAKE` steps is taken out of the pipeline (no contacts with the
floor, no dynamics) until something awake touches it, which wakes it within the same step, "exactly as if it
was awake all along" (MuJoCo's documentation). A box resting on the floor creeps by orders of magnitude less
than 1 mm/s in the solver's soft contact, so what sleeps is what a real obstacle does: stand still. The robot
never sleeps (MuJoCo keeps an actuated tree awake), nor do the pedestrians (mocap bodies, moved every step).
Resting obstacles make most of a cluttered room's contacts (four per box on the floor), and sleeping drops
them.
"""

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
    """Where each quantity lives in a row of sensors, the values the step loop records after every physics
    step (`SensorRows`; start offsets, widths fixed): what MuJoCo's sensors of the same names give
    (`world_xml(every_sensor=True)`)."""

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
    tyre_contact: int
    """W x 7: per wheel: found, net normal force between the wheel and the floor (3, world), centroid (3)."""
    width: int
    """Values in a row."""


SOURCES = ("qpos", "qvel", "actuator_force", "xpos", "xquat", "site_xpos", "sensordata")
"""The `MjData` arrays a row of sensors copies values from (the source column of `SensorRows`' copies)."""

_OBJ = mujoco.mjtObj
BODY, XBODY, GEOM = int(_OBJ.mjOBJ_BODY), int(_OBJ.mjOBJ_XBODY), int(_OBJ.mjOBJ_GEOM)
"""Object types of a contact sensor's sides: a body, a body's subtree, a geom (MuJoCo's `mjtObj`)."""


@dataclass(frozen=True)
class SensorRows:
    """How the step loop (`sim.stepper`) fills a row of sensors (`SensorSlices`) at every physics step.

    Most of a row is copies of the data's arrays, which MuJoCo's sensors of the same kinds are: joint angles
    and speeds (`qpos`, `qvel`, copied before the step, whose state the step's sensors see), actuator
    torques, body and site positions, the base's orientation; MuJoCo's own sensors give the base's velocity
    and the IMU (`sensordata`). The contact sensors (found count, net force, force-weighted centroid of the
    contacts between two objects) are computed as MuJoCo's `contact` sensor with `reduce="netforce"` does,
    from the step's contact list, scanned once. The values are MuJoCo's sensors', bit for bit (tests/sim,
    against `reference_model`); MuJoCo passes over every sensor at each of its stages, and each `contact`
    sensor scans the whole contact list.
    """

    copies_before: np.ndarray
    """(n, 3) int64: row index, source (`SOURCES`), index in the source; read before each step."""
    copies_after: np.ndarray
    """(n, 3) int64: the same, read after each step."""
    contacts: np.ndarray
    """(c, 5) int64: a contact sensor's first row index (7 values), then its two sides' type and id (`BODY`,
    `XBODY`, `GEOM`)."""
    contact_count: int
    """Index in `MjData.sensordata` of the step's contact count (a `contact` sensor that every contact
    matches)."""


@dataclass(frozen=True)
class World:
    """A compiled world and the tables needed to drive and record it."""

    model: mujoco.MjModel
    """The compiled model."""
    robot: BuiltRobot
    """The robot (its `info.mass` is the compiled mass)."""
    sensors: SensorSlices
    """Where each value lives in a row of sensors."""
    rows: SensorRows
    """How the step loop fills a row of sensors."""
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
    """Build and compile the scenario's world.

    Its MJCF text (`world_xml`) is written directly rather than through dm_control.mjcf's element tree,
    which cost many times the compilation; the text is the one dm_control writes for the same world
    (`sim.world_mjcf`, checked character for character in tests/sim), so the compiled model is too.
    """
    model, robot = _compile(scenario, every_sensor=False)
    obstacles = list(scenario.obstacles) + border_walls(scenario)
    slices = _sensor_slices(len(robot.info.wheel_names), len(obstacles))
    return _world(model, robot, scenario, obstacles, slices)


def reference_model(scenario: Scenario) -> mujoco.MjModel:
    """The scenario's world compiled with a MuJoCo sensor for every value of a row of sensors, in the row's
    order (`world_xml(every_sensor=True)`): its `sensordata` after a step is what the step loop's row of the
    same step holds (tests/sim checks it bit for bit). The same bodies, geoms and ids as `build_world`'s."""
    return _compile(scenario, every_sensor=True)[0]


def _compile(scenario: Scenario, every_sensor: bool) -> tuple[mujoco.MjModel, BuiltRobot]:
    """The compiled model of `world_xml` (its heightfield filled, its tyre pairs set) and the robot."""
    xml, robot, hfield_data = world_xml(scenario, every_sensor)
    model = mujoco.MjModel.from_xml_string(xml)
    if hfield_data is not None:
        model.hfield_data[:] = hfield_data
    _tyre_pairs(model)
    return model, robot


def world_xml(scenario: Scenario, every_sensor: bool = False) -> tuple[str, BuiltRobot, np.ndarray | None]:
    """The world's MJCF text (arena, floor, obstacles, transients, the robot on a free joint at the
    route's start, sensors), the robot, and the heightfield's data (None on a flat floor). `every_sensor`:
    with a MuJoCo sensor for every value of a row of sensors (the reference for the step loop's rows, see
    `_sensors_xml`).

    The text is dm_control.mjcf's for the same world (`sim.world_mjcf.mjcf_world`): its element and
    attribute order, its names for unnamed elements (`//unnamed_geom_<index>`), floats written `%.17g`
    (exact); the robot's part comes from `sim.robot.robot_mjcf`, made once per unit.
    """
    surface = SURFACES[scenario.surface]
    field = heightfield(scenario)
    part = robot_mjcf(scenario.robot, None if field is None else ROBOT_AFFINITY)
    obstacles = list(scenario.obstacles) + border_walls(scenario)
    out = [
        f'<mujoco model="arena_{scenario.environment}">\n',
        '  <compiler angle="radian"/>\n',
        f'  <option timestep="{_f(PHYSICS_DT)}" sleep_tolerance="{_f(SLEEP_TOLERANCE)}" '
        'integrator="implicitfast" cone="elliptic" noslip_iterations="0">\n'
        '    <flag sleep="enable"/>\n  </option>\n',
        '  <size memory="8M"/>\n',
        '  <default>\n    <default class="/"/>\n',
        part.defaults,
        "  </default>\n",
    ]
    if field is not None:
        out.append(
            f'  <asset>\n    <hfield name="ground" nrow="{field.nrow}" ncol="{field.ncol}" '
            f'size="{_fs(field.size)}"/>\n  </asset>\n'
        )
    out.append("  <worldbody>\n")
    geoms = _floor_xml(out, scenario, surface, field is not None)
    joints = 0
    for i, ob in enumerate(obstacles):
        geoms, joints = _obstacle_xml(out, i, ob, field is not None, geoms, joints)
    out.append('    <body name="transients">\n')
    for i, tr in enumerate(scenario.transients):
        out.append(_transient_xml(i, tr.kind, tr.x, tr.y, tr.yaw, tr.length))
    if not scenario.transients:
        out.append('      <site name="transients_empty" class="/" pos="0 0 -1"/>\n')
    out.append("    </body>\n")
    x0, y0, yaw0 = scenario.route.start
    robot = part.robot
    pos = [x0, y0, float(robot.info.wheel_radius.mean()) + 0.002]
    quat = [np.cos(yaw0 / 2), 0.0, 0.0, np.sin(yaw0 / 2)]
    prefix = robot.model.model + "/"
    wheels = robot.info.wheel_names
    out += [
        f'    <body pos="{_fs(pos)}" quat="{_fs(quat)}" name="{prefix}">\n',
        part.body,
        "  </worldbody>\n  <contact>\n",
        *(f'    <exclude name="//unnamed_contact_{i}" body1="world" body2="{prefix}wheel_{n}"/>\n'
          for i, n in enumerate(wheels)),
        *(f'    <pair name="//unnamed_contact_{len(wheels) + i}" class="/" geom1="floor" geom2="{prefix}{n}" '
          'condim="1"/>\n' for i, n in enumerate(wheels)),
        "  </contact>\n  <actuator>\n",
        part.actuators,
        "  </actuator>\n",
    ]
    _sensors_xml(out, prefix, robot.info.wheel_names, len(obstacles), every_sensor)
    out.append("</mujoco>\n")
    return "".join(out), robot, field.data if field is not None else None


def _f(x: float) -> str:
    """A float as dm_control.mjcf writes it (`%.17g`: exact)."""
    return format(x, ".17g")


def _fs(values: Sequence[float] | np.ndarray) -> str:
    """Floats as dm_control.mjcf writes an array attribute."""
    return " ".join([format(float(x), ".17g") for x in values])


def _floor_xml(out: list[str], scenario: Scenario, surface: Surface, rough: bool) -> int:
    """The floor's geoms (see `sim.world_mjcf._add_floor`); returns how many."""
    hx, hy = scenario.arena
    friction = _fs([surface.friction, 0.02, 0.002])
    solref = _fs(surface.solref)
    size = _fs([hx + 1, hy + 1, 0.1])
    if not rough:
        out.append(
            f'    <geom name="floor" class="/" type="plane" size="{size}" friction="{friction}" '
            f'solref="{solref}" rgba="{_fs([0.55, 0.55, 0.5, 1])}"/>\n'
        )
        return 1
    out.append(
        f'    <geom name="floor" class="/" type="hfield" contype="{HFIELD_BITS[0]}" '
        f'conaffinity="{HFIELD_BITS[1]}" friction="{friction}" solref="{solref}" '
        f'pos="{_fs([0, 0, -3 * surface.roughness])}" hfield="ground" rgba="{_fs([0.45, 0.5, 0.35, 1])}"/>\n'
    )
    out.append(
        f'    <geom name="obstacle_floor" class="/" type="plane" contype="{PLANE_BITS[0]}" '
        f'conaffinity="{PLANE_BITS[1]}" group="3" size="{size}" friction="{friction}" rgba="0 0 0 0"/>\n'
    )
    return 2


def _obstacle_xml(
    out: list[str], i: int, ob: Obstacle, rough: bool, geoms: int, joints: int
) -> tuple[int, int]:
    """Obstacle `i`'s body (see `sim.world_mjcf._add_obstacle`); `geoms` and `joints` are the arena's
    geoms and joints before it (unnamed elements are named by their index); returns them after it."""
    sx, sy, sz = ob.size
    quat = _fs([np.cos(ob.yaw / 2), 0.0, 0.0, np.sin(ob.yaw / 2)])
    rgba = _fs(COLORS[ob.kind])
    mocap = ' mocap="true"' if ob.kind == "pedestrian" else ""
    out.append(f'    <body name="obstacle_{i}" pos="{_fs([ob.x, ob.y, sz])}" quat="{quat}"{mocap}>\n')
    lines: list[str] = []
    if ob.kind == "pedestrian":
        radius = min(sx, sy)
        lines.append(
            f'type="capsule" size="{_fs([radius, sz - radius])}" solref="{_fs([0.03, 1.0])}" rgba="{rgba}"'
        )
    elif ob.kind in OBSTACLE_MASS:
        out.append(f'      <freejoint name="//unnamed_joint_{joints}"/>\n')
        joints += 1
        bits = f'contype="{FREE_OBSTACLE_BITS[0]}" conaffinity="{FREE_OBSTACLE_BITS[1]}" ' if rough else ""
        lines.append(
            f'type="box" {bits}size="{_fs([sx, sy, sz])}" friction="{_fs([0.5, 0.01, 0.001])}" '
            f'mass="{_f(OBSTACLE_MASS[ob.kind])}" rgba="{rgba}"'
        )
    elif ob.kind == "chair":
        leg = 0.012
        for dx in (-1, 1):
            for dy in (-1, 1):
                lines.append(
                    f'type="capsule" size="{_fs([leg, sz - 0.02])}" '
                    f'pos="{_fs([dx * (sx - leg), dy * (sy - leg), -0.02])}" rgba="{rgba}"'
                )
        lines.append(f'type="box" size="{_fs([sx, sy, 0.02])}" pos="{_fs([0, 0, sz - 0.02])}" rgba="{rgba}"')
    else:
        lines.append(f'type="box" size="{_fs([sx, sy, sz])}" rgba="{rgba}"')
    for line in lines:
        out.append(f'      <geom name="//unnamed_geom_{geoms}" class="/" {line}/>\n')
        geoms += 1
    out.append("    </body>\n")
    return geoms, joints


def _transient_xml(i: int, kind: str, x: float, y: float, yaw: float, length: float) -> str:
    """Transient `i`'s geom (see `sim.world_mjcf._add_transient`)."""
    h = TRANSIENT_HEIGHT[kind]
    quat = [np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]
    head = f'      <geom name="transient_{i}" class="/" '
    if kind in ("seam", "threshold"):  # a low strip across the path; a threshold is wider
        half_width = 0.01 if kind == "seam" else 0.04
        return (
            f'{head}type="box" size="{_fs([length / 2, half_width, h / 2])}" pos="{_fs([x, y, h / 2])}" '
            f'quat="{_fs(quat)}" rgba="{_fs([0.3, 0.3, 0.3, 1])}"/>\n'
        )
    if kind == "cable":
        half = length / 2
        c, s = np.cos(yaw), np.sin(yaw)
        ends = [x - c * half, y - s * half, h / 2, x + c * half, y + s * half, h / 2]
        rgba = _fs([0.1, 0.1, 0.1, 1])
        return f'{head}type="capsule" size="{_f(h / 2)}" fromto="{_fs(ends)}" rgba="{rgba}"/>\n'
    if kind == "kerb_ramp":
        # A plate tilted about its long axis: rises from the floor to `h` over 0.3 m, then drops.
        pitch = float(np.arctan2(h, 0.3))
        q_tilt = np.array([np.cos(pitch / 2), np.sin(pitch / 2), 0.0, 0.0])
        q = quat_mul(np.array(quat), q_tilt)
        return (
            f'{head}type="box" size="{_fs([length / 2, 0.15 / np.cos(pitch), 0.004])}" '
            f'pos="{_fs([x, y, h / 2 - 0.004])}" quat="{_fs(q)}" rgba="{_fs([0.5, 0.5, 0.45, 1])}"/>\n'
        )
    return (
        f'{head}type="sphere" size="{_f(h)}" pos="{_fs([x, y, 0.0])}" rgba="{_fs([0.4, 0.35, 0.3, 1])}"/>\n'
    )


def _sensors_xml(out: list[str], prefix: str, wheels: tuple[str, ...], k: int, every: bool = False) -> None:
    """MuJoCo's sensors of the world: those a row of sensors takes from MuJoCo (the base's velocity, the IMU)
    and the count of the step's contacts, which the step loop reads (`SensorRows`). `every`: instead, a
    MuJoCo sensor for every value of the row, in the row's order (`SensorSlices`): wheels, base, IMU, mics,
    obstacles, contacts; the reference the step loop's rows are checked against (tests/sim)."""
    out.append("  <sensor>\n")
    base = f'objtype="xbody" objname="{prefix}base"'
    imu = [
        f'    <framelinvel name="base_linvel" {base}/>\n',
        f'    <gyro name="gyro" site="{prefix}imu"/>\n',
        f'    <accelerometer name="acc" site="{prefix}imu"/>\n',
        f'    <velocimeter name="vel" site="{prefix}imu"/>\n',
    ]
    if not every:
        out += [*imu, '    <contact name="contacts" num="1" data="found"/>\n', "  </sensor>\n"]
        return
    out += [f'    <jointpos name="angle_{n}" joint="{prefix}{n}"/>\n' for n in wheels]
    out += [f'    <jointvel name="speed_{n}" joint="{prefix}{n}"/>\n' for n in wheels]
    out += [f'    <actuatorfrc name="torque_{n}" actuator="{prefix}{n}"/>\n' for n in wheels]
    out += [f'    <framepos name="base_pos" {base}/>\n', f'    <framequat name="base_quat" {base}/>\n', *imu]
    out += [
        f'    <framepos name="mic_left" objtype="site" objname="{prefix}mic_left"/>\n',
        f'    <framepos name="mic_right" objtype="site" objname="{prefix}mic_right"/>\n',
    ]
    out += [
        f'    <framepos name="obstacle_pos_{i}" objtype="xbody" objname="obstacle_{i}"/>\n' for i in range(k)
    ]
    data = 'num="1" data="found force pos" reduce="netforce"'
    out += [
        f'    <contact name="hit_{i}" body2="obstacle_{i}" subtree1="{prefix}base" {data}/>\n'
        for i in range(k)
    ]
    out += [f'    <contact name="bump_{n}" geom1="{prefix}{n}" body2="transients" {data}/>\n' for n in wheels]
    out += [f'    <contact name="tyre_{n}" geom1="{prefix}{n}" geom2="floor" {data}/>\n' for n in wheels]
    out.append("  </sensor>\n")


def _sensor_slices(w: int, k: int) -> SensorSlices:
    """Offsets of `_add_sensors`'s sensors for `w` wheels and `k` obstacles."""
    return SensorSlices(
        wheel_angle=0, wheel_speed=w, wheel_torque=2 * w, base_pos=3 * w, base_quat=3 * w + 3,
        base_linvel=3 * w + 7, base_angvel=3 * w + 10, acc=3 * w + 13, vel=3 * w + 16, mic=3 * w + 19,
        obstacle_pos=3 * w + 25, obstacle_contact=3 * w + 25 + 3 * k, transient_contact=3 * w + 25 + 10 * k,
        tyre_contact=3 * w + 25 + 10 * k + 7 * w, width=3 * w + 25 + 10 * k + 14 * w,
    )  # fmt: skip


def _sensor_rows(
    model: mujoco.MjModel, prefix: str, wheels: tuple[str, ...], k: int, sl: SensorSlices
) -> SensorRows:
    """The step loop's plan for a row of sensors (`SensorRows`) in a compiled world."""
    qpos, qvel, force, xpos, xquat, site, sensor = range(len(SOURCES))
    base = model.body(prefix + "base").id
    before, after = [], []
    for i, name in enumerate(wheels):
        joint = model.joint(prefix + name).id
        before += [
            (sl.wheel_angle + i, qpos, model.jnt_qposadr[joint]),
            (sl.wheel_speed + i, qvel, model.jnt_dofadr[joint]),
        ]
        after.append((sl.wheel_torque + i, force, model.actuator(prefix + name).id))
    after += [(sl.base_pos + j, xpos, 3 * base + j) for j in range(3)]
    after += [(sl.base_quat + j, xquat, 4 * base + j) for j in range(4)]
    for start, name in (
        (sl.base_linvel, "base_linvel"),
        (sl.base_angvel, "gyro"),
        (sl.acc, "acc"),
        (sl.vel, "vel"),
    ):
        after += [(start + j, sensor, model.sensor_adr[model.sensor(name).id] + j) for j in range(3)]
    for m, name in enumerate(("mic_left", "mic_right")):
        after += [(sl.mic + 3 * m + j, site, 3 * model.site(prefix + name).id + j) for j in range(3)]
    for i in range(k):
        after += [
            (sl.obstacle_pos + 3 * i + j, xpos, 3 * model.body(f"obstacle_{i}").id + j) for j in range(3)
        ]
    contacts = [
        (sl.obstacle_contact + 7 * i, XBODY, base, BODY, model.body(f"obstacle_{i}").id) for i in range(k)
    ]
    transients, floor = model.body("transients").id, model.geom("floor").id
    for w, name in enumerate(wheels):
        contacts.append((sl.transient_contact + 7 * w, GEOM, model.geom(prefix + name).id, BODY, transients))
    for w, name in enumerate(wheels):
        contacts.append((sl.tyre_contact + 7 * w, GEOM, model.geom(prefix + name).id, GEOM, floor))
    return SensorRows(
        copies_before=np.array(before, dtype=np.int64).reshape(-1, 3),
        copies_after=np.array(after, dtype=np.int64).reshape(-1, 3),
        contacts=np.array(contacts, dtype=np.int64).reshape(-1, 5),
        contact_count=int(model.sensor_adr[model.sensor("contacts").id]),
    )


def _tyre_pairs(model: mujoco.MjModel) -> None:
    """Give each wheel-floor pair what MuJoCo gives a contact it generates between the two geoms (solmix
    weighted solref and solimp, the larger friction, margin and gap): the pairs' normal force is the one
    of the dynamic contacts they replace; their friction is the tyre law's (`sim.tyre`)."""
    for p in range(model.npair):
        g1, g2 = int(model.pair_geom1[p]), int(model.pair_geom2[p])
        m1, m2 = float(model.geom_solmix[g1]), float(model.geom_solmix[g2])
        mix = 0.5 if m1 + m2 == 0 else m1 / (m1 + m2)
        model.pair_solref[p] = mix * model.geom_solref[g1] + (1 - mix) * model.geom_solref[g2]
        model.pair_solimp[p] = mix * model.geom_solimp[g1] + (1 - mix) * model.geom_solimp[g2]
        f = np.maximum(model.geom_friction[g1], model.geom_friction[g2])
        model.pair_friction[p] = [f[0], f[0], f[1], f[2], f[2]]
        model.pair_margin[p] = max(model.geom_margin[g1], model.geom_margin[g2])
        model.pair_gap[p] = max(model.geom_gap[g1], model.geom_gap[g2])


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
    shared = robot.info  # made once per unit (`robot_mjcf`): each world gets its own arrays
    info = dataclasses.replace(
        shared, mass=float(model.body_subtreemass[base_id]), wheel_radius=shared.wheel_radius.copy(),
        wheel_pos_body=shared.wheel_pos_body.copy(), mic_pos_body=shared.mic_pos_body.copy(),
        imu_pos_body=shared.imu_pos_body.copy(),
    )  # fmt: skip
    return World(
        model=model,
        robot=dataclasses.replace(robot, info=info),
        sensors=slices,
        rows=_sensor_rows(model, prefix, wheels, len(obstacles), slices),
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


@dataclass(frozen=True)
class HeightField:
    """A rough floor's heightfield: MJCF attributes and data."""

    nrow: int
    """Rows (along y)."""
    ncol: int
    """Columns (along x)."""
    size: tuple[float, float, float, float]
    """MJCF size: x and y half extents, top height, base depth, m."""
    data: np.ndarray
    """(nrow x ncol,) float32 elevations in 0 .. 1, for `MjModel.hfield_data`."""


def heightfield(scenario: Scenario) -> HeightField | None:
    """The floor's heightfield: seeded Gaussian roughness of the surface's RMS height and correlation
    length, 3 sigma each side of the mean in 0 .. 1 (None on a flat surface)."""
    surface = SURFACES[scenario.surface]
    if surface.roughness <= 0:
        return None
    hx, hy = scenario.arena
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
    return HeightField(nrow, ncol, (hx + 1, hy + 1, top, 0.1), np.asarray(data, dtype=np.float32).ravel())


HFIELD_BITS = (4, 4)
PLANE_BITS = (2, 2)
FREE_OBSTACLE_BITS = (2, 3)
ROBOT_AFFINITY = 5
"""Collision bits on rough floors: robot (1, 5) touches heightfield (4, 4), obstacles and transients;
free obstacles (2, 3) touch the robot and the flat plane (2, 2) but not the heightfield."""


def border_walls(scenario: Scenario) -> list[Obstacle]:
    """The arena's four border walls (obstacles after the scenario's)."""
    hx, hy = scenario.arena
    t = WALL_HALF_THICKNESS
    return [
        Obstacle("wall", hx + t, 0.0, 0.0, (t, hy + 2 * t, 0.6)),
        Obstacle("wall", -hx - t, 0.0, 0.0, (t, hy + 2 * t, 0.6)),
        Obstacle("wall", 0.0, hy + t, 0.0, (hx, t, 0.6)),
        Obstacle("wall", 0.0, -hy - t, 0.0, (hx, t, 0.6)),
    ]


COLORS: dict[str, list[float]] = {
    "wall": [0.9, 0.9, 0.85, 1],
    "door": [0.55, 0.35, 0.2, 1],
    "curb": [0.6, 0.6, 0.6, 1],
    "desk": [0.7, 0.5, 0.3, 1],
    "chair": [0.3, 0.3, 0.35, 1],
    "box": [0.75, 0.6, 0.4, 1],
    "luggage": [0.2, 0.3, 0.6, 1],
    "pedestrian": [0.8, 0.6, 0.5, 1],
}
"""RGBA of each obstacle kind."""


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The quaternion product a b (w, x, y, z)."""
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
