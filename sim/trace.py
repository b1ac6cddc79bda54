"""The Trace: everything one simulated episode produced, as numpy arrays (the sim -> audio contract).

A Trace is read by the audio stage, the dataset writer and the viewer. It carries the physics-rate
wheel and body state, the 200 Hz IMU, contact and benign-transient events, the fault schedule with the
frequencies the audio stage needs, and per-IMU-sample labels. `Trace.save` writes one `.npz` file that
keeps each array at its stated precision (`sim.trace_storage`: float32 signals; time stamps, wheel angles
and microphone positions derived); `Trace.load` reads it back as exactly `trace.at_storage_precision()`, and
reads format-1 files (every array float64) too.
"""

from __future__ import annotations

import dataclasses
import functools
import os
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from msvdd.atomic import atomic_file
from sim import trace_storage

TRACE_FORMAT_VERSION = 3
"""Bumped whenever a field is added, removed or changes meaning, or the file keeps it differently.

2: the sampled signals are float32; time stamps, wheel angles and microphone positions are derived when they
follow the simulator's laws (`sim.trace_storage`).
3: the faults' defect model (`FaultRecord.size`, `FaultRecord.phase`, `fault_strikes`); `imbalance` gave way
to `out_of_round`. Formats 1 and 2 read with no strikes and zero sizes and phases.
"""
READABLE_TRACE_FORMATS: tuple[int, ...] = (1, 2, 3)
"""Trace format versions `Trace.load` reads."""


class TraceError(ValueError):
    """A trace file or trace object is malformed; the message names the field."""


class TraceNotFoundError(TraceError, FileNotFoundError):
    """The trace file named does not exist."""


@dataclass(frozen=True)
class RobotInfo:
    """The simulated robot unit: geometry and drive-train constants the audio stage needs."""

    model: str
    """Robot model name: `skid4` (four-wheel skid steer) or `diff2` (two wheels and a caster)."""
    unit_id: int
    """Robot unit (like a DCASE machine id); units differ in radius, gear ratio and mass distribution."""
    mass: float
    """Total mass in kg."""
    wheel_names: tuple[str, ...]
    """Driven wheel names, in the order of every per-wheel array."""
    wheel_radius: np.ndarray
    """(W,) rolling radius of each wheel in m."""
    wheel_pos_body: np.ndarray
    """(W, 3) wheel centres in the base frame, m."""
    mic_pos_body: np.ndarray
    """(2, 3) left and right microphone positions in the base frame, m."""
    imu_pos_body: np.ndarray
    """(3,) IMU site position in the base frame, m."""
    gear_ratio: float
    """Motor shaft revolutions per wheel revolution."""
    pinion_teeth: int
    """Teeth on the motor pinion: gear-mesh frequency = motor shaft rev/s x pinion_teeth."""
    motor_pole_pairs: int
    """Pole pairs of the drive motors (electrical frequency = shaft rev/s x pole pairs)."""
    pwm_hz: float
    """PWM carrier frequency of the motor drivers, Hz."""
    tread_blocks: int
    """Tread blocks per tyre circumference (tread-pitch tone = wheel rev/s x tread_blocks)."""
    track: float
    """Distance between left and right wheel centres, m."""
    wheelbase: float
    """Distance between front and back axles, m (0 for `diff2`)."""


@dataclass(frozen=True)
class ContactEvents:
    """Robot-obstacle contact events (wheel-floor contacts are not events); one row per event."""

    time: np.ndarray
    """(n,) time of first contact, s."""
    position: np.ndarray
    """(n, 3) contact point in the world frame, m."""
    normal: np.ndarray
    """(n, 3) unit contact normal, pointing from the obstacle to the robot."""
    impulse: np.ndarray
    """(n,) normal impulse over the event, N s."""
    normal_speed: np.ndarray
    """(n,) approach speed along the normal at first contact, m/s."""
    duration: np.ndarray
    """(n,) how long the contact lasted, s (sustained contacts scrape)."""
    obstacle_kind: tuple[str, ...]
    """(n,) obstacle kind of each event (see `sim.vocab.OBSTACLE_KINDS`)."""
    material: tuple[str, ...]
    """(n,) material of each event (see `sim.vocab.MATERIALS`)."""


@dataclass(frozen=True)
class TransientEvents:
    """Benign transients met while driving (seams, thresholds, cables, ramps, debris)."""

    time: np.ndarray
    """(n,) time a wheel hits the transient, s."""
    position: np.ndarray
    """(n, 3) world position, m."""
    wheel: np.ndarray
    """(n,) index of the wheel that hit it."""
    impulse: np.ndarray
    """(n,) vertical impulse on the wheel over the contact, N s (it includes the weight the wheel carries
    meanwhile; the audio's loudness comes from `synth_audio.transients.strike_impulse` instead)."""
    kind: tuple[str, ...]
    """(n,) transient kind (see `sim.vocab.TRANSIENT_KINDS`)."""
    height: np.ndarray
    """(n,) height of the floor feature, m: the step the wheel climbs (what the audio's strike needs)."""


# What a fault record means physically, the same for every unit and so not stored in the trace: the wheel
# bearing's geometry. The physics applies it (`sim.faults`: the bearing's defect order and strikes) and the
# audio sounds it (`synth_audio.faults`); both read it here.
BEARING_BALLS = 9
"""Rolling elements in the wheel bearing (a 6001-size deep-groove ball bearing)."""
BEARING_BALL_DIAMETER = 0.00635
"""Ball diameter, m."""
BEARING_PITCH_DIAMETER = 0.0215
"""Pitch diameter, m."""
BEARING_CONTACT_ANGLE = 0.0
"""Contact angle, rad."""

# What a contact strikes, by `ContactEvents.obstacle_kind`: the physics simulates boxes and luggage as free
# bodies of this mass (`sim.scenario.OBSTACLE_MASS`), the audio bounds what a hit can exchange by the reduced
# mass with the robot (`synth_audio.impacts.impact_impulse`).
STRUCK_MASS: dict[str, float] = {"box": 4.0, "luggage": 14.0, "pedestrian": 70.0}
"""Obstacles that give way when hit and their mass, kg (free bodies, and a person who steps back); the
others are fixed."""


@dataclass(frozen=True)
class FaultRecord:
    """One injected wheel fault, with the frequencies the audio stage needs."""

    kind: str
    """Fault kind (see `sim.vocab.FAULT_KINDS`)."""
    wheel: int
    """Index of the faulty wheel in `RobotInfo.wheel_names`."""
    severity: float
    """0 (no effect) .. 1 (severe)."""
    onset: float
    """Start time, s."""
    duration: float
    """Length, s."""
    defect_order: float
    """Defect events per wheel revolution (1 for a flat spot, a runout and a loose hub, the ball-pass order
    less the balls' slip for a bearing, pinion teeth x gear ratio for gear mesh); the defect frequency is
    order x wheel rev/s."""
    resonance_hz: float
    """Structural resonance the defect excites, Hz."""
    damping_ratio: float
    """Damping ratio of that resonance."""
    size: float = 0.0
    """The defect's size (`sim.faults.defect_size`): flat depth, runout, spall length or play in m; for worn
    gears the transmission error's growth in units of a healthy pair's."""
    phase: float = 0.0
    """Wheel angle at which the defect meets the floor (flat, loose hub's wobble) or a ball meets the spall,
    rad; for an out-of-round wheel the direction of its runout in the wheel's frame (`sim.engine` offsets the
    tread towards (cos phase, 0, sin phase)), whose high point meets the floor a quarter turn later, at wheel
    angle phase + pi / 2."""


@dataclass(frozen=True)
class FaultStrikes:
    """The strikes the impulsive faults' physics applied to the chassis (`sim.faults`), as the audio sounds
    them."""

    time: np.ndarray
    """(n,) time of each strike, s."""
    wheel: np.ndarray
    """(n,) index of the faulty wheel that struck."""
    impulse: np.ndarray
    """(n,) vertical impulse of the strike, N s."""

    @classmethod
    def empty(cls) -> FaultStrikes:
        """No strikes."""
        return cls(np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0))


@dataclass(frozen=True)
class ObstacleRecord:
    """One obstacle placed in the arena."""

    kind: str
    """Obstacle kind (see `sim.vocab.OBSTACLE_KINDS`)."""
    material: str
    """Material (see `sim.vocab.MATERIALS`)."""
    position: np.ndarray
    """(3,) initial centre in the world frame, m."""
    size: np.ndarray
    """(3,) box half-extents, m."""
    yaw: float
    """Heading about z, rad."""


@dataclass(frozen=True)
class Trace:
    """One simulated episode. Physics-rate arrays share `time`; IMU-rate arrays share `imu_time`."""

    scenario_name: str
    """Name of the scenario that produced it."""
    seed: int
    """Seed of the scenario."""
    environment: str
    """`indoor` or `outdoor`."""
    surface: str
    """Floor surface (see `sim.vocab.SURFACES`)."""
    duration: float
    """Episode length, s."""
    physics_dt: float
    """Physics time step, s; `time` is sampled at this step."""
    imu_rate: float
    """IMU sample rate, Hz (200)."""
    robot: RobotInfo
    """The robot unit."""
    arena_half_size: np.ndarray
    """(2,) half-extents of the arena in x and y, m."""
    time: np.ndarray
    """(n,) physics-rate time stamps, s."""
    wheel_angle: np.ndarray
    """(n, W) wheel joint angles, rad (unwrapped)."""
    wheel_speed: np.ndarray
    """(n, W) wheel joint speeds, rad/s."""
    wheel_torque: np.ndarray
    """(n, W) motor torque at the wheel, N m."""
    base_pos: np.ndarray
    """(n, 3) base position in the world, m."""
    base_quat: np.ndarray
    """(n, 4) base orientation, (w, x, y, z)."""
    base_linvel: np.ndarray
    """(n, 3) base linear velocity in the world frame, m/s."""
    base_angvel: np.ndarray
    """(n, 3) base angular velocity in the base frame, rad/s."""
    mic_pos: np.ndarray
    """(n, 2, 3) left and right microphone positions in the world, m."""
    imu_time: np.ndarray
    """(m,) IMU time stamps, s."""
    imu_vel_z: np.ndarray
    """(m,) IMU z-axis velocity in the sensor frame, m/s, with added noise and bias (the paper's input)."""
    imu_acc: np.ndarray
    """(m, 3) accelerometer, m/s^2, with noise and bias."""
    imu_gyro: np.ndarray
    """(m, 3) gyroscope, rad/s, with noise and bias."""
    contacts: ContactEvents
    """Robot-obstacle contact events."""
    transients: TransientEvents
    """Benign transients."""
    faults: tuple[FaultRecord, ...]
    """The fault schedule."""
    obstacles: tuple[ObstacleRecord, ...]
    """Obstacles in the arena."""
    obstacle_pos: np.ndarray
    """(m, K, 3) obstacle centres at IMU rate (pedestrians move), m."""
    label: np.ndarray
    """(m,) int8 label per IMU sample: index into `sim.vocab.LABELS`."""
    sub_kind: np.ndarray
    """(m,) int16 sub-kind per IMU sample: index into `sim.vocab.SUB_KINDS`."""
    label_wheel: np.ndarray
    """(m,) int8 wheel of a mechanical label, -1 otherwise."""
    fault_strikes: FaultStrikes = field(default_factory=FaultStrikes.empty)
    """The strikes of the impulsive faults, in time order."""
    format_version: int = field(default=TRACE_FORMAT_VERSION)
    """Trace format version."""

    @property
    def n_wheels(self) -> int:
        """Number of driven wheels."""
        return len(self.robot.wheel_names)

    def non_finite_fields(self) -> list[str]:
        """Dotted names of float arrays that hold NaN or inf (empty when the trace is clean)."""
        bad: list[str] = []
        for key, value in _flatten(self).items():
            if value.dtype.kind == "f" and not np.all(np.isfinite(value)):
                bad.append(key)
        return bad

    def at_storage_precision(self) -> Trace:
        """This trace as `save` then `load` give it back: signals rounded to float32, derived fields derived.

        Render audio from this, not from the simulator's trace, and a re-render from the file is identical.
        """
        arrays = self._stored_arrays()
        stored = typing.cast(Trace, _unflatten(Trace, trace_storage.decode(arrays, TRACE_FORMAT_VERSION), ""))
        object.__setattr__(stored, "_stored", arrays)  # what its `save` writes (encoding it again gives them)
        return stored

    def _stored_arrays(self) -> dict[str, np.ndarray]:
        """The arrays `save` writes: those this trace was decoded from (`at_storage_precision`), else its
        encoding."""
        kept: dict[str, np.ndarray] | None = self.__dict__.get("_stored")
        if kept is not None:
            return kept
        arrays = trace_storage.encode(_flatten(self))
        arrays["format_version"] = np.asarray(TRACE_FORMAT_VERSION, dtype=np.int64)
        return arrays

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the trace to one compressed `.npz` file at its storage precision (`sim.trace_storage`),
        atomically (temp file, then rename); the same trace always gives the same bytes."""
        target = Path(path)
        arrays = self._stored_arrays()
        with atomic_file(target) as handle:
            trace_storage.write_npz(handle, arrays)
        return target

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Trace:
        """Read a trace written by `save` (format 1 or 2); raises TraceError naming the file and the fault."""
        source = Path(path)
        if not source.is_file():
            raise TraceNotFoundError(f"trace file not found: {source}")
        try:
            with np.load(source, allow_pickle=False) as data:
                arrays = {key: data[key] for key in data.files}
        except (OSError, ValueError) as exc:
            raise TraceError(f"{source}: not a readable trace .npz ({exc})") from exc
        version = int(arrays.get("format_version", np.asarray(-1)))
        if version not in READABLE_TRACE_FORMATS:
            readable = " or ".join(str(v) for v in READABLE_TRACE_FORMATS)
            raise TraceError(f"{source}: trace format_version {version}, this software reads {readable}")
        try:
            return typing.cast(Trace, _unflatten(cls, trace_storage.decode(arrays, version), ""))
        except KeyError as exc:
            raise TraceError(f"{source}: missing field {exc.args[0]}") from exc
        except ValueError as exc:
            raise TraceError(f"{source}: malformed trace ({exc})") from exc


def _hints(cls: type) -> dict[str, Any]:
    """The resolved field types of a trace record class (resolved once: `typing.get_type_hints` compiles
    every string annotation again on each call)."""
    return _resolved_hints(cls)


@functools.cache
def _resolved_hints(cls: Any) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _flatten(obj: Any, prefix: str = "") -> dict[str, np.ndarray]:
    """Dataclass tree -> flat {dotted name: array}; tuples of records are stored column-wise."""
    out: dict[str, np.ndarray] = {}
    hints = _hints(type(obj))
    for f in dataclasses.fields(obj):
        key = prefix + f.name
        value = getattr(obj, f.name)
        hint = hints[f.name]
        record = _record_type(hint)
        if record is not None:
            out[key + ".__len__"] = np.asarray(len(value), dtype=np.int64)
            for rf in dataclasses.fields(record):
                column = [getattr(item, rf.name) for item in value]
                out[f"{key}.{rf.name}"] = _column(column, _hints(record)[rf.name])
        elif dataclasses.is_dataclass(hint):
            out.update(_flatten(value, key + "."))
        elif hint == tuple[str, ...]:
            out[key] = np.asarray(value, dtype=np.str_) if value else np.zeros(0, dtype="<U1")
        elif hint is str:
            out[key] = np.asarray(value, dtype=np.str_)
        elif hint is int:
            out[key] = np.asarray(value, dtype=np.int64)
        elif hint is float:
            out[key] = np.asarray(value, dtype=np.float64)
        else:
            out[key] = np.asarray(value)
    return out


def _column(values: list[Any], hint: Any) -> np.ndarray:
    if hint is str:
        return np.asarray(values, dtype=np.str_) if values else np.zeros(0, dtype="<U1")
    if hint is int:
        return np.asarray(values, dtype=np.int64)
    if hint is float:
        return np.asarray(values, dtype=np.float64)
    if not values:
        return np.zeros((0,), dtype=np.float64)
    return np.stack([np.asarray(v) for v in values])


def _record_type(hint: Any) -> type | None:
    """The record class of a `tuple[Record, ...]` hint, else None."""
    if typing.get_origin(hint) is tuple:
        args = typing.get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis and dataclasses.is_dataclass(args[0]):
            return typing.cast(type, args[0])
    return None


def _unflatten(cls: type, arrays: dict[str, np.ndarray], prefix: str) -> Any:
    hints = _hints(cls)
    kwargs: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        key = prefix + f.name
        hint = hints[f.name]
        record = _record_type(hint)
        if record is not None:
            n = int(arrays[key + ".__len__"])
            rhints = _hints(record)
            columns = {rf.name: arrays[f"{key}.{rf.name}"] for rf in dataclasses.fields(record)}
            kwargs[f.name] = tuple(
                record(**{name: _scalar(col[i], rhints[name]) for name, col in columns.items()})
                for i in range(n)
            )
        elif dataclasses.is_dataclass(hint):
            kwargs[f.name] = _unflatten(typing.cast(type, hint), arrays, key + ".")
        elif hint == tuple[str, ...]:
            kwargs[f.name] = tuple(str(s) for s in arrays[key])
        elif hint in (str, int, float):
            kwargs[f.name] = _scalar(arrays[key], hint)
        else:
            kwargs[f.name] = arrays[key]
    return cls(**kwargs)


def _scalar(value: np.ndarray, hint: Any) -> Any:
    if hint is str:
        return str(value)
    if hint is int:
        return int(value)
    if hint is float:
        return float(value)
    return np.asarray(value)
