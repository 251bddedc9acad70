"""Pieces the reconstructed baselines share: their followers and the anchor's clearance region."""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from aoass_env.config import AOASSConfig
from aoass_env.maps import ObstacleMap
from aoass_env.planning.detour import DetourPlanner
from aoass_env.planning.follower import WaypointFollower
from aoass_env.planning.path import polyline_path


def point_follower(config: AOASSConfig, points: np.ndarray,
                   planner: DetourPlanner | None) -> WaypointFollower:
    """A follower of the polyline through ``points`` (K, 2) (m), with waypoints every
    ``waypoint_step`` (or ``beacon_interval``) metres so that no leg outlasts the follower's
    stall time, and the simulator's nominal capture radius, speed and deceleration; ``planner``
    detours around static obstacles (None: straight legs)."""
    pts = polyline_path(np.asarray(points, dtype=np.float64).reshape(-1, 2),
                        config.path_step).waypoints
    return WaypointFollower.nominal(config, pts, planner=planner)


def free_region(obstacle_map: ObstacleMap, clearance: float, border: float) -> BaseGeometry:
    """Where the anchor's centre may go: the field shrunk by ``border`` (m) minus the obstacles
    dilated by ``clearance`` (m). A Polygon or MultiPolygon (narrow passages may split it)."""
    box = shapely.box(border, border, obstacle_map.width - border, obstacle_map.height - border)
    if not obstacle_map.polygons:
        return box
    return shapely.difference(box, shapely.buffer(obstacle_map.union, clearance))
