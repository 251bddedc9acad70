"""Nominal path follower: (speed, heading) commands that track a waypoint list.

The follower is the zero-action behaviour of the environment (DESIGN.md section 3): it steers
toward the next waypoint that is not blocked, skipping waypoints inside obstacles and resuming the
path after them (Section 3.3 of the paper). When an obstacle stands between the anchor and its
target, an optional :class:`~aoass_env.planning.detour.DetourPlanner` supplies intermediate points
around it; without a planner the follower steers straight (and relies on a safety layer).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from aoass_env.config import AOASSConfig
from aoass_env.planning.detour import DetourPlanner


@dataclass
class WaypointFollower:
    """Tracks progress along ``waypoints`` (W, 2) with a ``blocked`` (W,) mask.

    Args:
        waypoints: positions (m).
        blocked: waypoints to skip.
        capture_radius: a waypoint counts as reached within this distance (m).
        cruise_speed: commanded speed on straight stretches (m/s).
        max_accel: the anchor's deceleration limit (m/s^2), used to brake ahead of sharp turns.
        stall_time: a target (spiral or detour point) not reached within this time (s) is
            skipped, so a follower pushed against an obstacle does not wait forever.
        planner: detour planner used when the straight line to the target is obstructed.
    """

    waypoints: np.ndarray
    blocked: np.ndarray
    capture_radius: float
    cruise_speed: float
    max_accel: float = math.inf
    stall_time: float = 30.0
    planner: DetourPlanner | None = None
    index: int = 0
    _clock: float = 0.0
    _budget: float = 0.0
    _planned: bool = False
    _detour: list[np.ndarray] = field(default_factory=list)
    _way_on: tuple[tuple[bytes, bytes] | None, bool] = (None, True)

    def __post_init__(self) -> None:
        self.index = self._next_free(self.index)
        self._budget = self.stall_time

    @classmethod
    def nominal(cls, config: AOASSConfig, waypoints: np.ndarray, blocked: np.ndarray | None = None,
                planner: DetourPlanner | None = None, start: int = 0) -> WaypointFollower:
        """The nominal follower of ``config``: cruise at ``anchor_nominal_speed``, brake within
        ``anchor_max_accel``, and capture a waypoint within the anchor radius or half a control
        period's travel, whichever is larger; ``blocked`` None: no waypoint is skipped; the
        waypoints before ``start`` are skipped."""
        wps = np.asarray(waypoints, dtype=np.float64)
        return cls(wps, np.zeros(len(wps), dtype=bool) if blocked is None else blocked,
                   capture_radius=max(config.anchor_radius,
                                      0.5 * config.anchor_nominal_speed * config.dt),
                   cruise_speed=config.anchor_nominal_speed, max_accel=config.anchor_max_accel,
                   planner=planner, index=start)

    @property
    def done(self) -> bool:
        """True once every waypoint has been reached or skipped."""
        return self.index >= len(self.waypoints)

    @property
    def target(self) -> np.ndarray | None:
        """The waypoint currently steered to, or None when done."""
        return None if self.done else self.waypoints[self.index]

    def progress(self) -> float:
        """Fraction of waypoints reached or skipped, in [0, 1]."""
        return min(self.index, len(self.waypoints)) / len(self.waypoints)

    def _next_free(self, i: int) -> int:
        while i < len(self.waypoints) and self.blocked[i]:
            i += 1
        return i

    def _advance(self) -> None:
        self.index = self._next_free(self.index + 1)
        self._budget = self._clock + self.stall_time
        self._planned = False
        self._detour.clear()

    def command(self, position: np.ndarray, heading: float, dt: float) -> tuple[float, float]:
        """(speed [m/s], heading [rad]) toward the current target after advancing past reached
        waypoints. ``heading`` (rad) is the anchor's current heading: the speed is scaled by the
        cosine of the heading error (zero beyond 90 deg, so sharp turns happen in place);
        ``dt`` (s) is the time since the last call, for stall detection.

        With a planner, an obstructed target gets one detour (intermediate points, then the
        target); the time allowed for the target grows by twice the detour's travel time.
        """
        self._clock += dt
        while not self.done:
            target = self.waypoints[self.index]
            if (np.hypot(*(target - position)) <= self.capture_radius
                    or self._clock > self._budget):
                self._advance()
                continue
            while self._detour and np.hypot(*(self._detour[0] - position)) <= self.capture_radius:
                self._detour.pop(0)
            if self.planner is None or self._planned or self.planner.visible(position, target):
                break
            path = self.planner.path(position, target)
            if path is None:
                self._advance()      # unreachable from here: skip it, as if inside an obstacle
                continue
            self._planned = True
            self._detour = list(path[1:-1])
            length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
            self._budget = self._clock + self.stall_time + 2.0 * length / self.cruise_speed
            break
        if self.done:
            return 0.0, 0.0
        aim, after = self._aim_points()
        dx, dy = aim - position
        bearing = math.atan2(dy, dx)
        speed = self.cruise_speed * max(0.0, math.cos(bearing - heading))
        if after is not None:
            # brake so that the speed at the aim point suits the turn there
            ox, oy = after - aim
            turn = math.atan2(oy, ox) - bearing
            corner_speed = self.cruise_speed * max(0.0, math.cos(turn))
            if not self._way_on_open(aim, after):
                corner_speed = 0.0      # the way on is obstructed: stop there to replan
            room = max(0.0, math.hypot(dx, dy) - self.capture_radius)
            speed = min(speed, math.sqrt(corner_speed**2 + 2.0 * self.max_accel * room))
        return speed, bearing

    def _way_on_open(self, aim: np.ndarray, after: np.ndarray) -> bool:
        """Whether the leg aim -> after is free; one planner query per leg, not per step."""
        if self.planner is None:
            return True
        key = (aim.tobytes(), after.tobytes())
        if self._way_on[0] != key:
            self._way_on = (key, self.planner.visible(aim, after))
        return self._way_on[1]

    def _aim_points(self) -> tuple[np.ndarray, np.ndarray | None]:
        """The point steered to and the one after it (None at the end of the path)."""
        queue = self._detour + [self.waypoints[self.index]]
        if len(queue) > 1:
            return queue[0], queue[1]
        nxt = self._next_free(self.index + 1)
        return queue[0], (self.waypoints[nxt] if nxt < len(self.waypoints) else None)
