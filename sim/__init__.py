"""The MuJoCo robot simulator: scenarios, world building, driving, faults, rollout and environments.

`from sim import Scenario, simulate`; `simulate(scenario) -> Trace`. Importing `sim` registers the
Gymnasium environment `robot_anomaly/DiffDrive-v0`.
"""

import os

# dm_control picks an OpenGL backend on import; the simulator never renders, so default to none.
os.environ.setdefault("MUJOCO_GL", "disable")

from sim.envs import DiffDriveEnv, make_dm_env, make_env, register_envs
from sim.random_scenarios import ScenarioOptions, draw_scenario, scenario_presets
from sim.rollout import simulate
from sim.scenario import (
    Fault,
    Obstacle,
    Reflex,
    Route,
    Scenario,
    ScenarioError,
    Sensors,
    Transient,
    Unit,
    Waypoint,
)
from sim.trace import (
    ContactEvents,
    FaultRecord,
    ObstacleRecord,
    RobotInfo,
    Trace,
    TraceError,
    TransientEvents,
)

register_envs()

__all__ = [
    "ContactEvents",
    "DiffDriveEnv",
    "Fault",
    "FaultRecord",
    "Obstacle",
    "ObstacleRecord",
    "Reflex",
    "RobotInfo",
    "Route",
    "Scenario",
    "ScenarioError",
    "ScenarioOptions",
    "Sensors",
    "Trace",
    "TraceError",
    "Transient",
    "TransientEvents",
    "Unit",
    "Waypoint",
    "draw_scenario",
    "make_dm_env",
    "make_env",
    "scenario_presets",
    "simulate",
]
