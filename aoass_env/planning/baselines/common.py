"""Pieces the reconstructed baselines share: their followers, the anchor's clearance region and
the links that join their beacon points."""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from aoass_env.config import AOASSConfig
from aoass_env.maps import ObstacleMap
from aoass_env.planning.detour import DETOUR_MARGIN, DetourPlanner
from aoass_env.planning.follower import WaypointFollower
from aoass_env.planning.path import WaypointPath, polyline_path

#: Extra room (m) beyond the anchor radius and the detour margin that beacon points and links
#: keep from obstacles, so that the turn-rate-limited anchor does not touch them at corners.
LINK_MARGIN = 0.7
#: Fractions of ``LINK_MARGIN`` added to the follower's clearance for the links tried, widest
#: first (:func:`link_clearances`).
PASSAGE_FRACTIONS = (1.0, 0.5, 0.0)


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


def main_free_part(obstacle_map: ObstacleMap, passage: float, margin: float) -> BaseGeometry:
    """The largest connected part of :func:`free_region` with clearance ``passage`` (m): where
    the anchor's centre moves with that clearance from the field's main free space (an empty
    Polygon when nothing is free)."""
    parts = shapely.get_parts(free_region(obstacle_map, passage, margin))
    return max(parts, key=lambda g: g.area) if len(parts) else shapely.Polygon()


def reachable_region(obstacle_map: ObstacleMap, clearance: float, margin: float,
                     passage: float) -> shapely.Geometry:
    """Where beacon points go (prepared): :func:`free_region` with ``clearance`` (m), only its
    parts inside :func:`main_free_part` with the smaller ``passage`` clearance (m), through
    which the follower can still reach them."""
    main = main_free_part(obstacle_map, passage, margin)
    region = shapely.intersection(free_region(obstacle_map, clearance, margin), main)
    shapely.prepare(region)
    return region


def link_clearances(config: AOASSConfig) -> tuple[float, ...]:
    """Clearances (m) tried for a link, widest first: the link clearance (anchor radius + detour
    margin + ``LINK_MARGIN``), then halfway, then the follower's own (anchor radius + detour
    margin), the narrowest passage the simulator's anchor takes."""
    follower = config.anchor_radius + DETOUR_MARGIN
    return tuple(follower + f * LINK_MARGIN for f in PASSAGE_FRACTIONS)


def linked_path(obstacle_map: ObstacleMap, points: np.ndarray,
                config: AOASSConfig) -> WaypointPath:
    """The path through ``points`` (K, 2) (m) in their order: consecutive points joined straight
    where a disc of the link clearance passes and by the shortest detour of
    :class:`~aoass_env.planning.detour.DetourPlanner` otherwise, through narrower passages only
    when there is no wider way (:func:`link_clearances`); a point unreachable even at the
    follower's own clearance is skipped (the next link starts from the last point reached), so
    no link cuts through an obstacle. The path starts at the first point from which the
    follower reaches the field (``DetourPlanner.can_start``; the first point when none does).
    No points: the field's centre. Waypoints every ``waypoint_step`` / ``beacon_interval``
    metres."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(points) == 0:                # every sample inside obstacles: stand at the centre
        points = np.array([[obstacle_map.width / 2, obstacle_map.height / 2]])
    planners: dict[float, DetourPlanner] = {}

    def planner_at(c: float) -> DetourPlanner:
        if c not in planners:
            planners[c] = DetourPlanner(obstacle_map, c)
        return planners[c]

    # start at the first point from which the follower reaches the field (a first point shut
    # in a pocket would leave every later one unreachable)
    narrowest = min(link_clearances(config))
    first = next((k for k, p in enumerate(points)
                  if planner_at(narrowest).can_start(p, narrowest)), 0)
    points = points[first:]
    vertices, here = [points[:1]], points[0]
    for b in points[1:]:
        for c in link_clearances(config):
            planner = planner_at(c)
            route = np.stack([here, b]) if planner.visible(here, b) else planner.path(here, b)
            if route is not None:
                vertices.append(route[1:])
                here = b
                break
    return polyline_path(np.concatenate(vertices), config.path_step)
