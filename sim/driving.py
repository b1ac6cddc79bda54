"""The route-following controller: speed profile with acceleration limits, turns, stops and ramming legs.

Called once per control period with the robot's pose and speed; returns the body speed and yaw rate
to command. A bumper reflex backs the robot off after any obstacle contact (how a collision leg ends).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sim.scenario import Route

ARRIVE_RADIUS = 0.25
"""Distance at which a waypoint counts as reached, m."""
SHARP_TURN = 0.7
"""Heading error above which the robot stops and turns in place, rad."""
BACKOFF_TIME = 0.7
"""How long the robot reverses after a contact, s."""
BACKOFF_SPEED = 0.25
"""Reverse speed of the bumper reflex, m/s."""
RAM_TIMEOUT = 20.0
"""A ramming leg that has not touched its obstacle after this long is given up, s."""
HEADING_GAIN = 2.5
"""Yaw-rate command per rad of heading error, 1/s."""


def wrap(angle: float) -> float:
    """Angle wrapped to (-pi, pi]."""
    return (angle + math.pi) % (2 * math.pi) - math.pi


@dataclass
class RouteController:
    """Follows a `Route`; one instance per episode."""

    route: Route
    """The route."""
    index: int = 0
    """Current waypoint."""
    v_cmd: float = 0.0
    """Current commanded forward speed, m/s (ramped)."""
    dwell_left: float = 0.0
    """Time left stopped at a waypoint, s."""
    backoff_left: float = 0.0
    """Time left reversing after a contact, s."""
    leg_time: float = 0.0
    """Time spent on the current leg, s."""
    finished: bool = False
    """True once a non-looping route is done."""
    contacts: list[float] = field(default_factory=list)
    """Times at which the bumper reflex fired."""
    live_mask: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    """(K,) obstacles whose live position a ramming leg aims at (moving pedestrians)."""

    def command(
        self, t: float, pose: tuple[float, float, float], contact: bool, targets: np.ndarray, dt: float
    ) -> tuple[float, float]:
        """Forward speed (m/s) and yaw rate (rad/s) for the next control period.

        Args:
            t: time now, s.
            pose: (x, y, yaw) of the robot.
            contact: whether the robot touched an obstacle during the last period.
            targets: (K, 2) live obstacle centres (ramming legs aim at pedestrians' live position).
            dt: control period, s.
        """
        wps = self.route.waypoints
        v_des, w_des = 0.0, 0.0
        if contact and self.backoff_left <= 0.0:
            # Bumper reflex: brake at once (the motors' torque limit sets the deceleration), then reverse.
            self.backoff_left = BACKOFF_TIME
            self.v_cmd = 0.0
            self.contacts.append(t)
        if self.backoff_left > 0.0:
            self.backoff_left -= dt
            v_des = -BACKOFF_SPEED
            if self.backoff_left <= 0.0 and wps and wps[self.index].ram >= 0:
                self._advance()
            return self._ramp(v_des, dt), 0.0
        if not wps or self.finished:
            return self._ramp(0.0, dt), 0.0
        if self.dwell_left > 0.0:
            self.dwell_left -= dt
            if self.dwell_left <= 0.0:
                self._advance()
            return self._ramp(0.0, dt), 0.0
        wp = wps[self.index]
        self.leg_time += dt
        x, y, yaw = pose
        tx, ty = wp.x, wp.y
        if 0 <= wp.ram < len(self.live_mask) and self.live_mask[wp.ram]:
            tx, ty = float(targets[wp.ram, 0]), float(targets[wp.ram, 1])
        dx, dy = tx - x, ty - y
        dist = math.hypot(dx, dy)
        err = wrap(math.atan2(dy, dx) - yaw)
        if wp.ram < 0 and dist < ARRIVE_RADIUS:
            if wp.dwell > 0:
                self.dwell_left = wp.dwell
                return self._ramp(0.0, dt), 0.0
            self._advance()
            return self._ramp(self.v_cmd, dt), 0.0
        if wp.ram >= 0 and self.leg_time > RAM_TIMEOUT:
            self._advance()
        v_des = wp.speed
        if abs(err) > SHARP_TURN:
            v_des = 0.0
        else:
            v_des *= math.cos(err)
            if wp.ram < 0 and (wp.dwell > 0 or self._next_turn_sharp()):
                v_des = min(v_des, math.sqrt(2 * self.route.accel * max(dist - 0.15, 0.0)) + 0.05)
        w_des = max(-self.route.yaw_rate, min(self.route.yaw_rate, HEADING_GAIN * err))
        return self._ramp(v_des, dt), w_des

    def _ramp(self, v_des: float, dt: float) -> float:
        step = self.route.accel * dt
        self.v_cmd += max(-step, min(step, v_des - self.v_cmd))
        return self.v_cmd

    def _next_turn_sharp(self) -> bool:
        wps = self.route.waypoints
        if len(wps) < 2:
            return True
        a = wps[self.index]
        nxt = (self.index + 1) % len(wps)
        prv = (self.index - 1) % len(wps)
        if not self.route.loop and self.index + 1 >= len(wps):
            return True
        b, p = wps[nxt], wps[prv]
        h1 = math.atan2(a.y - p.y, a.x - p.x)
        h2 = math.atan2(b.y - a.y, b.x - a.x)
        return abs(wrap(h2 - h1)) > SHARP_TURN

    def _advance(self) -> None:
        self.leg_time = 0.0
        self.index += 1
        if self.index >= len(self.route.waypoints):
            if self.route.loop:
                self.index = 0
            else:
                self.index = len(self.route.waypoints) - 1
                self.finished = True
