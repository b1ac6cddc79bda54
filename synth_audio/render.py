"""`render(trace, config, seed) -> Audio`: every source, spatialised at the two microphones, and the mix.

Levels: the robot's sound is scaled so that its unit's reference drive (straight at
`config.reference_speed` on concrete at the typical torque `drive.reference_torque`, motor and rolling
sound only) has RMS `reference_level_dbfs`; this
fixed, per-unit reference is the "mean RMS of the unit" against which the environment is set to
`snr_db` (as MIMII / ToyADMOS2 mix at a fixed level per machine, not per clip), so a loud collision never
turns the background down. Near-field events (`synth_audio.nearfield`: footsteps, voices, drops, doors)
have their own SPL at 1 m, independent of `snr_db`; the robot's cooling fan (`synth_audio.electronics`)
is its own sound, `electronics.FAN_DB` re the reference drive.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from sim.trace import STRUCK_MASS, RobotInfo, Trace
from synth_audio import ambience as amb
from synth_audio import kernels
from synth_audio import nearfield as nf
from synth_audio.config import STEM_NAMES, Audio, AudioConfig, AudioError
from synth_audio.drive import Drive, build_drive, reference_torque, unstrained_torque
from synth_audio.dsp import add_at, bed_pool, noise_bed, rms, white
from synth_audio.electronics import FAN_DB, fan_sound, unit_fan
from synth_audio.faults import fault_sound
from synth_audio.impacts import impact, impact_impulse, scrape
from synth_audio.motor import motor_wheel, pwm_carrier
from synth_audio.reverb import DECIMATION, Room
from synth_audio.rolling import SURFACES, chassis_rattle, rolling_wheel
from synth_audio.spatial import REF_DISTANCE, mic_axes, point_gains, quat_to_matrix, spatialize_into
from synth_audio.transients import strike_impulse, transient
from synth_audio.validate import check_seed, check_trace

_STREAMS = (
    "motor", "rolling", "transients", "impacts", "faults", "ambience", "room", "mic_noise", "noise",
    "nearfield", "electronics",
)  # fmt: skip
"""Generator streams; new ones are appended, so that every existing stream keeps its seed."""
_REFERENCE_SURFACE = "concrete"
_REFERENCE_SECONDS = 1.0
_LIMIT_KNEE = 0.5
_MIX_CHUNK = 2**15
"""Samples the mix adds up at a time (every stem, in order, then the limiter)."""
_reference_cache: dict[tuple[object, ...], float] = {}


def _rng(seed: int, stream: str) -> np.random.Generator:
    """Independent generator per source group, so that adding a source never changes another."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(_STREAMS.index(stream),)))


def _unit_rng(robot: RobotInfo, wheel: int) -> np.random.Generator:
    """Generator for the unit's fixed character (harmonic weights): the same unit sounds the same."""
    unit = int(robot.unit_id)
    return np.random.default_rng([abs(unit), int(unit < 0), wheel, 0xA0D10])


def _body_sources(robot: RobotInfo) -> np.ndarray:
    """(W + 1, 3) body-frame positions of the per-wheel buses and the chassis bus (wheel centroid)."""
    wheels = np.asarray(robot.wheel_pos_body, dtype=np.float64)
    return np.vstack([wheels, np.mean(wheels, axis=0, keepdims=True)])


def _robot_buses(
    drive: Drive,
    surface: str,
    seed: int,
    trace: Trace | None,
    merged: bool = False,
    muted: tuple[str, ...] = (),
    fan_level: float = 0.0,
) -> dict[str, np.ndarray]:
    """Mono buses (W + 1, n) per robot source group; the last row is the chassis. Events need `trace`.

    With `merged`, every group accumulates into one bus array (same samples, no per-group copies); all
    dictionary entries are then the same array. Groups in `muted` stay silent. With `trace`, the chassis
    row of the `electronics` bus carries the unit's cooling fan at RMS `fan_level` (raw bus units).
    """
    robot = drive.robot
    w, n, sr = drive.n_wheels, drive.n, drive.sample_rate
    shared = np.zeros((w + 1, n), dtype=np.float32) if merged else None

    def bus() -> np.ndarray:
        return shared if shared is not None else np.zeros((w + 1, n), dtype=np.float32)

    buses = {"motor": bus(), "rolling": bus()}
    noise_rng = _rng(seed, "noise")
    spec = SURFACES[surface]
    road = bed_pool(sr, spec.points_hz, spec.gains_db)
    brush = bed_pool(sr, (1000, 2500, 6000, 12000), (-30, -6, 0, -12))
    roll_rng = _rng(seed, "rolling")
    carrier = pwm_carrier(drive, float(_rng(seed, "motor").uniform(0.0, 2.0 * np.pi)))
    for i in range(w):  # every wheel's brush and road noise is its own, uncorrelated with the others'
        motor_wheel(drive, i, _unit_rng(robot, i), noise_bed(noise_rng, n, brush), carrier, buses["motor"][i])
        rolling_wheel(drive, i, spec, noise_bed(noise_rng, n, road), roll_rng, buses["rolling"][i])
    buses["rolling"][w] += chassis_rattle(drive, spec, roll_rng)
    if trace is None:
        return buses
    buses["faults"] = bus()
    fault_rng = _rng(seed, "faults")
    # Each faulty wheel's nominal sound (motor + rolling), taken before any fault is added.
    nominal = {
        f.wheel: buses["motor"][f.wheel].copy()
        if merged
        else buses["motor"][f.wheel] + buses["rolling"][f.wheel]
        for f in trace.faults
    }
    for fault in () if "faults" in muted else trace.faults:
        buses["faults"][fault.wheel] += fault_sound(
            drive, fault, trace.fault_strikes, nominal[fault.wheel], fault_rng
        )
    buses["transients"] = bus()
    tr_rng = _rng(seed, "transients")
    tr = trace.transients
    robot = trace.robot
    corner_mass = float(robot.mass) / len(robot.wheel_names)
    for i in range(0 if "transients" in muted else len(tr.kind)):
        wheel = int(tr.wheel[i])
        t = float(tr.time[i])
        speed = float(np.interp(t, drive.block_time, drive.speed_mps[wheel]))
        strike = strike_impulse(
            tr.kind[i], float(tr.height[i]), speed, float(robot.wheel_radius[wheel]), corner_mass
        )
        sound = transient(tr.kind[i], strike, speed, sr, tr_rng)
        add_at(buses["transients"][wheel], round(t * sr), sound)
    buses["electronics"] = bus()
    if fan_level > 0:
        fan = fan_sound(unit_fan(robot), n, sr, _rng(seed, "electronics"))
        fan *= np.float32(fan_level)
        buses["electronics"][w] += fan
    return buses


def _spatialize(bus: np.ndarray, delays: np.ndarray, gains: np.ndarray) -> np.ndarray:
    """(2, n) from mono buses (S, n) at body-fixed positions with delays/gains (S, 2)."""
    out = np.zeros((2, bus.shape[1]), dtype=np.float32)
    for s in range(bus.shape[0]):
        if kernels.any_nonzero(bus[s]):
            spatialize_into(out, bus[s], delays[s], gains[s])
    return out


def _impacts(trace: Trace, sr: int, seed: int, speed_of_sound: float) -> np.ndarray:
    """(2, n) collision impacts and scrapes, each spatialised from its world contact point."""
    n = round(trace.duration * sr)
    out = np.zeros((2, n), dtype=np.float32)
    c = trace.contacts
    if len(c.material) == 0:
        return out
    rng = _rng(seed, "impacts")
    axes_body = mic_axes(np.asarray(trace.robot.mic_pos_body))
    mass = float(trace.robot.mass)
    for i in range(len(c.material)):
        t = float(c.time[i])
        k = int(np.clip(np.searchsorted(trace.time, t), 0, len(trace.time) - 1))
        rot = quat_to_matrix(trace.base_quat[k])
        delays, gains = point_gains(c.position[i], trace.mic_pos[k], axes_body @ rot.T, sr, speed_of_sound)
        start = math.floor(t * sr)
        offset = t * sr - start
        hit = impact_impulse(
            float(c.impulse[i]), float(c.normal_speed[i]), mass, STRUCK_MASS.get(c.obstacle_kind[i])
        )
        sound = impact(c.material[i], hit, float(c.normal_speed[i]), sr, rng)
        normal = np.asarray(c.normal[i], dtype=np.float64)
        vel = np.asarray(trace.base_linvel[k], dtype=np.float64)
        slide = float(np.linalg.norm(vel - np.dot(vel, normal) * normal))
        rub = scrape(c.material[i], float(c.impulse[i]), float(c.duration[i]), slide, sr, rng)
        if rub.size:
            sound = np.pad(sound, (0, max(rub.size - sound.size, 0)))
            sound[: rub.size] += rub
        spatialize_into(out, sound, delays[0] + offset, gains[0], start)
    return out


def _world_to_body(trace: Trace) -> Callable[[float], np.ndarray]:
    def rotation(t: float) -> np.ndarray:
        k = int(np.clip(np.searchsorted(trace.time, t), 0, len(trace.time) - 1))
        return quat_to_matrix(trace.base_quat[k]).T

    return rotation


def reference_rms(robot: RobotInfo, config: AudioConfig) -> float:
    """Raw (unscaled) binaural RMS of the unit's reference drive; cached per unit and config."""
    key = (
        robot.model, robot.unit_id, robot.mass, robot.wheel_names, robot.wheel_radius.tobytes(),
        np.asarray(robot.wheel_pos_body).tobytes(), np.asarray(robot.mic_pos_body).tobytes(),
        robot.gear_ratio, robot.pinion_teeth, robot.motor_pole_pairs, robot.pwm_hz, robot.tread_blocks,
        config.sample_rate, config.reference_speed, config.speed_of_sound,
    )  # fmt: skip
    cached = _reference_cache.get(key)
    if cached is not None:
        return cached
    sr = config.sample_rate
    n = int(_REFERENCE_SECONDS * sr)
    t = np.arange(0.0, _REFERENCE_SECONDS + 0.01, 0.002)
    w = len(robot.wheel_names)
    omega = config.reference_speed / np.asarray(robot.wheel_radius, dtype=np.float64)
    angle = t[:, None] * omega[None, :]
    speed = np.broadcast_to(omega, (t.size, w))
    torque = np.full((t.size, w), reference_torque(robot))
    drive = build_drive(robot, t, angle, speed, torque, n, sr)
    buses = _robot_buses(drive, _REFERENCE_SURFACE, 0, None)
    delays, gains = _robot_gains(robot, config)
    value = rms(_spatialize(buses["motor"] + buses["rolling"], delays, gains))
    if not value > 0:
        raise AudioError(
            "the robot unit's reference drive is silent; check robot.wheel_radius and gear_ratio"
        )
    if len(_reference_cache) > 256:
        _reference_cache.clear()
    _reference_cache[key] = value
    return value


def render(trace: Trace, config: AudioConfig | None = None, seed: int = 0) -> Audio:
    """Render a trace to two-microphone audio.

    Args:
        trace: the simulated episode.
        config: rendering settings (defaults: 44.1 kHz, 6 dB SNR, ambience on, no stems).
        seed: seed of every random draw; the same seed gives the same samples bit for bit.

    Returns:
        Audio with samples (round(trace.duration * sample_rate), 2) float32 and stems if asked.

    Raises:
        AudioError: the trace or config cannot be rendered (the message names the problem).
    """
    config = _checked_config(config)
    seed = check_seed(seed)
    check_trace(trace)
    sr = config.sample_rate
    n = round(trace.duration * sr)
    robot = trace.robot
    torque = trace.wheel_torque
    if "strain" in config.muted:
        torque = unstrained_torque(trace.time, torque, trace.contacts.time, trace.contacts.duration)
    drive = build_drive(robot, trace.time, trace.wheel_angle, trace.wheel_speed, torque, n, sr)
    scale = 10.0 ** (config.reference_level_dbfs / 20.0) / reference_rms(robot, config)
    # Stems in this order: the mix adds them in it, and the room's send is the sum of those before it.
    stems = _robot_stems(trace, drive, config, seed, scale)
    if "impacts" not in config.muted and (len(trace.contacts.material) or config.stems):
        stems["impacts"] = _impact_stem(trace, config, seed, scale)
    room = _room(trace, config, seed, n)
    room_gain = 10.0 ** (config.room_send_db / 20.0)
    near = _nearfield(trace, config, seed, n, room_gain, room is not None)
    room_spectrum = None
    if room is not None:
        room_spectrum = _room_send(room, stems, near, room_gain, n, config.stems)
    if near is not None:
        stems["nearfield"] = near[0]
    if config.ambience:
        stems["ambience"] = _ambience(trace, config, seed, n, room, room_spectrum)
    if room is not None and room_spectrum is not None:
        stems["room"] = room.wet(room_spectrum)
    if math.isfinite(config.mic_noise_dbfs):
        stems["mic_noise"] = _mic_noise(config, seed, n)
    return _mixdown(stems, config, n)


def _checked_config(config: AudioConfig | None) -> AudioConfig:
    """The config (the default one when None); AudioError unless it is a valid `AudioConfig`."""
    config = config if config is not None else AudioConfig()
    if not isinstance(config, AudioConfig):
        raise AudioError(f"config must be a synth_audio.AudioConfig, got {type(config).__name__}")
    config.validate()
    return config


def _robot_gains(robot: RobotInfo, config: AudioConfig) -> tuple[np.ndarray, np.ndarray]:
    """Delays and gains (W + 1, 2) from the wheel and chassis buses (`_body_sources`) to the two mics."""
    return point_gains(
        _body_sources(robot), robot.mic_pos_body, mic_axes(robot.mic_pos_body), config.sample_rate,
        config.speed_of_sound,
    )  # fmt: skip


def _bus_gains_db(config: AudioConfig) -> dict[str, float]:
    """Gain of each robot bus of `_robot_buses`, dB (the fan has none: its level is `FAN_DB`)."""
    return {
        "motor": config.gain_motor_db,
        "rolling": config.gain_rolling_db,
        "transients": config.gain_transients_db,
        "faults": config.gain_faults_db,
        "electronics": 0.0,
    }


def _fan_level(robot: RobotInfo, config: AudioConfig, gains: np.ndarray) -> float:
    """Raw RMS of the fan on the chassis bus, so that at the mics (x chassis gain x scale) it is `FAN_DB`
    re the reference drive."""
    chassis_gain = float(np.sqrt(np.mean(np.square(gains[-1]))))
    return 10.0 ** (FAN_DB / 20.0) * reference_rms(robot, config) / max(chassis_gain, 1e-12)


def _robot_stems(
    trace: Trace, drive: Drive, config: AudioConfig, seed: int, scale: float
) -> dict[str, np.ndarray]:
    """The robot's own sound at the mics, (2, n) each, times `scale` and each bus's gain.

    With `config.stems`, one stem per bus (source group); otherwise one `robot` stem. When no bus has a
    gain, the buses are accumulated into one array as they are made (`merged`), so one is spatialised;
    otherwise their gain-weighted sum is.
    """
    gains_db = _bus_gains_db(config)
    merged = not config.stems and all(g == 0.0 for g in gains_db.values())
    delays, gains = _robot_gains(trace.robot, config)
    fan_level = _fan_level(trace.robot, config, gains)
    buses = _robot_buses(drive, trace.surface, seed, trace, merged, config.muted, fan_level)
    if config.stems:
        return {
            name: _spatialize(bus, delays, gains) * np.float32(scale * 10.0 ** (gains_db[name] / 20.0))
            for name, bus in buses.items()
        }
    robot = _spatialize(buses["motor"] if merged else _weighted_sum(buses, gains_db), delays, gains)
    robot *= np.float32(scale)
    return {"robot": robot}


def _weighted_sum(buses: dict[str, np.ndarray], gains_db: dict[str, float]) -> np.ndarray:
    """Sum of the buses, each times its gain (in the buses' order)."""
    total = np.zeros_like(buses["motor"])
    for name, bus in buses.items():
        total += bus * np.float32(10.0 ** (gains_db[name] / 20.0))
    return total


def _impact_stem(trace: Trace, config: AudioConfig, seed: int, scale: float) -> np.ndarray:
    """(2, n) collision impacts and scrapes at the mics, times `scale` and `gain_impacts_db`."""
    impacts = _impacts(trace, config.sample_rate, seed, config.speed_of_sound)
    impacts *= np.float32(scale * 10.0 ** (config.gain_impacts_db / 20.0))
    return impacts


def _room(trace: Trace, config: AudioConfig, seed: int, n: int) -> Room | None:
    """The room that reverberates an indoor episode; None outdoors or with `rt60_s` 0."""
    if trace.environment == "indoor" and config.rt60_s > 0:
        return Room(config.rt60_s, config.sample_rate, n, _rng(seed, "room"))
    return None


def _nearfield(
    trace: Trace, config: AudioConfig, seed: int, n: int, room_gain: float, with_send: bool
) -> tuple[np.ndarray, np.ndarray] | None:
    """(2, n) near-field events and their mono room send (times `room_gain`), or None when there are none."""
    if not (config.ambience and config.nearfield_rate_hz > 0):
        return None
    listener = nf.Listener(np.asarray(trace.time, dtype=np.float64), np.asarray(trace.mic_pos))
    near, near_send = nf.render_nearfield(
        listener, trace.environment, trace.surface, n, config, _rng(seed, "nearfield"), with_send
    )
    near_send *= np.float32(room_gain / REF_DISTANCE)  # send per source power (see synth_audio.nearfield)
    return near, near_send


def _room_send(
    room: Room,
    stems: dict[str, np.ndarray],
    near: tuple[np.ndarray, np.ndarray] | None,
    room_gain: float,
    n: int,
    separate: bool,
) -> np.ndarray:
    """Send spectrum of the room: the stems so far (robot, impacts), mono, times `room_gain`.

    The near-field events' send joins it (one inverse FFT for every reverberation), unless `separate`
    (stems asked for): then their reverberation is added to the near-field signal itself, in place.
    """
    dry = np.zeros(n, dtype=np.float32)
    for part in stems.values():
        dry += part[0]
        dry += part[1]
    dry *= np.float32(0.5 * room_gain)
    if near is not None and near[1].size:
        signal, send = near
        if separate:  # the near-field events' reverberation belongs to their own stem
            signal += room.apply(send)
        else:
            dry += send
    return room.send_spectrum(dry)


def _ambience(
    trace: Trace,
    config: AudioConfig,
    seed: int,
    n: int,
    room: Room | None,
    room_spectrum: np.ndarray | None,
) -> np.ndarray:
    """(2, n) environment at `snr_db` below the reference level (with its distant sources' reverberation).

    With a room, the distant sources' reverberation is in the returned stem when stems are asked for;
    otherwise it is added to `room_spectrum` in place (one inverse FFT for every reverberation).
    """
    env, env_send = _raw_ambience(trace, config, seed, n)
    env_spectrum, level = _distant_sources(env, env_send, room, n)
    target = 10.0 ** (config.reference_level_dbfs / 20.0) * 10.0 ** (-config.snr_db / 20.0)
    gain = target / level if level > 0 else 0.0
    env *= np.float32(gain)
    if room is not None and env_spectrum is not None:
        env_spectrum *= np.complex64(gain)
        if config.stems:
            env += room.wet(env_spectrum)
        elif room_spectrum is not None:  # one inverse FFT for the robot's and the rooms' reverberation
            room_spectrum += env_spectrum
    return env


def _raw_ambience(trace: Trace, config: AudioConfig, seed: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(2, n) unscaled dry ambience of the trace's environment and its mono reverberation send (reduced
    rate; empty outdoors)."""
    robot = trace.robot
    scene = amb.Scene(
        n, config.sample_rate, np.asarray(robot.mic_pos_body, dtype=np.float64), mic_axes(robot.mic_pos_body),
        config.speed_of_sound, _world_to_body(trace),
    )  # fmt: skip
    env_rng = _rng(seed, "ambience")
    if trace.environment == "indoor":
        return amb.indoor(scene, env_rng, config.door_rate_hz, DECIMATION)
    return amb.outdoor(scene, env_rng, config.bird_rate_hz)


def _distant_sources(
    env: np.ndarray, env_send: np.ndarray, room: Room | None, n: int
) -> tuple[np.ndarray | None, float]:
    """The send spectrum of the ambience's distant sources (None without a room) and the ambience's RMS.

    With a room, the RMS counts their reverberation (Parseval); without one, they are added to `env` dry,
    in place.
    """
    env_spectrum = None
    energy = kernels.sum_squares(env.reshape(-1))
    if env_send.size and room is not None:
        env_spectrum = room.send_spectrum_low(env_send)
        energy += room.wet_energy(env_spectrum)
    elif env_send.size:  # no reverberation asked for: the distant sources arrive dry
        t_low = np.arange(env_send.size) * DECIMATION
        env += np.interp(np.arange(n), t_low, env_send).astype(np.float32)[None, :]
        energy = kernels.sum_squares(env.reshape(-1))
    return env_spectrum, float(np.sqrt(energy / env.size))


def _mic_noise(config: AudioConfig, seed: int, n: int) -> np.ndarray:
    """(2, n) microphone self-noise, independent per channel, at `mic_noise_dbfs`."""
    noise_rng = _rng(seed, "mic_noise")
    noise = np.empty((2, n), dtype=np.float32)
    for row in noise:
        white(noise_rng, n, row)
    noise *= np.float32(10.0 ** (config.mic_noise_dbfs / 20.0))
    return noise


def _mixdown(stems: dict[str, np.ndarray], config: AudioConfig, n: int) -> Audio:
    """The Audio: the stems added in order (and limited), plus every `STEM_NAMES` stem if asked for."""
    parts = list(stems.values())
    mix = parts[0].copy() if config.stems else parts[0]  # the first stem's buffer is free to reuse
    samples = np.empty((n, 2), dtype=np.float32)
    knee = _LIMIT_KNEE if config.limiter else math.inf
    for a in range(0, n, _MIX_CHUNK):  # each chunk's partial sum stays in cache while the stems are added
        block = mix[:, a : a + _MIX_CHUNK]
        for part in parts[1:]:
            block += part[:, a : a + _MIX_CHUNK]
        # a monotonic soft limiter (identity below the knee, tanh towards full scale above it), as the
        # channels are interleaved into the samples
        kernels.limit_interleave(block, knee, samples[a : a + _MIX_CHUNK])
    out_stems: dict[str, np.ndarray] = {}
    if config.stems:
        zero = np.zeros((n, 2), dtype=np.float32)
        out_stems = {
            name: np.ascontiguousarray(stems[name].T, dtype=np.float32) if name in stems else zero.copy()
            for name in STEM_NAMES
        }
    return Audio(samples=samples, sample_rate=config.sample_rate, stems=out_stems)
