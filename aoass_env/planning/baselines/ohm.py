"""OHM (reconstructed): a boustrophedon sweep with Bug-2 boundary following around obstacles.

Sabale et al.'s obstacle-presence schemes (Sensors 21(11):3697, 2021) add obstacle handling to a
static sweep path. No code or pseudo-code was retrieved; this module rebuilds the idea
(docs/baselines.md lists what is verified and what is our choice):

* Base path: horizontal lines from ``y = edge_margin`` to ``height - edge_margin``, at most the
  square spiral's spacing apart (the same coverage argument, :func:`sweep_spacing`), joined
  boustrophedon-wise.
* Obstacles: the anchor keeps a fixed clearance ``anchor_radius + gap`` from every obstacle, i.e.
  its centre stays in :func:`~aoass_env.planning.baselines.common.free_region`. Moving along the
  base path it detects, within its sensing range, where the path leaves that region (the hit
  point), goes there and follows the region's boundary (Bug-2) until the boundary meets the base
  path again farther on and the path continues into free space (the leave point). Of the two
  ways round, the one that rejoins the base path earliest is taken (shorter walk on a tie).
* Termination: a walk longer than ``max_follow`` metres is not taken; the rest of that base
  segment is skipped and the anchor moves (with the shortest detour) to the next base corner.
  Progress along the base path grows at every phase, so the controller always finishes.

Beacons are sent every ``beacon_interval`` metres throughout, detours included (the simulator
does that).
"""

from __future__ import annotations

import math

import numpy as np
import shapely
from shapely import ops
from shapely.geometry.base import BaseGeometry

from aoass_env.config import AOASSConfig
from aoass_env.maps import ObstacleMap
from aoass_env.planning.baselines.common import free_region, point_follower
from aoass_env.planning.follower import WaypointFollower
from aoass_env.planning.path import WaypointPath, polyline_path
from aoass_env.planning.square_spiral import default_spacing
from aoass_env.planning.sweep import PlannedMethod, SweepState
from aoass_env.validators import positive, real

#: Gap (m) kept between the anchor's body and an obstacle while following its boundary: half
#: the room a map guarantees beyond the anchor diameter (map_clearance 2.5 m, radius 0.5 m), so
#: the clearance region stays connected through the narrowest passage.
DEFAULT_GAP = 0.5
#: Longest boundary walk (m) the anchor makes around one obstacle before it skips the rest of
#: the base segment.
DEFAULT_MAX_FOLLOW = 150.0
#: Progress (m) along the base path below which two points count as the same place.
_EPS = 1e-6
#: A leave point must lie this far (m) along the base path beyond the hit point.
_MIN_PROGRESS = 0.05


def sweep_spacing(obstacle_map: ObstacleMap, config: AOASSConfig) -> float:
    """Line spacing (m): ``config.spiral_spacing``, else the square spiral's rule
    (:func:`~aoass_env.planning.square_spiral.default_spacing`) with the origin in a corner,
    which fits whole gaps of at most :func:`~aoass_env.planning.square_spiral.max_spacing`
    between the lines at ``edge_margin`` and ``height - edge_margin`` (the bound of a corner
    beside a line's unlinked end, as at the spiral's last corner)."""
    m = config.edge_margin
    return config.spiral_spacing or default_spacing(
        obstacle_map.width, obstacle_map.height, config.radio_range, config.beacon_interval,
        m, origin=(m, m))


def sweep_vertices(width: float, height: float, spacing: float, margin: float) -> np.ndarray:
    """Corners (V, 2) (m) of a boustrophedon sweep of the field shrunk by ``margin`` (m):
    horizontal lines, bottom to top, at most ``spacing`` (m) apart, left-right alternating."""
    w = positive("width", width, "m")
    h = positive("height", height, "m")
    s = positive("spacing", spacing, "m")
    margin = real("margin", margin, "m", low=0.0, high=min(w, h) / 2, high_open=True)
    n = max(1, math.ceil((h - 2 * margin) / s - 1e-9))
    corners = []
    for k, y in enumerate(np.linspace(margin, h - margin, n + 1)):
        xs = (margin, w - margin) if k % 2 == 0 else (w - margin, margin)
        corners += [(xs[0], y), (xs[1], y)]
    return np.array(corners)


def first_exit(start: np.ndarray, end: np.ndarray, region: BaseGeometry) -> float | None:
    """Distance (m) from ``start`` along the segment to ``end`` at which it first leaves
    ``region``; None when it stays inside (pieces outside shorter than 1e-6 m are ignored)."""
    seg = shapely.LineString([start, end])
    outside = [p for p in shapely.get_parts(shapely.difference(seg, region))
               if p.geom_type == "LineString" and p.length > _EPS]
    if not outside:
        return None
    return min(seg.project(shapely.Point(c)) for p in outside for c in (p.coords[0],
                                                                          p.coords[-1]))


def _ring_walk(ring: shapely.LineString, s0: float, s1: float, forward: bool) -> np.ndarray:
    """Points (K, 2) of the closed ``ring`` from arc ``s0`` to ``s1`` (m), forward (along the
    ring's orientation) or backward, wrapping past the ring's start."""
    length = ring.length
    if forward:
        parts = [(s0, s1)] if s1 >= s0 else [(s0, length), (0.0, s1)]
    else:
        parts = [(s0, s1)] if s1 <= s0 else [(s0, 0.0), (length, s1)]
    pts = np.concatenate([np.asarray(ops.substring(ring, a, b).coords) for a, b in parts])
    keep = np.r_[True, np.any(np.abs(np.diff(pts, axis=0)) > 1e-9, axis=1)]
    return pts[keep]


def boundary_route(region: BaseGeometry, base: shapely.LineString, hit_arc: float,
                   max_follow: float) -> tuple[np.ndarray, float] | None:
    """Bug-2 walk along the boundary of ``region`` from the base path's point at ``hit_arc``
    (m along ``base``) to a leave point.

    Leave points are where the boundary ring meets the base path more than 5 cm farther on and
    the path continues into ``region``. The one earliest along the base path is taken, by the
    shorter way round; walks longer than ``max_follow`` (m) are not considered.

    Returns:
        ``(points, leave_arc)``: the walk (K, 2) (m), hit point first, leave point last, and the
        leave point's distance along ``base`` (m); None when no leave point is within reach.
    """
    positive("max_follow", max_follow, "m")
    hit = base.interpolate(hit_arc)
    rings = [r for poly in shapely.get_parts(region) if not poly.is_empty
             for r in (poly.exterior, *poly.interiors)]
    if not rings:
        return None
    ring = shapely.LineString(min(rings, key=lambda r: r.distance(hit)).coords)
    s0 = ring.project(hit)
    rest = ops.substring(base, hit_arc + _MIN_PROGRESS, base.length)
    meet = shapely.intersection(ring, rest)
    points = {tuple(c) for part in shapely.get_parts(meet) if not part.is_empty
              for c in np.asarray(part.coords)}
    best: tuple[float, float, float, bool] | None = None
    for q in sorted(points):
        qp = shapely.Point(q)
        arc = base.project(qp)
        if arc <= hit_arc + _MIN_PROGRESS / 2:
            continue
        if arc < base.length - _EPS and \
                region.distance(base.interpolate(min(arc + 0.1, base.length))) > _EPS:
            continue                                    # the path runs on into the obstacle
        sq = ring.project(qp)
        ahead, back = (sq - s0) % ring.length, (s0 - sq) % ring.length
        walk, forward = (ahead, True) if ahead <= back else (back, False)
        if walk > max_follow:
            continue
        key = (arc, walk, sq, forward)
        if best is None or key[:2] < best[:2]:
            best = key
    if best is None:
        return None
    arc, _, sq, forward = best
    route = _ring_walk(ring, s0, sq, forward)
    return np.vstack([np.asarray(hit.coords), route, np.asarray(base.interpolate(arc).coords)]), \
        arc


class OHMController:
    """Online OHM driver: base path, hit points, boundary walks and skips (module docstring).

    Args:
        sim: the episode; its ``path`` is the base sweep, its map and config give the obstacles,
            clearance and speeds; ``sim.planner`` (shortest detours) is used only to reach the
            next base corner after a skip.
        gap: gap (m) between the anchor's body and an obstacle while following its boundary.
        max_follow: longest boundary walk (m) per obstacle.

    Attributes:
        walks: boundary walks made; skips: base segments given up.
    """

    def __init__(self, sim: SweepState, gap: float = DEFAULT_GAP,
                 max_follow: float = DEFAULT_MAX_FOLLOW) -> None:
        c = sim.config
        positive("gap", gap, "m", high=10.0)
        self.max_follow = positive("max_follow", max_follow, "m")
        self.config = c
        self.planner = sim.planner
        self.base = shapely.LineString(sim.path.waypoints)
        border = 0.5 * (c.anchor_radius + max(c.edge_margin, c.anchor_radius))
        self.region = free_region(sim.map, c.anchor_radius + gap, border)
        shapely.prepare(self.region)
        wps = sim.path.waypoints
        u, v = wps[1:-1] - wps[:-2], wps[2:] - wps[1:-1]
        turn = np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]) > 1e-9
        self._corners = np.r_[sim.path.arc_length[1:-1][turn], sim.path.length]
        self.arc = 0.0
        self.walks = 0
        self.skips = 0
        self._follower: WaypointFollower | None = None
        self._done = False

    @property
    def done(self) -> bool:
        """True once the base path has been swept to its end."""
        return self._done

    def command(self, position: np.ndarray, heading: float, dt: float) -> tuple[float, float]:
        """(speed [m/s], heading [rad]) for the next ``dt`` seconds."""
        while not self._done:
            if self._follower is not None and not self._follower.done:
                speed, bearing = self._follower.command(position, heading, dt)
                if not self._follower.done:
                    return speed, bearing
            self._follower = None
            self._done = not self._next_phase()
        return 0.0, 0.0

    def _free(self, point: shapely.Point) -> bool:
        return self.region.distance(point) <= _EPS

    def _go(self, points: np.ndarray, planner: bool) -> None:
        self._follower = point_follower(self.config, points,
                                        self.planner if planner else None)

    def _next_phase(self) -> bool:
        """Set up the next phase from base arc ``self.arc``; False when the sweep is over."""
        length = self.base.length
        if self.arc >= length - _EPS:
            return False
        here = self.base.interpolate(self.arc)
        if not self._free(here):                       # resume where the base path is free
            entry = self._next_entry(self.arc)
            if entry is None:
                return False
            self.arc = entry
            self._go(np.asarray(self.base.interpolate(entry).coords), planner=True)
            return True
        corner = float(self._corners[np.searchsorted(self._corners, self.arc + _EPS)])
        end = self.base.interpolate(corner)
        exit_at = first_exit(np.asarray(here.coords[0]), np.asarray(end.coords[0]), self.region)
        if exit_at is None:                            # free to the next corner
            self.arc = corner
            self._go(np.vstack([here.coords, end.coords]), planner=False)
        elif exit_at > _MIN_PROGRESS:                  # obstacle sensed ahead: go to the hit
            self.arc += exit_at
            self._go(np.vstack([here.coords, self.base.interpolate(self.arc).coords]),
                     planner=False)
        else:                                          # at the hit point: follow the boundary
            route = boundary_route(self.region, self.base, self.arc, self.max_follow)
            if route is None:                          # cannot rejoin: skip to the corner
                self.skips += 1
                self.arc = corner
                if self._free(end):
                    self._go(np.asarray(end.coords), planner=True)
            else:
                self.walks += 1
                points, self.arc = route
                self._go(points, planner=False)
        return True

    def _next_entry(self, arc: float) -> float | None:
        """First distance (m) along the base path beyond ``arc`` where it lies in the region."""
        rest = ops.substring(self.base, arc, self.base.length)
        arcs = [self.base.project(shapely.Point(c))
                for p in shapely.get_parts(shapely.intersection(rest, self.region))
                if not p.is_empty for c in (p.coords[0], p.coords[-1])]
        ahead = [a for a in arcs if a > arc]
        return min(ahead) if ahead else None


def plan(obstacle_map: ObstacleMap, config: AOASSConfig) -> WaypointPath:
    """OHM's base sweep (waypoints every ``waypoint_step`` / ``beacon_interval`` metres)."""
    corners = sweep_vertices(obstacle_map.width, obstacle_map.height,
                             sweep_spacing(obstacle_map, config), config.edge_margin)
    return polyline_path(corners, config.path_step)


OHM = PlannedMethod(
    name="ohm",
    label="OHM (reconstructed)",
    source=("K. Sabale et al., \"Path Planning for Mobile-Anchor Based WSN Localization: "
            "Obstacle-Presence Schemes\", Sensors 21(11):3697, 2021, doi 10.3390/s21113697"),
    plan=plan,
    controller=OHMController,
    reconstructed=True,
)
