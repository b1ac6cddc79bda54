"""`simulate(scenario) -> Trace`: build the world, drive the route, record everything, label it."""

from __future__ import annotations

import numpy as np

from sim.driving import RouteController
from sim.engine import CONTROL_STEPS, Engine, yaw_of
from sim.events import contact_events, labels, transient_events
from sim.faults import fault_record
from sim.imu import imu_samples
from sim.scenario import Scenario
from sim.trace import Trace
from sim.world import World, build_world


def simulate(scenario: Scenario, world: World | None = None) -> Trace:
    """Simulate one episode; the same scenario gives the same trace, bit for bit.

    Args:
        scenario: the validated scenario.
        world: a world already built from this scenario (built here when None).
    """
    world = world if world is not None else build_world(scenario)
    engine = Engine(world, scenario)
    sensordata = run_route(engine, scenario)
    return assemble_trace(scenario, world, sensordata, engine.dt)


def steps_for(scenario: Scenario, dt: float) -> int:
    """Physics steps of an episode: a whole number of IMU samples covering the duration."""
    per_sample = max(1, round(1.0 / (scenario.sensors.imu_rate * dt)))
    samples = max(1, int(np.ceil(scenario.duration / (per_sample * dt) - 1e-9)))
    return samples * per_sample


def run_route(engine: Engine, scenario: Scenario) -> np.ndarray:
    """Drive the scenario's route; returns (n, nsensordata) sensors after every physics step."""
    world = engine.world
    sl = world.sensors
    n = steps_for(scenario, engine.dt)
    k_obs = len(world.obstacles)
    out = np.empty((n, world.model.nsensordata))
    found_cols = sl.obstacle_contact + 7 * np.arange(k_obs)
    live = np.zeros(k_obs, dtype=bool)
    live[engine.ped_index.astype(np.int64)] = True
    footprints = np.array([[ob.size[0], ob.size[1], ob.yaw] for ob in world.obstacles]).reshape(k_obs, 3)
    controller = RouteController(
        scenario.route, live_mask=live, footprints=footprints, reach=world.bumper_reach
    )
    period = CONTROL_STEPS * engine.dt
    pos_cols = (sl.obstacle_pos + 3 * np.arange(k_obs)[:, None] + np.arange(2)[None, :]).ravel()
    prev = 0
    for start in range(0, n, CONTROL_STEPS):
        k = min(CONTROL_STEPS, n - start)
        sd = engine.sensordata
        pose = (
            float(sd[sl.base_pos]),
            float(sd[sl.base_pos + 1]),
            yaw_of(sd[sl.base_quat : sl.base_quat + 4]),
        )
        touched = (out[prev:start, found_cols] > 0).any(axis=0) if start > 0 else np.zeros(k_obs, dtype=bool)
        contact = bool(touched.any())
        for ob in np.flatnonzero(touched & live):
            engine.step_back(int(ob), pose)  # a pedestrian who is bumped steps back and stands
        targets = sd[pos_cols].reshape(k_obs, 2)
        v, w = controller.command(engine.time, pose, contact, targets, period)
        engine.step(engine.wheel_commands(v, w), out[start : start + k])
        prev = start
    return out


def assemble_trace(scenario: Scenario, world: World, sd: np.ndarray, dt: float) -> Trace:
    """Turn recorded sensors into a Trace: IMU with noise, events, fault records and labels."""
    sl = world.sensors
    w = world.n_wheels
    k = len(world.obstacles)
    n = sd.shape[0]
    time = dt * np.arange(1, n + 1)

    def cols(start: int, width: int) -> np.ndarray:
        return np.ascontiguousarray(sd[:, start : start + width])

    base_linvel = cols(sl.base_linvel, 3)
    imu = imu_samples(
        time, cols(sl.acc, 3), cols(sl.base_angvel, 3), cols(sl.vel, 3), scenario.sensors, scenario.seed
    )
    ob_pos = cols(sl.obstacle_pos, 3 * k).reshape(n, k, 3)
    ob_vel = np.gradient(ob_pos, dt, axis=0) if n > 1 else np.zeros_like(ob_pos)
    hits = cols(sl.obstacle_contact, 7 * k).reshape(n, k, 7)
    contacts, event_runs = contact_events(
        hits[:, :, 0], hits[:, :, 1:4], hits[:, :, 4:7], base_linvel, ob_vel, world.obstacles, dt
    )
    bumps = cols(sl.transient_contact, 7 * w).reshape(n, w, 7)
    transients = transient_events(bumps[:, :, 0], bumps[:, :, 1:4], bumps[:, :, 4:7], scenario, dt)
    info = world.robot.info
    faults = tuple(fault_record(f, info, float(time[-1])) for f in scenario.faults)
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
        obstacles=world.obstacles,
        obstacle_pos=np.ascontiguousarray(ob_pos[factor - 1 :: factor][: len(imu.time)]),
        label=label,
        sub_kind=sub,
        label_wheel=wheel,
    )
