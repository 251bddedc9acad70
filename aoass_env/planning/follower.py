"""Nominal path follower: (speed, heading) commands that track a waypoint list.

The follower is the zero-action behaviour of the environment (DESIGN.md section 3): it steers
toward the next waypoint that is not blocked, skipping waypoints inside obstacles and resuming the
path after them (Section 3.3 of the paper). It holds only its progress along the list.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass
class WaypointFollower:
    """Tracks progress along ``waypoints`` (W, 2) with a ``blocked`` (W,) mask.

    Args:
        waypoints: positions (m).
        blocked: waypoints to skip.
        capture_radius: a waypoint counts as reached within this distance (m).
        cruise_speed: commanded speed on straight stretches (m/s).
        stall_time: a target not reached within this time (s) is skipped, so a follower pushed
            against an obstacle does not wait forever.
    """

    waypoints: np.ndarray
    blocked: np.ndarray
    capture_radius: float
    cruise_speed: float
    stall_time: float = 30.0
    index: int = 0
    _time_on_target: float = 0.0

    def __post_init__(self) -> None:
        self.index = self._next_free(self.index)

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

    def command(self, position: np.ndarray, dt: float) -> tuple[float, float]:
        """(speed [m/s], heading [rad]) toward the current target after advancing past reached
        waypoints; ``dt`` (s) is the time since the last call, for stall detection."""
        self._time_on_target += dt
        while not self.done:
            reached = np.hypot(*(self.waypoints[self.index] - position)) <= self.capture_radius
            if not (reached or self._time_on_target > self.stall_time):
                break
            self.index = self._next_free(self.index + 1)
            self._time_on_target = 0.0
        if self.done:
            return 0.0, 0.0
        dx, dy = self.waypoints[self.index] - position
        return self.cruise_speed, math.atan2(dy, dx)
