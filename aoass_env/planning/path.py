"""A planned path as a list of waypoints: what every planner hands to the path follower.

The square spiral (:class:`~aoass_env.planning.square_spiral.SquareSpiral`) and the baseline
planners' paths share this interface: ``waypoints``, ``arc_length``, ``blocked``, ``length``,
``nominal_time`` and ``with_obstacles``. :func:`polyline_path` turns the corner points of a
planner's polyline into waypoints a fixed step apart, the form the follower tracks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aoass_env.maps import ObstacleMap
from aoass_env.validators import positive

__all__ = ["ArcLengthTiming", "WaypointPath", "polyline_path"]


class ArcLengthTiming:
    """``length`` and ``nominal_time`` of a path from its ``arc_length`` (m) attribute."""

    arc_length: np.ndarray

    @property
    def length(self) -> float:
        """Length of the ideal, obstacle-free path (m) -- L_ideal of Eq. 19."""
        return float(self.arc_length[-1])

    def nominal_time(self, speed: float) -> float:
        """Travel time (s) of the ideal path at constant ``speed`` (m/s) -- T_ideal of Eq. 19."""
        if speed <= 0:
            raise ValueError(f"speed={speed} must be positive (m/s)")
        return self.length / speed


@dataclass(frozen=True)
class WaypointPath(ArcLengthTiming):
    """Waypoints of a planned path.

    Attributes:
        waypoints: (W, 2) positions (m), in travel order.
        arc_length: (W,) distance along the ideal path from the first waypoint (m).
        blocked: (W,) True where the waypoint lies inside an obstacle dilated by the anchor
            radius (set by :meth:`with_obstacles`; the follower skips these).
    """

    waypoints: np.ndarray
    arc_length: np.ndarray
    blocked: np.ndarray

    def with_obstacles(self, obstacle_map: ObstacleMap, anchor_radius: float) -> WaypointPath:
        """A copy whose ``blocked`` marks waypoints inside obstacles dilated by the radius."""
        blocked = obstacle_map.inside_obstacle(self.waypoints, dilation=anchor_radius)
        return WaypointPath(self.waypoints, self.arc_length, blocked)


def polyline_path(vertices: np.ndarray, step: float) -> WaypointPath:
    """Waypoints at most ``step`` (m) apart along the polyline through ``vertices`` (V, 2) (m).

    Every vertex is kept (a corner stays a waypoint); repeated consecutive vertices are dropped.
    """
    step = positive("step", step, "m")
    v = np.asarray(vertices, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 2 or len(v) == 0 or not np.all(np.isfinite(v)):
        raise ValueError(f"vertices must be a non-empty (V, 2) array of finite metres, "
                         f"got shape {v.shape}")
    keep = np.r_[True, np.any(np.diff(v, axis=0) != 0, axis=1)]
    v = v[keep]
    points = [v[:1]]
    for a, b in zip(v[:-1], v[1:], strict=True):
        seg = float(np.hypot(*(b - a)))
        n = math.ceil(seg / step - 1e-9)
        points.append(a + (np.arange(1, n + 1) / n)[:, None] * (b - a))
    wps = np.concatenate(points)
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(wps, axis=0), axis=1))]
    return WaypointPath(wps, arc, np.zeros(len(wps), dtype=bool))
