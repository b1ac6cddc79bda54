"""Analytic Traces for the audio tests: given wheel speeds, contacts, transients and faults."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from sim.trace import ContactEvents, FaultRecord, RobotInfo, Trace, TransientEvents
from sim.vocab import TRANSIENT_HEIGHT

DT = 0.002
WHEELS = ("front_left", "front_right", "back_left", "back_right")


def robot(unit_id: int = 0) -> RobotInfo:
    """A skid-steer unit: x forward, y left; wheels at +-0.15 m, mics at the front corners."""
    return RobotInfo(
        model="skid4",
        unit_id=unit_id,
        mass=12.0,
        wheel_names=WHEELS,
        wheel_radius=np.full(4, 0.06),
        wheel_pos_body=np.array(
            [[0.15, 0.17, 0.0], [0.15, -0.17, 0.0], [-0.15, 0.17, 0.0], [-0.15, -0.17, 0.0]]
        ),
        mic_pos_body=np.array([[0.2, 0.1, 0.12], [0.2, -0.1, 0.12]]),
        imu_pos_body=np.zeros(3),
        gear_ratio=30.0,
        pinion_teeth=12,
        motor_pole_pairs=2,
        pwm_hz=16000.0,
        tread_blocks=24,
        track=0.34,
        wheelbase=0.3,
    )


def contacts(
    times: Sequence[float] = (),
    impulses: Sequence[float] | None = None,
    positions: Sequence[Sequence[float]] | None = None,
    materials: Sequence[str] | None = None,
    durations: Sequence[float] | None = None,
    normal_speed: float = 0.5,
) -> ContactEvents:
    """Contact events (world frame; the robot sits at the origin facing +x)."""
    k = len(times)
    pos = np.asarray(positions if positions is not None else [[0.25, 0.0, 0.1]] * k, dtype=float).reshape(
        k, 3
    )
    return ContactEvents(
        time=np.asarray(times, dtype=float),
        position=pos,
        normal=np.tile([-1.0, 0.0, 0.0], (k, 1)),
        impulse=np.asarray(impulses if impulses is not None else [2.0] * k, dtype=float),
        normal_speed=np.full(k, normal_speed),
        duration=np.asarray(durations if durations is not None else [0.01] * k, dtype=float),
        obstacle_kind=tuple("wall" for _ in range(k)),
        material=tuple(materials if materials is not None else ["plaster"] * k),
    )


def transients(
    times: Sequence[float] = (),
    wheels: Sequence[int] = (),
    impulses: Sequence[float] = (),
    kinds: Sequence[str] = (),
) -> TransientEvents:
    """Benign transient events."""
    k = len(times)
    return TransientEvents(
        time=np.asarray(times, dtype=float),
        position=np.zeros((k, 3)),
        wheel=np.asarray(wheels, dtype=np.int64),
        impulse=np.asarray(impulses, dtype=float),
        kind=tuple(kinds),
        height=np.array([TRANSIENT_HEIGHT[k] for k in kinds], dtype=float),
    )


def make_trace(
    duration: float = 2.0,
    wheel_speed: float | Callable[[np.ndarray], np.ndarray] = 10.0,
    torque: float = 0.7,
    environment: str = "indoor",
    surface: str = "tile",
    contact_events: ContactEvents | None = None,
    transient_events: TransientEvents | None = None,
    faults: tuple[FaultRecord, ...] = (),
    unit_id: int = 0,
) -> Trace:
    """A robot standing at the origin facing +x whose four wheels all turn at `wheel_speed` rad/s.

    `wheel_speed` may be a function of time (rad/s); the wheel angle is its exact integral.
    """
    t = np.arange(0.0, duration + DT / 2, DT)
    n = t.size
    if callable(wheel_speed):
        omega = np.asarray(wheel_speed(t), dtype=float)
    else:
        omega = np.full(n, float(wheel_speed))
    angle = np.concatenate([[0.0], np.cumsum(0.5 * (omega[1:] + omega[:-1]) * DT)])
    rob = robot(unit_id)
    mic = np.broadcast_to(rob.mic_pos_body, (n, 2, 3)).copy()
    m = int(duration * 200) + 1
    return Trace(
        scenario_name="analytic",
        seed=0,
        environment=environment,
        surface=surface,
        duration=duration,
        physics_dt=DT,
        imu_rate=200.0,
        robot=rob,
        arena_half_size=np.array([5.0, 5.0]),
        time=t,
        wheel_angle=np.tile(angle[:, None], (1, 4)),
        wheel_speed=np.tile(omega[:, None], (1, 4)),
        wheel_torque=np.full((n, 4), torque) * (omega[:, None] != 0),
        base_pos=np.zeros((n, 3)),
        base_quat=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)),
        base_linvel=np.zeros((n, 3)),
        base_angvel=np.zeros((n, 3)),
        mic_pos=mic,
        imu_time=np.arange(m) / 200.0,
        imu_vel_z=np.zeros(m),
        imu_acc=np.zeros((m, 3)),
        imu_gyro=np.zeros((m, 3)),
        contacts=contact_events if contact_events is not None else contacts(),
        transients=transient_events if transient_events is not None else transients(),
        faults=faults,
        obstacles=(),
        obstacle_pos=np.zeros((m, 0, 3)),
        label=np.zeros(m, np.int8),
        sub_kind=np.zeros(m, np.int16),
        label_wheel=-np.ones(m, np.int8),
    )
