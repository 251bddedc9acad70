"""The square spiral of the paper (Eq. 1-5) as a list of waypoints.

Geometry (Eq. 1-2): starting at (x0, y0), legs run right, up, left, down, right, ...; leg j
(0-based) has length ``(j // 2 + 1) * spacing``, so the length grows by one spacing every two legs
and parallel passes end up ``spacing`` apart. Waypoints are placed every ``step`` metres along each
leg (Eq. 1's Δs step; a leg's last step may be shorter so that corners are exact waypoints).

The anchor cannot leave the field, so legs are clipped to the field shrunk by ``margin``; once the
path has run along all four clipped borders, the spiral is complete (any further leg would repeat
a border pass).

Default spacing (:func:`default_spacing`) -- every point of an obstacle-free field must hear at
least three non-collinear beacons (Eq. 18):

* Beacons on one straight pass are collinear, so a point must hear two different passes (or a
  corner). A point between two parallel passes ``s`` apart is at most ``s`` from the farther one.
  At perpendicular distance ``d`` a pass offers a chord of length ``2 sqrt(R^2 - d^2)`` inside the
  radio range; beacons are ``Δs`` apart along the path, so a chord of at least ``2 Δs`` holds at
  least two beacons. The farther pass thus contributes >= 2 beacons when
  ``s <= sqrt(R^2 - Δs^2)``, and the nearer pass contributes many more, off that line.
* A point on the field border lies ``margin`` beyond the outermost (clipped) pass, so the bound on
  the gap between the two outermost passes is ``sqrt(R^2 - Δs^2) - margin``.
* The corner where the spiral stops binds harder: the path breaks after the leg that completes
  the fourth border pass, so the pass along the other border there starts ``s`` short of the
  corner, at ``sqrt(margin^2 + (margin + s)^2)`` from it, and its first beacon may lie up to
  ``Δs`` farther along the path. The corner hears an off-line beacon (beside the border pass's
  collinear ones) when that distance plus ``Δs`` is at most R:
  ``s_max = sqrt((R - Δs)^2 - margin^2) - margin``, below the passes' bound for every
  ``Δs < R`` (``(R - Δs)^2 < R^2 - Δs^2``). (With the passes' bound alone, fields whose fitted
  spacing came within a few decimetres of it left that corner uncovered: 143.5, 190, 237 m.)
* The spacing is then fitted to the field so that the outermost ring lands exactly on the clipped
  border instead of leaving a thin redundant strip: with ``h`` the largest distance from the origin
  to a clipped border, ``k = ceil(h / s_max)`` rings and ``s = h / k <= s_max``.

For R = 25 m, Δs = 2 m and a 1.5 m margin, s_max = 21.45 m (the passes' bound alone: 23.42 m);
a 100 m field centred spiral gets k = 3 and s = 16.17 m, a 200 m field k = 5 and s = 19.70 m
(the same with either bound).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aoass_env.config import AOASSConfig
from aoass_env.maps import ObstacleMap
from aoass_env.planning.path import ArcLengthTiming
from aoass_env.validators import integer, positive, real, vec2

#: Unit direction vectors d_n of Eq. 1, cycling right, up, left, down.
DIRECTIONS = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])


def range_and_interval(radio_range: float, beacon_interval: float) -> tuple[float, float]:
    """The radio range and beacon interval (m) of a coverage guarantee, checked: ValueError
    naming them unless ``0 < beacon_interval < radio_range``."""
    r = positive("radio_range", radio_range, "m")
    ds = positive("beacon_interval", beacon_interval, "m")
    if ds >= r:
        raise ValueError(f"beacon_interval={beacon_interval} m must be below radio_range="
                         f"{radio_range} m for the coverage guarantee")
    return r, ds


def max_spacing(radio_range: float, beacon_interval: float, margin: float = 0.0) -> float:
    """Largest spacing (m) between passes that keeps every point covered (module docstring)."""
    range_and_interval(radio_range, beacon_interval)
    real("margin", margin, "m", low=0.0)
    reach = radio_range - beacon_interval          # the corner's bound (module docstring)
    s = math.sqrt(reach**2 - margin**2) - margin if margin < reach else -math.inf
    if s <= 0:
        raise ValueError(f"margin={margin} m leaves no valid spacing for radio_range="
                         f"{radio_range} m")
    return s


def default_spacing(width: float, height: float, radio_range: float, beacon_interval: float,
                    margin: float = 0.0, origin: tuple[float, float] | None = None, *,
                    wide: bool = False) -> float:
    """Spacing (m) fitted to the field: the outermost ring lands on the clipped border. The
    ring count is the fewest at :func:`max_spacing` or less, or with ``wide`` the most at
    :func:`max_spacing` or more (at least one): the adaptive sweep's passes, which leave the
    gaps to its densify phase (:mod:`aoass_env.planning.adaptive`)."""
    width, height = positive("width", width, "m"), positive("height", height, "m")
    x0, y0 = vec2("origin", origin, "m") if origin is not None else (width / 2, height / 2)
    h = max(x0 - margin, width - margin - x0, y0 - margin, height - margin - y0)
    s_max = max_spacing(radio_range, beacon_interval, margin)
    if h <= 0:
        return s_max
    if wide:
        return h / max(1, math.floor(h / s_max + 1e-9))
    return h / math.ceil(h / s_max - 1e-9)


def config_spacing(config: AOASSConfig, width: float, height: float, *,
                   wide: bool = False) -> float:
    """The pass spacing (m) of ``config`` on a ``width`` x ``height`` (m) field: its
    ``spiral_spacing``, else :func:`default_spacing` (``wide`` or not) for its radio range,
    beacon interval, edge margin and spiral origin."""
    return config.spiral_spacing or default_spacing(
        width, height, config.radio_range, config.beacon_interval, config.edge_margin,
        config.spiral_origin, wide=wide)


@dataclass(frozen=True)
class SquareSpiral(ArcLengthTiming):
    """Waypoints of a square spiral.

    Attributes:
        waypoints: (W, 2) positions (m), the first one the origin.
        leg: (W,) index of the leg that ends at (or contains) each waypoint; 0 for the origin.
        arc_length: (W,) distance along the ideal path from the origin to each waypoint (m).
        blocked: (W,) True where the waypoint lies inside an obstacle dilated by the anchor
            radius (set by :meth:`with_obstacles`; a follower skips these and resumes after).
        spacing: distance between parallel passes (m).
        step: waypoint step along a leg (m).
    """

    waypoints: np.ndarray
    leg: np.ndarray
    arc_length: np.ndarray
    blocked: np.ndarray
    spacing: float
    step: float

    def corners(self) -> np.ndarray:
        """(C, 2) leg end points: the turning points of the spiral, origin first."""
        last_of_leg = np.r_[np.diff(self.leg) != 0, True]
        last_of_leg[0] = True
        return self.waypoints[last_of_leg]

    def with_obstacles(self, obstacle_map: ObstacleMap, anchor_radius: float) -> SquareSpiral:
        """A copy whose ``blocked`` marks waypoints inside obstacles dilated by the radius."""
        blocked = obstacle_map.inside_obstacle(self.waypoints, dilation=anchor_radius)
        return SquareSpiral(self.waypoints, self.leg, self.arc_length, blocked, self.spacing,
                            self.step)


def square_spiral(width: float, height: float, spacing: float, step: float, *,
                  origin: tuple[float, float] | None = None, margin: float = 0.0,
                  max_legs: int = 100_000) -> SquareSpiral:
    """Waypoints of the square spiral (Eq. 1-2) clipped to the field shrunk by ``margin``.

    Args:
        width, height: field size (m).
        spacing: leg increment of Eq. 2 = distance between parallel passes (m).
        step: distance between waypoints along a leg, Eq. 1's step (m).
        origin: (x0, y0) (m); default the field centre.
        margin: inset of the clipped border from the field edge (m).
    """
    for name, value in (("width", width), ("height", height), ("spacing", spacing),
                        ("step", step)):
        positive(name, value, "m")
    margin = real("margin", margin, "m", low=0.0)
    max_legs = integer("max_legs", max_legs, low=1)
    if origin is not None:
        origin = vec2("origin", origin, "m")
    lo = np.array([margin, margin], dtype=np.float64)
    hi = np.array([width - margin, height - margin], dtype=np.float64)
    if np.any(hi <= lo):
        raise ValueError(f"margin={margin} m leaves no room in a {width} x {height} m field")
    start = np.array(origin if origin is not None else (width / 2, height / 2), dtype=np.float64)
    if np.any(start < lo) or np.any(start > hi):
        raise ValueError(f"origin={tuple(start)} must lie within the field shrunk by the margin: "
                         f"[{lo[0]}, {hi[0]}] x [{lo[1]}, {hi[1]}] m")

    points, legs = [start], [0]
    # which clipped border lines (right, top, left, bottom) a leg has run along
    borders_done = np.zeros(4, dtype=bool)
    # the unclipped spiral's corner: each leg ends at Eq. 2's length from it, clipped; from the
    # clipped position instead, a leg clipped at a near border (an off-centre origin) shifted
    # every later pass toward it and left gaps wider than the spacing by the far border. A
    # clip of round-off size (the last ring of a fitted spacing) moves the corner to the clip.
    pos = virtual = start
    roundoff = 1e-9 * max(width, height)
    for j in range(max_legs):
        d = DIRECTIONS[j % 4]
        virtual = virtual + (j // 2 + 1) * spacing * d
        # a corner within round-off of a border, either side, is on it (one ulp short of it,
        # the pass along it did not count and the spiral ran a whole extra ring)
        end = np.where(np.abs(virtual - hi) <= roundoff, hi,
                       np.where(np.abs(virtual - lo) <= roundoff, lo, np.clip(virtual, lo, hi)))
        if np.abs(end - virtual).max() <= roundoff:
            virtual = end
        seg = float(np.abs(end - pos).sum())
        if seg > 1e-9:
            n = math.ceil(seg / step - 1e-9)
            t = np.minimum(np.arange(1, n + 1) * step, seg)[:, None]
            points.extend(pos + t * d)
            legs.extend([j + 1] * n)
            # the leg runs along a border if its constant coordinate sits on one
            axis = 1 if d[0] != 0 else 0      # constant coordinate of this leg
            if pos[axis] == hi[axis]:
                borders_done[1 if axis == 1 else 0] = True
            if pos[axis] == lo[axis]:
                borders_done[3 if axis == 1 else 2] = True
        pos = end
        if borders_done.all():
            break
    else:
        raise ValueError(f"spiral did not close within max_legs={max_legs} legs")

    wps = np.array(points)
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(wps, axis=0), axis=1))]
    return SquareSpiral(wps, np.array(legs, dtype=np.int64), arc,
                        np.zeros(len(wps), dtype=bool), float(spacing), float(step))


def episode_spiral(config: AOASSConfig, obstacle_map: ObstacleMap) -> SquareSpiral:
    """The square spiral of ``config`` over ``obstacle_map`` (at the map's own size), blocked
    waypoints marked: the environment's reference path."""
    w, h = obstacle_map.width, obstacle_map.height
    spiral = square_spiral(w, h, config_spacing(config, w, h), config.path_step,
                           origin=config.spiral_origin, margin=config.edge_margin)
    return spiral.with_obstacles(obstacle_map, config.anchor_radius)
