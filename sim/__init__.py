"""The MuJoCo robot simulator: scenarios, world building, driving, faults, rollout and environments."""

from sim.trace import (
    ContactEvents,
    FaultRecord,
    ObstacleRecord,
    RobotInfo,
    Trace,
    TraceError,
    TransientEvents,
)

__all__ = [
    "ContactEvents",
    "FaultRecord",
    "ObstacleRecord",
    "RobotInfo",
    "Trace",
    "TraceError",
    "TransientEvents",
]
