"""Gymnasium and dm_env environments over the same simulation (world, engine, faults, contact sensors).

Action: left and right wheel speed commands in [-1, 1] (scaled to `max_wheel_speed` rad/s). Observation:
the IMU (3-axis accelerometer, 3-axis gyro, z-velocity, with noise and bias) and the wheel state
(speeds and torques). Info: the label of the step (normal / collision / mechanical, sub-kind, wheel)
and the robot-obstacle contacts of the step. One step is one 40 ms control period.

The observables come from the same code as `sim.simulate`'s trace: the IMU observation is the last IMU
sample of the step, decimated by `sim.imu.decimate` with the noise of `sim.imu.imu_noise` (the scenario's
seed, or the seed given to `reset`); the label is `sim.events.labels` at the step's end over the contacts so
far (so it matches the trace's label at that sample, except the 20 ms before first contact, which needs the
future).
"""

from __future__ import annotations

from typing import Any

import dm_env
import gymnasium as gym
import numpy as np
from dm_env import specs

from sim.engine import CONTROL_STEPS, Engine
from sim.events import extend_runs, labels, merge_gap_steps
from sim.faults import fault_records
from sim.imu import ImuNoise, decimate, decimation_factor, imu_noise
from sim.random_scenarios import ScenarioOptions, draw_scenario
from sim.rollout import steps_for
from sim.scenario import Scenario
from sim.vocab import SUB_KINDS
from sim.world import build_world

ENV_ID = "robot_anomaly/DiffDrive-v0"
"""Gymnasium id registered on `import sim`."""


OBS_LIMITS: dict[str, float] = {
    "acc": 160.0,
    "gyro": 35.0,
    "vel": 10.0,
    "wheel_speed": 120.0,
    "wheel_torque": 60.0,
}
"""Observation bounds (the IMU's full scale; wheel speed rad/s and torque N m), values are clipped to them."""


class DiffDriveEnv(gym.Env[np.ndarray, np.ndarray]):
    """A wheeled robot in a scenario's world, driven by left/right wheel speed commands."""

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012

    def __init__(
        self, scenario: Scenario | None = None, *, seed: int = 0, max_wheel_speed: float = 15.0
    ) -> None:
        """Build the world once; `reset` puts the robot back at the route start.

        Args:
            scenario: the world (obstacles, faults, surface, robot); a nominal indoor one when None.
            seed: seed of the default scenario.
            max_wheel_speed: wheel speed of an action of 1, rad/s.
        """
        self.scenario = (
            scenario
            if scenario is not None
            else draw_scenario(seed, "nominal", ScenarioOptions(duration=30.0))
        )
        self.world = build_world(self.scenario)
        self.engine = Engine(self.world, self.scenario)
        self.max_wheel_speed = float(max_wheel_speed)
        self.n_wheels = self.world.n_wheels
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        w = self.n_wheels
        self._high = np.array(
            [OBS_LIMITS["acc"]] * 3
            + [OBS_LIMITS["gyro"]] * 3
            + [OBS_LIMITS["vel"]]
            + [OBS_LIMITS["wheel_speed"]] * w
            + [OBS_LIMITS["wheel_torque"]] * w,
            dtype=np.float32,
        )
        self.observation_space = gym.spaces.Box(-self._high, self._high, dtype=np.float32)
        self._buffer = np.zeros((CONTROL_STEPS, self.world.sensors.width))
        self._factor = decimation_factor(self.scenario.sensors, self.engine.dt)
        self._n_samples = steps_for(self.scenario, self.engine.dt) // self._factor
        self._noise: ImuNoise = imu_noise(self._n_samples, self.scenario.sensors, self.scenario.seed)
        self._faults = fault_records(self.scenario, self.world.robot.info)
        self._contact_runs: list[list[tuple[int, int]]] = [[] for _ in self.world.obstacles]
        self._steps = 0
        self._left = np.array([1.0 if "left" in n else 0.0 for n in self.world.robot.info.wheel_names])

    def _observe(self, physics: np.ndarray) -> np.ndarray:
        """Observation from the physics-rate sensors of the step (`physics`: (k, row width))."""
        sl = self.world.sensors
        f = min(self._factor, physics.shape[0])
        tail = physics[-f:]

        def imu(start: int, width: int) -> np.ndarray:
            return decimate(tail[:, start : start + width], f)  # (1, width): the step's last sample

        done = round(self.engine.time / self.engine.dt) // self._factor  # IMU samples so far
        i = max(done - 1, 0) % self._n_samples  # past the scenario's duration the noise repeats
        acc, gyro, vel = self._noise.apply(
            imu(sl.acc, 3), imu(sl.base_angvel, 3), imu(sl.vel + 2, 1)[:, 0], slice(i, i + 1)
        )
        sd = self.engine.sensordata
        w = self.n_wheels
        wheels = np.concatenate(
            [sd[sl.wheel_speed : sl.wheel_speed + w], sd[sl.wheel_torque : sl.wheel_torque + w]]
        )
        obs = np.concatenate([acc[0], gyro[0], vel, wheels])
        return np.clip(obs, -self._high, self._high).astype(np.float32)

    def _info(self, contacts: list[dict[str, Any]]) -> dict[str, Any]:
        t = self.engine.time
        dt = self.engine.dt
        event_runs = [(a, b, k) for k, found in enumerate(self._contact_runs) for a, b in found]
        label, sub, wheel = labels(np.array([t]), event_runs, self.world.obstacles, self._faults, dt)
        return {
            "time": t,
            "label": int(label[0]),
            "sub_kind": SUB_KINDS[int(sub[0])],
            "label_wheel": int(wheel[0]),
            "contacts": contacts,
        }

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Put the robot back at the start. The IMU noise and bias are the scenario's (as `simulate` draws
        them) when `seed` is None, else drawn by the same code from `seed`."""
        super().reset(seed=seed)
        self.engine.reset()
        noise_seed = self.scenario.seed if seed is None else int(seed)
        self._noise = imu_noise(self._n_samples, self.scenario.sensors, noise_seed)
        self._contact_runs = [[] for _ in self.world.obstacles]
        self._steps = 0
        return self._observe(self.engine.sensordata[None, :]), self._info([])

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One 40 ms control period with wheel speed commands `action` (left, right) in [-1, 1]."""
        a = np.clip(np.asarray(action, dtype=np.float64).reshape(2), -1.0, 1.0) * self.max_wheel_speed
        cmd = np.where(self._left > 0, a[0], a[1])
        sl = self.world.sensors
        before = self.engine.sensordata[sl.base_pos : sl.base_pos + 2].copy()
        self.engine.step(cmd, self._buffer)
        k = len(self.world.obstacles)
        hits = self._buffer[:, sl.obstacle_contact : sl.obstacle_contact + 7 * k].reshape(-1, k, 7)
        gap = merge_gap_steps(self.engine.dt)
        for k, found in enumerate(self._contact_runs):  # the contact runs so far, extended by this step's
            extend_runs(found, self._steps + np.flatnonzero(hits[:, k, 0] > 0), gap)
        self._steps += hits.shape[0]
        touched = np.flatnonzero((hits[:, :, 0] > 0).any(axis=0))
        contacts = [
            {
                "obstacle_kind": self.world.obstacles[i].kind,
                "material": self.world.obstacles[i].material,
                "impulse": float(np.linalg.norm(hits[:, i, 1:4].sum(axis=0)) * self.engine.dt),
            }
            for i in touched
        ]
        after = self.engine.sensordata[sl.base_pos : sl.base_pos + 2]
        reward = float(np.linalg.norm(after - before)) - float(len(contacts))
        truncated = self.engine.time >= self.scenario.duration - 1e-9
        return self._observe(self._buffer), reward, False, bool(truncated), self._info(contacts)


class DiffDriveDmEnv(dm_env.Environment):
    """The same simulation as a dm_env.Environment (observations: `imu` and `wheels`)."""

    def __init__(self, scenario: Scenario | None = None, *, seed: int = 0) -> None:
        self._env = DiffDriveEnv(scenario, seed=seed)
        self._seed = seed
        self._needs_reset = True
        self.last_info: dict[str, Any] = {}

    def _split(self, obs: np.ndarray) -> dict[str, np.ndarray]:
        return {"imu": obs[:7], "wheels": obs[7:]}

    def reset(self) -> dm_env.TimeStep:
        """Start an episode (the seed given at construction drives the noise)."""
        obs, self.last_info = self._env.reset(seed=self._seed)
        self._needs_reset = False
        return dm_env.restart(self._split(obs))

    def step(self, action: np.ndarray) -> dm_env.TimeStep:
        """One control period; the episode ends (LAST) at the scenario's duration."""
        if self._needs_reset:
            return self.reset()
        obs, reward, terminated, truncated, self.last_info = self._env.step(action)
        if terminated or truncated:
            self._needs_reset = True
            return dm_env.truncation(reward, self._split(obs))
        return dm_env.transition(reward, self._split(obs))

    def observation_spec(self) -> dict[str, specs.Array]:
        """IMU (7) and wheel state (2 x wheels), float32."""
        w = self._env.n_wheels
        return {
            "imu": specs.Array((7,), np.float32, name="imu"),
            "wheels": specs.Array((2 * w,), np.float32, name="wheels"),
        }

    def action_spec(self) -> specs.BoundedArray:
        """Left and right wheel speed commands in [-1, 1]."""
        return specs.BoundedArray((2,), np.float32, -1.0, 1.0, name="wheel_speed")


def make_env(scenario: Scenario | None = None, *, seed: int = 0, **kwargs: Any) -> DiffDriveEnv:
    """The Gymnasium environment over a scenario (a nominal one from `seed` when None)."""
    return DiffDriveEnv(scenario, seed=seed, **kwargs)


def make_dm_env(scenario: Scenario | None = None, *, seed: int = 0) -> DiffDriveDmEnv:
    """The dm_env environment over a scenario (a nominal one from `seed` when None)."""
    return DiffDriveDmEnv(scenario, seed=seed)


def register_envs() -> None:
    """Register `robot_anomaly/DiffDrive-v0` with Gymnasium (idempotent)."""
    if ENV_ID not in gym.registry:
        gym.register(id=ENV_ID, entry_point="sim.envs:DiffDriveEnv")
