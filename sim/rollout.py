"""`simulate(scenario) -> Trace`: build the world, drive the route, record everything, label it."""

from __future__ import annotations

import mmap

import numpy as np

from sim.driving import RouteController
from sim.engine import CONTROL_STEPS, Engine, yaw_of
from sim.events import contact_events, labels, merge_gap_steps, transient_events
from sim.faults import fault_records, strikes_of
from sim.imu import imu_samples
from sim.scenario import Scenario
from sim.trace import FaultStrikes, Trace
from sim.world import SensorSlices, World, build_world


def simulate(scenario: Scenario, world: World | None = None) -> Trace:
    """Simulate one episode; the same scenario gives the same trace, bit for bit.

    Args:
        scenario: the validated scenario.
        world: a world already built from this scenario (built here when None).
    """
    world = world if world is not None else build_world(scenario)
    engine = Engine(world, scenario)
    sensordata = run_route(engine, scenario)
    return assemble_trace(scenario, world, sensordata, engine.dt, strikes_of(engine.forcings))


def steps_for(scenario: Scenario, dt: float) -> int:
    """Physics steps of an episode: a whole number of IMU samples covering the duration."""
    per_sample = max(1, round(1.0 / (scenario.sensors.imu_rate * dt)))
    samples = max(1, int(np.ceil(scenario.duration / (per_sample * dt) - 1e-9)))
    return samples * per_sample


RECORD_PERIODS = 32
"""Control periods whose sensors the recording buffer holds (512 steps, about 0.5 MB: it stays in the CPU's
cache) before they are moved to the episode's per-signal arrays (more if a gap that merges contacts into one
event, `sim.events.MERGE_GAP`, were longer: the sparse contact arrays rely on it, see `Recording`)."""


class Recording:
    """The physics-rate sensors of an episode, as `run_route` records them.

    The stepper writes every step's row of sensors into `buffer` (a few control periods, in the CPU's
    cache); `move` then copies the signals (the sensors up to the contact sensors, which follow them) to one
    (n, width of the signals) array in one copy of whole rows, of which each signal is a column view
    (`cols`: what `assemble_trace` takes apart), so there is no (n, row width) array. The contact sensors
    (`contact`: per obstacle or wheel, found count, net force, centroid) are kept densely for the found
    counts only; force and centroid are copied for the blocks (the buffer's length) in which a contact was
    found and stay 0 elsewhere (their array is made at the first such block: a sensor that never finds a
    contact reads as a read-only view of zeros). `contact_events` and
    `transient_events` read them only inside runs of found contacts (gaps shorter than `MERGE_GAP` merged),
    which never reach a block without one, so the events are the same as from the full arrays. The tyres'
    floor contacts, the last sensors, are the step loop's (`sim.tyre`) and are not recorded.
    """

    def __init__(self, n: int, sl: SensorSlices, w: int, k: int, periods: int) -> None:
        self.n = n
        """Physics steps."""
        groups = (
            (sl.wheel_angle, w),
            (sl.wheel_speed, w),
            (sl.wheel_torque, w),
            (sl.base_pos, 3),
            (sl.base_quat, 4),
            (sl.base_linvel, 3),
            (sl.base_angvel, 3),
            (sl.acc, 3),
            (sl.vel, 3),
            (sl.mic, 6),
            (sl.obstacle_pos, 3 * k),
        )
        contacts = ((sl.obstacle_contact, k), (sl.transient_contact, w))
        spans = sorted([*groups, *((start, 7 * count) for start, count in contacts)])
        ends = [0] + [start + width for start, width in spans]
        # the tyres' floor contacts follow, read by the step loop (`sim.tyre`) and not recorded
        if [start for start, _ in spans] != ends[:-1] or ends[-1] != sl.tyre_contact:
            raise RuntimeError(f"the recorded signals {spans} do not tile the first {sl.tyre_contact} values")
        self.buffer = np.empty((periods * CONTROL_STEPS, sl.width))
        """Where the stepper writes: (periods x CONTROL_STEPS, row width)."""
        self.done = 0
        """Steps moved from `buffer` to the arrays."""
        first = min(start for start, _ in groups)
        self._width = max(start + width for start, width in groups)
        if first != 0 or sum(width for _, width in groups) != self._width:
            raise RuntimeError(f"the signals {groups} are not the first {self._width} sensor values")
        self._signal_block = np.empty((n, self._width))
        self._signals = {start: self._signal_block[:, start : start + width] for start, width in groups}
        self._found = {start: np.empty((n, count)) for start, count in contacts}
        self._values: dict[int, np.ndarray] = {}  # made at the first block with a contact (`move`)
        buffer = self.buffer
        self._contact_moves = [
            (
                start,
                self._found[start],
                buffer[:, start : start + 7 * count : 7],
                buffer[:, start : start + 7 * count],
            )
            for start, count in contacts
        ]

    def move(self, stop: int) -> None:
        """Copy the buffer's first `stop - done` rows (steps done to stop of the episode) to the arrays."""
        start, rows = self.done, stop - self.done
        self._signal_block[start:stop] = self.buffer[:rows, : self._width]  # every signal, in one copy
        for at, found, found_column, value_columns in self._contact_moves:
            block = found[start:stop]
            block[:] = found_column[:rows]
            if block.any():  # found counts are whole numbers >= 0
                values = self._values.get(at)
                if values is None:
                    values = self._values[at] = _untouched_zeros((self.n, value_columns.shape[1]))
                values[start:stop] = value_columns[:rows]
        self.done = stop

    def cols(self, start: int, width: int) -> np.ndarray:
        """The (n, width) sensors of the signal at sensordata[start] (not a contact sensor): a view of the
        signals' array."""
        array = self._signals[start]
        if array.shape[1] != width:
            raise ValueError(f"no recorded signal of width {width} at sensordata[{start}]")
        return array

    def contact(self, start: int, count: int) -> tuple[np.ndarray, np.ndarray]:
        """The `count` contact sensors at sensordata[start]: found counts (n, count) and (n, count, 7) values
        (found, force, centroid; force and centroid only in blocks with a contact, see the class)."""
        found = self._found[start]
        if found.shape[1] != count:
            raise ValueError(f"no {count} contact sensors at sensordata[{start}]")
        values = self._values.get(start)
        if values is None:  # no contact in the episode: zeros, as the copied blocks would have left
            return found, np.broadcast_to(np.zeros(()), (self.n, count, 7))
        return found, values.reshape(self.n, count, 7)


def run_route(engine: Engine, scenario: Scenario) -> Recording:
    """Drive the scenario's route; returns the sensors after every physics step.

    Per control period: the pose from the last step's sensors, the contacts of the period before, the
    controller's command, and `CONTROL_STEPS` physics steps (`sim.stepper`) into a slot of the recording
    buffer (the views the next period reads of each slot are made once, not every period).
    """
    world = engine.world
    sl = world.sensors
    n = steps_for(scenario, engine.dt)
    k_obs = len(world.obstacles)
    merge_gap = merge_gap_steps(engine.dt)  # the longest gap inside a contact event, steps
    periods = max(RECORD_PERIODS, merge_gap // CONTROL_STEPS + 2)  # a block is longer than the gap
    record = Recording(n, sl, world.n_wheels, k_obs, periods)
    pose_at, targets_at, found_at = sl.base_pos, sl.obstacle_pos, sl.obstacle_contact
    if sl.base_quat != pose_at + 3 or found_at != targets_at + 3 * k_obs:
        raise RuntimeError("unexpected sensordata layout")
    found_end = found_at + 7 * k_obs
    slots = [record.buffer[i * CONTROL_STEPS : (i + 1) * CONTROL_STEPS] for i in range(periods)]
    slot_found = [out[:, found_at:found_end:7] for out in slots]  # contact counts (steps, K)
    slot_pose = [out[-1, pose_at : pose_at + 7] for out in slots]  # base position, then orientation
    slot_targets = [out[-1, targets_at:found_at].reshape(k_obs, 3)[:, :2] for out in slots]
    live = np.zeros(k_obs, dtype=bool)
    live[engine.ped_index.astype(np.int64)] = True
    footprints = np.array([[ob.size[0], ob.size[1], ob.yaw] for ob in world.obstacles]).reshape(k_obs, 3)
    controller = RouteController(
        scenario.route, live_mask=live, footprints=footprints, reach=world.bumper_reach
    )
    command = controller.command
    wheel_commands = engine.wheel_commands
    step = engine.step
    period = CONTROL_STEPS * engine.dt
    sd = engine.sensordata
    pose_now = sd[pose_at : pose_at + 7]
    targets = sd[targets_at:found_at].reshape(k_obs, 3)[:, :2]
    found = slot_found[0]  # contact counts of the period before (read only after a contact)
    contact = False  # whether the robot touched an obstacle in the period before
    for p, start in enumerate(range(0, n, CONTROL_STEPS)):
        slot = p % periods
        if slot == 0 and start > 0:  # buffer full: move it to the arrays, start again at its top
            record.move(start)
        x, y, _, qw, qx, qy, qz = pose_now.tolist()
        pose = (x, y, yaw_of((qw, qx, qy, qz)))
        if contact:  # in the period before
            for ob in np.flatnonzero(found.any(axis=0) & live):
                engine.step_back(int(ob), pose)  # a pedestrian who is bumped steps back and stands
        v, w = command(engine.time, pose, contact, targets, period)
        k = min(CONTROL_STEPS, n - start)
        contact = step(wheel_commands(v, w), slots[slot] if k == CONTROL_STEPS else slots[slot][:k])
        found, pose_now, targets = slot_found[slot], slot_pose[slot], slot_targets[slot]
    record.move(n)
    return record


def assemble_trace(
    scenario: Scenario,
    world: World,
    sd: np.ndarray | Recording,
    dt: float,
    strikes: FaultStrikes | None = None,
) -> Trace:
    """Turn recorded sensors into a Trace: IMU with noise, events, fault records and labels.

    Args:
        sd: (n, row width) sensors after every physics step, or `run_route`'s recording of them.
        strikes: the strikes the faults' physics applied (`sim.faults.strikes_of`); None: none.
    """
    sl = world.sensors
    w = world.n_wheels
    k = len(world.obstacles)
    n = sd.n if isinstance(sd, Recording) else sd.shape[0]
    time = dt * np.arange(1, n + 1)

    def cols(start: int, width: int) -> np.ndarray:
        if isinstance(sd, Recording):
            return sd.cols(start, width)
        return np.ascontiguousarray(sd[:, start : start + width])

    def contact(start: int, count: int) -> tuple[np.ndarray, np.ndarray]:
        """Found counts (n, count) and (n, count, 7) values of `count` contact sensors."""
        if isinstance(sd, Recording):
            return sd.contact(start, count)
        values = cols(start, 7 * count).reshape(n, count, 7)
        return values[:, :, 0], values

    base_linvel = cols(sl.base_linvel, 3)
    imu = imu_samples(
        time, cols(sl.acc, 3), cols(sl.base_angvel, 3), cols(sl.vel, 3), scenario.sensors, scenario.seed
    )
    ob_pos = cols(sl.obstacle_pos, 3 * k).reshape(n, k, 3)
    ob_vel = _velocities(ob_pos, dt, world.obstacle_free | (world.obstacle_mocap >= 0))
    found, hits = contact(sl.obstacle_contact, k)
    contacts, event_runs = contact_events(
        found, hits[:, :, 1:4], hits[:, :, 4:7], base_linvel, ob_vel, world.obstacles, dt
    )
    found, bumps = contact(sl.transient_contact, w)
    transients = transient_events(found, bumps[:, :, 1:4], bumps[:, :, 4:7], scenario, dt)
    info = world.robot.info
    faults = fault_records(scenario, info)
    factor = n // len(imu.time)
    label, sub, wheel = labels(imu.time, event_runs, world.obstacles, faults, dt)
    return Trace(
        scenario_name=scenario.name,
        seed=scenario.seed,
        environment=scenario.environment,
        surface=scenario.surface,
        duration=float(time[-1]),
        physics_dt=dt,
        imu_rate=float(scenario.sensors.imu_rate),
        robot=info,
        arena_half_size=np.asarray(scenario.arena, dtype=np.float64),
        time=time,
        wheel_angle=cols(sl.wheel_angle, w),
        wheel_speed=cols(sl.wheel_speed, w),
        wheel_torque=cols(sl.wheel_torque, w),
        base_pos=cols(sl.base_pos, 3),
        base_quat=cols(sl.base_quat, 4),
        base_linvel=base_linvel,
        base_angvel=cols(sl.base_angvel, 3),
        mic_pos=cols(sl.mic, 6).reshape(n, 2, 3),
        imu_time=imu.time,
        imu_vel_z=imu.vel_z,
        imu_acc=imu.acc,
        imu_gyro=imu.gyro,
        contacts=contacts,
        transients=transients,
        faults=faults,
        fault_strikes=strikes if strikes is not None else FaultStrikes.empty(),
        obstacles=world.obstacles,
        obstacle_pos=np.ascontiguousarray(ob_pos[factor - 1 :: factor][: len(imu.time)]),
        label=label,
        sub_kind=sub,
        label_wheel=wheel,
    )


def _velocities(pos: np.ndarray, dt: float, movable: np.ndarray) -> np.ndarray:
    """`np.gradient(pos, dt, axis=0)` of (n, K, 3) obstacle positions, computed for the `movable` (K,)
    obstacles (free bodies, pedestrians) only: a fixed body's position is the same every step, and
    np.gradient's differences of equal values are +0.0, what the others get."""
    vel = _untouched_zeros(pos.shape)
    moving = np.flatnonzero(movable)
    if len(pos) > 1 and len(moving):
        vel[:, moving] = np.gradient(pos[:, moving], dt, axis=0)
    return vel


def _untouched_zeros(shape: tuple[int, ...]) -> np.ndarray:
    """A float64 array of zeros in a private anonymous memory mapping: the kernel zero-fills each page when
    it is first touched, so the parts never written cost neither time nor memory (np.zeros' calloc fills
    memory it reuses from the heap, all of it, at once). Small arrays, and systems without anonymous
    mappings, get np.zeros."""
    count = int(np.prod(shape))
    flags = getattr(mmap, "MAP_PRIVATE", 0) | getattr(mmap, "MAP_ANONYMOUS", 0)
    if count * 8 < mmap.PAGESIZE * 64 or not hasattr(mmap, "MAP_ANONYMOUS"):
        return np.zeros(shape)
    memory = mmap.mmap(-1, count * 8, flags=flags)
    return np.frombuffer(memory, dtype=np.float64, count=count).reshape(shape)
