"""Wheel faults: one defect model per kind, from which the physics and the audio both derive.

A fault's severity s (0..1) scales its *excitation* linearly: the impulse of each strike, or the amplitude
of the motion it forces, at a given speed. The defect's physical size follows from s by the kind's own law
(`defect_size`), so that equal severities are equally strong in the sensors whatever the kind. Severity 1 is
a defect a maintenance technician notices at once, the condition in which a wheel is taken out of service;
severity 0.25 is a developing defect, near what the sensors resolve over the noise of driving. Sizes at
severity 1 are those of a 160 mm polyurethane-tread drive wheel of a 20 kg robot (the model's), from the
maintenance criteria of AGV / AMR wheels, hubs, bearings and gearboxes:

- flat_spot: a flat worn into the tread (a wheel that skidded locked in an emergency stop, or a tread that
  took a set standing under load), depth h = s^2 `FLAT_DEPTH_M` (8 mm: a 70 mm-long flat, the tread worn
  through at one place; AGV wheel makers replace a polyurethane wheel whose flats or chunking reach a few
  mm, because it then thumps at every revolution). It is geometry: while the flat passes the floor, the
  wheel's collision sphere is raised towards its axle so that its bottom sits where the flat's lowest
  point does (`FaultForcing.flat_lift`); the corner of the robot pivots down on the flat's leading edge by
  up to h, lands on the flat (the slap) and pivots up on its trailing edge. Landing stops the corner's
  descent (v sin a, a = acos(1 - h / r) the flat's half-angle) and the pivot on the trailing edge lifts it
  at once by as much (the rimless wheel's impact): the slap reverses the corner's vertical velocity and
  exchanges J = 2 m_c v sin a ~ 2 m_c v sqrt(2 h / r) (m_c the robot's mass over its wheels, v the rim
  speed, r the radius), twice a benign step's (`synth_audio.transients.strike_impulse`, which only stops
  or starts a descent), recorded as the strike the audio sounds.
- out_of_round: a wheel whose tread runs eccentric to its axle (a bent rim, or a tread worn or swollen
  unevenly), radial runout e = s `RUNOUT_M` (5 mm, a wheel that visibly rides up and down; a new wheel runs
  within a few tenths of a mm). It is
  geometry, not a force: the wheel's collision shape is moved off its axle by e (`geometry_offset`), so the
  corner of the robot rises and falls by e once per revolution and the rolling radius varies, at any speed.
  It replaces the rotating mass imbalance of earlier versions, which at this robot's wheel speeds (about one
  revolution per second) makes m e omega^2 of about 1 N on a 20 kg robot: nothing a sensor carries.
- bearing: an outer-race spall of the wheel bearing (a 6001-size deep-groove ball bearing,
  `sim.trace.BEARING_*`), length l = s `SPALL_M` (a whole ball diameter: stage-4 damage, a bearing to
  replace). Each rolling element that crosses the spall strikes its edge: J = m_c v_b min(l / d, 1), with
  v_b = omega D_pitch / 4 the balls' speed over the race and d the ball diameter, at the ball-pass order
  (BPFO) less a slip drawn per fault (`BEARING_SLIP`). The balls also grind over the spall's debris: a
  rough noise through the hub's resonance that grows with l (`synth_audio.faults`, `BEARING_GROWL`).
- loose_wheel: a hub whose fixings have worked loose, with play delta = s `PLAY_M` (5 mm: a wheel that
  visibly wobbles). The wheel rocks in its play once per revolution (toe angle delta / `HUB_SPAN`, a lateral
  tyre force F = `TYRE_CORNERING` delta / `HUB_SPAN` at the hub), and clunks through the play: the tyre's
  force (at least the wheel's weight) slams the hub across it, so each clunk exchanges
  J = sqrt(2 `WHEEL_MASS` F delta), `RATTLE_RATE` clunks per second at `NOMINAL_RIM_SPEED`, in proportion
  to speed, most where the wobble peaks.
- motor_degradation: worn gears and a weakened motor. The gear mesh's transmission error grows to
  (1 + s `WEAR_GAIN`) times a healthy pair's (the mesh tone, in the audio); the worn pinion's eccentricity
  (s `GEAR_ECCENTRICITY_M` on its `PINION_PITCH_RADIUS`) makes the wheel's speed lead and lag the motor's
  once per motor shaft revolution (`MOTOR_SPEED_RIPPLE`, the gear pair's transmission error), which the
  tyres pass to the chassis as a rocking force; the motor loses
  s `MOTOR_TORQUE_LOSS` of its torque, drags with s `MOTOR_DRAG`, and its wheel droops by s `MOTOR_DROOP`.

The strikes the physics applies (flat spot, bearing, loose wheel) are recorded in the trace
(`sim.trace.FaultStrikes`), and the audio sounds exactly those (`synth_audio.faults`); the flat's and the
spall's angular position and the balls' slip are drawn once per fault and kept in its `FaultRecord`.

The bearing's and the loose hub's strikes are vertical impulses on the chassis at the hub, over one physics
step: the chassis rests on its tyres' contact springs, so an impulse reaches the IMU whatever its size. A
wheel that stands still strikes nothing (the laws grow with speed; a loose hub clunks only while rolling).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sim.scenario import Fault, Scenario
from sim.trace import (
    BEARING_BALL_DIAMETER,
    BEARING_BALLS,
    BEARING_CONTACT_ANGLE,
    BEARING_PITCH_DIAMETER,
    FaultRecord,
    FaultStrikes,
    RobotInfo,
)

GRAVITY = 9.81
"""Standard gravity, m/s^2."""
FLAT_DEPTH_M = 0.008
"""Depth of the flat at severity 1, m (a 70 mm flat: the tread worn through at one place)."""
RUNOUT_M = 0.005
"""Radial runout of an out-of-round wheel at severity 1, m (10 mm total indicated runout)."""
SPALL_M = BEARING_BALL_DIAMETER
"""Length of the outer-race spall at severity 1, m (one ball diameter)."""
PLAY_M = 0.005
"""Play of a loose hub at severity 1, m."""
HUB_SPAN = 0.05
"""Axial span of the hub's bearing seat, m: a play delta lets the wheel rock by delta / span rad."""
TYRE_CORNERING = 900.0
"""Cornering stiffness of one polyurethane tyre, N/rad (lateral force per rad of toe)."""
WHEEL_MASS = 1.1
"""Mass of a wheel and hub, kg (the robot model's wheel): what clunks in a loose hub's play."""
RATTLE_RATE = 35.0
"""Clunks per second of a loose hub at `NOMINAL_RIM_SPEED` (proportional to speed)."""
NOMINAL_RIM_SPEED = 0.6
"""Rim speed at which the loose hub clunks `RATTLE_RATE` times a second, m/s."""
WEAR_GAIN = 6.0
"""Growth of the gear-mesh transmission error at severity 1, in units of a healthy pair's (+17 dB)."""
MOTOR_TORQUE_LOSS = 0.4
"""Fraction of motor torque lost at severity 1."""
GEAR_ECCENTRICITY_M = 50e-6
"""Runout of a worn motor pinion at severity 1, m (a healthy one of its size runs true to about 10 um)."""
PINION_PITCH_RADIUS = 2.75e-3
"""Pitch radius of the motor pinion, m (14 teeth of module 0.4 mm)."""
MOTOR_SPEED_RIPPLE = GEAR_ECCENTRICITY_M / PINION_PITCH_RADIUS
"""Amplitude of the worn gears' speed ripple at severity 1, fraction of the wheel speed: an eccentric
pinion's pitch radius, and with it the speed it passes on, varies by its runout once per revolution."""
MOTOR_DRAG = 0.15
"""Extra viscous drag at severity 1, N m s/rad."""
MOTOR_DROOP = 0.25
"""Fraction of commanded speed lost at severity 1."""
BEARING_GROWL = 8.0
"""Grinding of a spalled bearing at severity 1: its noise in the hub's resonance octave, in units of the
wheel's own drive sound there (+18 dB: a wheel that growls); proportional to the spall's length."""
BEARING_SLIP = (0.01, 0.02)
"""Range of the rolling elements' slip: the ball-pass rate is this fraction below the kinematic BPFO."""
RUNOUT_RAMP_S = 0.2
"""Time over which an out-of-round wheel's runout grows from 0 at onset to its size, s (no step)."""

RESONANCE: dict[str, tuple[float, float]] = {
    "flat_spot": (150.0, 0.08),
    "out_of_round": (160.0, 0.08),
    "bearing": (1600.0, 0.03),
    "loose_wheel": (420.0, 0.06),
    "motor_degradation": (1150.0, 0.04),
}
"""Structural resonance (Hz) and damping ratio each fault excites, before per-unit variation.

All lie below 2.2 kHz, the Nyquist frequency of the detectors' 4410 Hz audio (the paper decimates by 10):
the tyre and hub modes of a small aluminium-frame robot, not the kHz ring of an isolated bearing race. A
flat's slap rings the wheel bouncing on its tread (1.1 kg on a polyurethane tread of about 1 MN/m: 150 Hz),
a thud: the 2 ms contact of a tread on the floor carries little above a few hundred Hz."""


def bpfo_order() -> float:
    """Ball-pass frequency of the outer race, in events per wheel revolution (kinematic, no slip)."""
    ratio = BEARING_BALL_DIAMETER / BEARING_PITCH_DIAMETER * math.cos(BEARING_CONTACT_ANGLE)
    return BEARING_BALLS / 2.0 * (1.0 - ratio)


def defect_size(kind: str, severity: float) -> float:
    """The defect's size at `severity`: flat depth, runout, spall length or play in m; for worn gears the
    transmission error's growth in units of a healthy pair's."""
    s = float(np.clip(severity, 0.0, 1.0))
    sizes = {
        "flat_spot": FLAT_DEPTH_M * s * s,
        "out_of_round": RUNOUT_M * s,
        "bearing": SPALL_M * s,
        "loose_wheel": PLAY_M * s,
        "motor_degradation": WEAR_GAIN * s,
    }
    if kind not in sizes:
        raise ValueError(f"unknown fault kind {kind!r}; allowed: {', '.join(sizes)}")
    return sizes[kind]


def strike_impulse(
    fault: FaultRecord, rim_speed: np.ndarray, corner_mass: float, radius: float
) -> np.ndarray:
    """Impulse of each strike of an impulsive fault at rim speeds `rim_speed` (m/s), N s (the laws above)."""
    v = np.abs(np.asarray(rim_speed, dtype=np.float64))
    size = fault.size
    if fault.kind == "flat_spot":
        return 2.0 * corner_mass * v * math.sin(math.acos(max(1.0 - size / radius, -1.0)))
    if fault.kind == "bearing":
        ball_speed = v / radius * BEARING_PITCH_DIAMETER / 4.0
        return corner_mass * ball_speed * min(size / BEARING_BALL_DIAMETER, 1.0)
    if fault.kind == "loose_wheel":
        slam = max(WHEEL_MASS * GRAVITY, TYRE_CORNERING * size / HUB_SPAN)
        return np.full(v.shape, math.sqrt(2.0 * WHEEL_MASS * slam * size))
    raise ValueError(f"{fault.kind!r} is not an impulsive fault; allowed: flat_spot, bearing, loose_wheel")


IMPULSIVE_KINDS: tuple[str, ...] = ("flat_spot", "bearing", "loose_wheel")
"""Kinds whose physics strikes the chassis (`sim.trace.FaultStrikes`)."""


def defect_order(kind: str, robot: RobotInfo) -> float:
    """Kinematic defect events per wheel revolution for a fault kind (a bearing's without slip)."""
    if kind == "bearing":
        return bpfo_order()
    if kind == "motor_degradation":
        return float(robot.pinion_teeth * robot.gear_ratio)
    return 1.0


def envelope_band(kind: str, rate: float) -> tuple[float, float]:
    """One octave around the structural resonance a fault of `kind` excites (before per-unit variation),
    clipped to [20 Hz, 0.5 `rate`): where its strikes' envelope is read."""
    f0 = RESONANCE.get(kind, (1000.0, 0.0))[0]
    top = 0.5 * rate
    return float(np.clip(f0 / math.sqrt(2.0), 20.0, top)), float(np.clip(f0 * math.sqrt(2.0), 20.0, top))


def fault_records(scenario: Scenario, robot: RobotInfo) -> tuple[FaultRecord, ...]:
    """The trace's records of a scenario's faults (`fault_record` of each, in order)."""
    return tuple(
        fault_record(f, robot, scenario.duration, scenario.seed, i) for i, f in enumerate(scenario.faults)
    )


def fault_record(fault: Fault, robot: RobotInfo, episode: float, seed: int, index: int = 0) -> FaultRecord:
    """The trace's record of a fault: its defect's size, angular position and order, and the resonance the
    audio stage rings. The resonance is the unit's and wheel's; the defect's position and the balls' slip are
    drawn from the scenario's seed and the fault's index."""
    unit = np.random.default_rng([0xFA17, robot.unit_id, fault.wheel])
    f0, zeta = RESONANCE[fault.kind]
    resonance = float(f0 * (1.0 + unit.uniform(-0.05, 0.05)))
    rng = np.random.default_rng([seed, 0xDEF, index])
    phase = float(rng.uniform(0.0, 2.0 * math.pi))
    order = defect_order(fault.kind, robot)
    if fault.kind == "bearing":
        order *= 1.0 - float(rng.uniform(*BEARING_SLIP))
    return FaultRecord(
        kind=fault.kind,
        wheel=fault.wheel,
        severity=float(fault.severity),
        onset=float(fault.onset),
        duration=float(min(fault.duration, episode - fault.onset)),
        defect_order=order,
        resonance_hz=resonance,
        damping_ratio=float(zeta),
        size=defect_size(fault.kind, fault.severity),
        phase=phase,
    )


@dataclass
class FaultForcing:
    """Per-step forcing of one fault, and the strikes it applied (internal state: its rattle generator)."""

    record: FaultRecord
    """The fault as the trace records it (size, phase, order)."""
    robot: RobotInfo
    """The robot (radius, mass, gear ratio)."""
    rng: np.random.Generator
    """Random draws of this fault (a loose hub's clunks), independent of every other stream."""
    strike_time: list[np.ndarray] = field(default_factory=list)
    """Times of the strikes applied so far, s (one array per control period)."""
    strike_impulse: list[np.ndarray] = field(default_factory=list)
    """Their impulses, N s."""

    @property
    def wheel(self) -> int:
        """The faulty wheel."""
        return self.record.wheel

    def active(self, t: np.ndarray) -> np.ndarray:
        """(k,) True where the fault acts at times `t`."""
        f = self.record
        return np.asarray((t >= f.onset) & (t < f.onset + f.duration))

    def apply(
        self,
        t: np.ndarray,
        theta: np.ndarray,
        omega: float,
        lateral: np.ndarray,
        motor_torque: float,
        xfrc: np.ndarray,
        qfrc: np.ndarray,
        speed: np.ndarray,
        dt: float,
    ) -> None:
        """Add this fault's forcing over k steps, and record its strikes.

        Args:
            t: (k,) step start times.
            theta: (k,) extrapolated wheel angles.
            omega: wheel speed now, rad/s.
            lateral: (3,) robot left axis in the world.
            motor_torque: wheel motor torque now, N m.
            xfrc: (k, 6) force/torque on the chassis at the hub (world frame), added to.
            qfrc: (k,) generalised force on the wheel joint, added to.
            speed: (k,) the wheel's speed command at each step, multiplied by the fault's factor on it.
            dt: physics step, s.
        """
        on = self.active(t)
        if not on.any():
            return
        f = self.record
        kind = f.kind
        radius = float(self.robot.wheel_radius[f.wheel])
        corner = float(self.robot.mass) / len(self.robot.wheel_names)
        rim = abs(omega) * radius
        if kind == "flat_spot":  # geometry (`flat_lift`); the strike is recorded for the audio
            hits = on & _crossed(theta - f.phase, omega * dt, 1.0)
            if hits.any():
                strike = strike_impulse(f, np.full(len(t), rim), corner, radius)
                self.strike_time.append(t[hits])
                self.strike_impulse.append(strike[hits])
        elif kind == "bearing":
            hits = on & _crossed(theta - f.phase, omega * dt, f.defect_order)
            if hits.any():
                self._strike(xfrc, t, hits, strike_impulse(f, np.full(len(t), rim), corner, radius), dt)
        elif kind == "loose_wheel":
            wobble = np.sin(theta - f.phase)
            force = on * TYRE_CORNERING * f.size / HUB_SPAN * min(rim / NOMINAL_RIM_SPEED, 1.0) * wobble
            xfrc[:, :3] += force[:, None] * lateral
            rate = RATTLE_RATE * rim / NOMINAL_RIM_SPEED * (1.0 + np.cos(theta - f.phase))
            hits = on & (self.rng.random(len(t)) < rate * dt)
            if hits.any():
                self._strike(xfrc, t, hits, strike_impulse(f, np.zeros(len(t)), corner, radius), dt)
        elif kind == "motor_degradation":
            s = f.severity
            speed *= 1.0 + on * s * MOTOR_SPEED_RIPPLE * np.sin(self.robot.gear_ratio * theta)
            qfrc -= on * s * (MOTOR_TORQUE_LOSS * motor_torque + MOTOR_DRAG * omega)

    def _strike(
        self, xfrc: np.ndarray, t: np.ndarray, hits: np.ndarray, impulse: np.ndarray, dt: float
    ) -> None:
        """Vertical impulses `impulse` at the steps `hits` (one step each), recorded as strikes."""
        if not hits.any():
            return
        xfrc[:, 2] += hits * impulse / dt
        self.strike_time.append(t[hits])
        self.strike_impulse.append(impulse[hits])

    def speed_factor(self, t: float) -> float:
        """Multiplier on the wheel's commanded speed at time t (worn gears droop)."""
        f = self.record
        if f.kind == "motor_degradation" and f.onset <= t < f.onset + f.duration:
            return 1.0 - MOTOR_DROOP * f.severity
        return 1.0

    def flat_lift(self, t: float, theta: float) -> float:
        """How far a flat-spotted wheel's collision sphere is raised towards its axle at time t and wheel
        angle theta, m: the sphere's bottom then sits where the flat's lowest point does.

        The flat (depth h, half-angle a = acos(1 - h / r) as seen from the axle) meets the floor flush at
        theta = `phase`; at phi = theta - phase within +-a the wheel pivots on the flat's edge and its axle
        stands (r - h) cos phi + r sin a |sin phi| above the floor, else r. 0 outside the fault.
        """
        f = self.record
        if f.kind != "flat_spot" or not f.onset <= t < f.onset + f.duration:
            return 0.0
        radius = float(self.robot.wheel_radius[f.wheel])
        half = math.acos(max(1.0 - f.size / radius, -1.0))
        phi = (theta - f.phase + math.pi) % (2 * math.pi) - math.pi
        if abs(phi) >= half:
            return 0.0
        height = (radius - f.size) * math.cos(phi) + radius * math.sin(half) * abs(math.sin(phi))
        return radius - height

    def flat_near(self, t: float, theta: float, omega: float, span: float) -> bool:
        """Whether a flat-spotted wheel at angle theta turning at omega may meet its flat within `span` s."""
        f = self.record
        if f.kind != "flat_spot" or t + span < f.onset or t >= f.onset + f.duration:
            return False
        radius = float(self.robot.wheel_radius[f.wheel])
        reach = math.acos(max(1.0 - f.size / radius, -1.0)) + abs(omega) * span + 0.05
        phi = (theta - f.phase + math.pi) % (2 * math.pi) - math.pi
        return abs(phi) < reach

    def geometry_offset(self, t: float) -> float:
        """How far the wheel's collision shape sits off its axle at time t, m (an out-of-round wheel's
        runout, grown over `RUNOUT_RAMP_S` after onset; 0 for the other kinds)."""
        f = self.record
        if f.kind != "out_of_round" or not f.onset <= t < f.onset + f.duration:
            return 0.0
        return f.size * min(1.0, (t - f.onset) / RUNOUT_RAMP_S)


def _crossed(angle: np.ndarray, step: float, order: float) -> np.ndarray:
    """(k,) True at the steps in which `order` x `angle` / 2 pi passed an integer (either way), the angle
    having advanced by `step` over the step."""
    cycles = order * angle / (2 * math.pi)
    return np.asarray(np.floor(cycles) != np.floor(cycles - order * step / (2 * math.pi)))


def make_forcings(scenario: Scenario, robot: RobotInfo) -> list[FaultForcing]:
    """Forcing objects of the scenario's faults that act (severity > 0); zero severity adds nothing."""
    return [
        FaultForcing(record=record, robot=robot, rng=np.random.default_rng([scenario.seed, 0xB0B, i]))
        for i, record in enumerate(fault_records(scenario, robot))
        if record.severity > 0.0
    ]


def strikes_of(forcings: list[FaultForcing]) -> FaultStrikes:
    """The strikes every forcing applied, in time order (ties: in forcing order)."""
    times = [np.concatenate(f.strike_time) if f.strike_time else np.zeros(0) for f in forcings]
    impulses = [np.concatenate(f.strike_impulse) if f.strike_impulse else np.zeros(0) for f in forcings]
    wheels = [np.full(t.size, f.wheel, dtype=np.int64) for t, f in zip(times, forcings, strict=True)]
    if not times:
        return FaultStrikes.empty()
    t = np.concatenate(times)
    order = np.argsort(t, kind="stable")
    return FaultStrikes(t[order], np.concatenate(wheels)[order], np.concatenate(impulses)[order])
