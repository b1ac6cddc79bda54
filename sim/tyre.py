"""The tyres' grip: a regularised Coulomb law applied in the compiled step loop (`sim.stepper`).

MuJoCo solves each wheel's floor contact for its normal force only (an explicit contact pair of one
dimension, `sim.world`); the tangential force is this law's. At the contact point the wheel's material
slides over the floor at the slip velocity u (the point's velocity less its normal part); the floor pushes
back with F = -mu N tanh(|u| / V0) u / |u|, full Coulomb friction once the slip exceeds a few V0 and a
stiff viscous grip below (a tyre's carcass deflects before its tread slides). The law is applied linearly
implicitly per wheel, F / (1 + dt g dF/du), with g a bound on the contact point's inverse mass, so that the
stiff grip neither overshoots nor rings at the physics step.

Before each step the loop reads the wheel's floor contact (normal force, centroid) and the bodies' poses as
the last step left them, and the velocities the step starts from: the point where the grip acts lags a step
(millimetres), the slip it answers does not.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import mujoco
import numpy as np

if TYPE_CHECKING:
    from sim.world import World

TYRE_SLIP_SPEED = 0.03
"""V0: slip speed at which the grip reaches tanh(1) = 76 % of full Coulomb friction, m/s. A rubber tyre's
tread saturates at a few degrees of slip angle: 3 cm/s of lateral slip is 3.4 degrees at 0.5 m/s."""


@dataclass(frozen=True)
class Tyres:
    """What the step loop needs of each driven wheel's tyre."""

    table: np.ndarray
    """(W, 6) float64: wheel body id, wheel dof address, wheel joint id, first sensordata index of the
    wheel's floor contact sensor (found, net force, centroid), friction coefficient, inverse mass bound."""
    root: np.ndarray
    """(2,) float64: the robot's root body id and its free joint's first dof address."""


def tyres(world: World, data: mujoco.MjData) -> Tyres:
    """The tyres of a world at the state `data` holds (evaluated by `mj_forward`): each wheel's friction
    (its floor pair's) and the largest row sum of J M^-1 J^T at its lowest point (Gershgorin: at least the
    largest eigenvalue of the point's inverse mass)."""
    model = world.model
    sensor = world.sensors.tyre_contact
    rows = []
    jacp = np.zeros((3, model.nv))
    jacr = np.zeros((3, model.nv))
    wheels = zip(world.wheel_body, world.wheel_dof, world.wheel_geom, strict=True)
    for w, (body, dof, geom) in enumerate(wheels):
        pair = next(p for p in range(model.npair) if int(model.pair_geom2[p]) == int(geom))
        point = data.geom_xpos[geom] - np.array([0.0, 0.0, model.geom_size[geom, 0]])
        mujoco.mj_jac(model, data, jacp, jacr, point, int(body))
        minv_j = np.zeros((3, model.nv))
        mujoco.mj_solveM(model, data, minv_j, jacp)
        inverse_mass = float(np.abs(jacp @ minv_j.T).sum(axis=1).max())
        joint = int(model.dof_jntid[dof])
        rows.append([body, dof, joint, sensor + 7 * w, float(model.pair_friction[pair, 0]), inverse_mass])
    root = [float(model.dof_bodyid[world.root_dof]), float(world.root_dof)]
    return Tyres(np.array(rows, dtype=np.float64), np.array(root))
