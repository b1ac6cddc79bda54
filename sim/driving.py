"""The route-following controller: speed profile with acceleration limits, turns, stops and reactions.

Called once per control period with the robot's pose and speed; returns the body speed and yaw rate to
command. What it does is what a delivery or inspection robot does in a busy space, in nominal driving
and around anomalies alike:

- legs at cruise speed with turns in place where the next heading is sharp, smooth stops at dwells;
- legs driven backwards (`Waypoint.reverse`: backing out, docking, three-point turns);
- emergency stops (`Waypoint.hard_stop`): the speed command drops to zero at once and the motors' torque
  limit (and the tyres' grip) sets the deceleration;
- legs that drive at an obstacle (`Waypoint.ram`): the safety field stops the robot short of it
  (`stop_short` > 0, a near miss), or the obstacle is not seen and the robot touches it;
- a reflex (`Route.reflex`) after a contact or a safety stop: keep going for the reaction delay, then brake
  and back off, brake and stand, keep pushing against the obstacle (stall) before braking, or glance off
  and carry on to the next waypoint.
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
RAM_TIMEOUT = 20.0
"""A leg driving at an obstacle that has neither touched it nor stopped short after this long is given
up, s."""
HEADING_GAIN = 2.5
"""Yaw-rate command per rad of heading error, 1/s."""
CONTACT_COOLDOWN = 1.5
"""After a reflex has run, contacts are ignored this long while the robot turns away, s."""


def wrap(angle: float) -> float:
    """Angle wrapped to (-pi, pi]."""
    return (angle + math.pi) % (2 * math.pi) - math.pi


def box_distance(point: tuple[float, float], centre: np.ndarray, half: np.ndarray, yaw: float) -> float:
    """Distance from a point to a rotated rectangle's footprint (0 inside), m."""
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy = point[0] - float(centre[0]), point[1] - float(centre[1])
    lx, ly = abs(dx * c + dy * s), abs(-dx * s + dy * c)
    return math.hypot(max(lx - float(half[0]), 0.0), max(ly - float(half[1]), 0.0))


@dataclass
class _Phase:
    """One step of a running reflex."""

    mode: str
    """`drive` (carry on with the leg), `brake` (speed command to zero at once), `hold` or `reverse`."""
    left: float
    """Time left in this step, s."""


@dataclass
class RouteController:
    """Follows a `Route`; one instance per episode."""

    route: Route
    """The route."""
    index: int = 0
    """Current waypoint."""
    v_cmd: float = 0.0
    """Current commanded forward speed, m/s (ramped, or dropped to zero by a hard stop)."""
    dwell_left: float = 0.0
    """Time left stopped at a waypoint, s."""
    leg_time: float = 0.0
    """Time spent on the current leg, s."""
    finished: bool = False
    """True once a non-looping route is done."""
    contacts: list[float] = field(default_factory=list)
    """Times at which a reflex was triggered by a contact."""
    safety_stops: list[float] = field(default_factory=list)
    """Times at which the safety field stopped the robot short of an obstacle (near misses)."""
    live_mask: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    """(K,) obstacles whose live position a leg driving at them aims at (moving pedestrians)."""
    footprints: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """(K, 3) half-length, half-width and yaw of each obstacle's footprint (for the safety field)."""
    reach: float = 0.3
    """Distance from the robot's centre to the front of its bumper, m."""
    _phases: list[_Phase] = field(default_factory=list)
    _advance_after: bool = False
    _cooldown: float = 0.0

    def command(
        self, t: float, pose: tuple[float, float, float], contact: bool, targets: np.ndarray, dt: float
    ) -> tuple[float, float]:
        """Forward speed (m/s) and yaw rate (rad/s) for the next control period.

        Args:
            t: time now, s.
            pose: (x, y, yaw) of the robot.
            contact: whether the robot touched an obstacle during the last period.
            targets: (K, 2) live obstacle centres (legs driving at an obstacle aim at its live position).
            dt: control period, s.
        """
        self._cooldown = max(self._cooldown - dt, 0.0)
        if not self._phases and self._cooldown <= 0.0:
            if contact:
                self.contacts.append(t)
                self._react(contact=True)
            elif self._safety_stop(pose, targets):
                self.safety_stops.append(t)
                self._react(contact=False)
        if self._phases:
            phase = self._phases[0]
            if phase.mode == "brake":
                self._phases.pop(0)
                self._end_reaction()
                self.v_cmd = 0.0
                return 0.0, 0.0
            phase.left -= dt
            if phase.left <= 0.0:
                self._phases.pop(0)
                self._end_reaction()
            if phase.mode == "hold":
                return self._ramp(0.0, dt), 0.0
            if phase.mode == "reverse":
                return self._ramp(-self.route.reflex.reverse_speed, dt), 0.0
        return self._follow(pose, targets, dt)

    def _react(self, contact: bool) -> None:
        """Start the route's reflex after a contact, or after the safety field stopped the robot."""
        reflex = self.route.reflex
        kind = reflex.kind if contact or reflex.kind in ("reverse", "wait") else "wait"
        on_ram = bool(self.route.waypoints) and self.route.waypoints[self.index].ram >= 0
        phases: list[_Phase] = []
        if contact and reflex.delay > 0:
            phases.append(_Phase("drive", reflex.delay))
        if kind == "continue":
            phases = []
        elif kind == "push":
            phases += [_Phase("drive", reflex.push_time), _Phase("brake", 0.0), _Phase("hold", reflex.wait)]
        else:
            if not contact:
                phases = []  # the safety field brakes at once
            phases += [_Phase("brake", 0.0), _Phase("hold", reflex.wait)]
            if kind == "reverse":
                phases.append(_Phase("reverse", reflex.reverse_time))
        self._phases = phases
        self._advance_after = on_ram
        if not phases:  # glancing off: straight on to the next waypoint
            self._end_reaction()

    def _end_reaction(self) -> None:
        """Once the last step of a reflex is done: ignore contacts a while, leave a leg that drove at the
        obstacle for the next waypoint."""
        if self._phases:
            return
        self._cooldown = CONTACT_COOLDOWN
        if self._advance_after:
            self._advance_after = False
            self._advance()

    def _safety_stop(self, pose: tuple[float, float, float], targets: np.ndarray) -> bool:
        wps = self.route.waypoints
        if not wps or self.finished:
            return False
        wp = wps[self.index]
        if wp.ram < 0 or wp.stop_short <= 0 or wp.ram >= len(self.footprints):
            return False
        x, y, yaw = pose
        front = (x + self.reach * math.cos(yaw), y + self.reach * math.sin(yaw))
        half = self.footprints[wp.ram, :2]
        return box_distance(front, targets[wp.ram], half, float(self.footprints[wp.ram, 2])) <= wp.stop_short

    def _follow(
        self, pose: tuple[float, float, float], targets: np.ndarray, dt: float
    ) -> tuple[float, float]:
        """Drive the current leg."""
        wps = self.route.waypoints
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
        facing = yaw + math.pi if wp.reverse else yaw
        err = wrap(math.atan2(dy, dx) - facing)
        if wp.ram < 0 and dist < ARRIVE_RADIUS:
            if wp.hard_stop:
                self.v_cmd = 0.0  # emergency stop: the torque limit sets the deceleration
            if wp.dwell > 0 or wp.hard_stop:
                self.dwell_left = max(wp.dwell, dt)
                return (0.0 if wp.hard_stop else self._ramp(0.0, dt)), 0.0
            self._advance()
            return self._ramp(self.v_cmd, dt), 0.0
        if wp.ram >= 0 and self.leg_time > RAM_TIMEOUT:
            self._advance()
        speed = wp.speed
        if abs(err) > SHARP_TURN:
            speed = 0.0
        else:
            speed *= math.cos(err)
            if wp.ram < 0 and not wp.hard_stop and (wp.dwell > 0 or self._next_turn_sharp()):
                speed = min(speed, math.sqrt(2 * self.route.accel * max(dist - 0.15, 0.0)) + 0.05)
        w_des = max(-self.route.yaw_rate, min(self.route.yaw_rate, HEADING_GAIN * err))
        return self._ramp(-speed if wp.reverse else speed, dt), w_des

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
        if b.reverse != a.reverse:
            return True  # changing direction means stopping there
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
