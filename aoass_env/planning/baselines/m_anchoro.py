"""M-ANCHORO (reconstructed): triangle-lattice beacon points, SCAN order, redundancy pruning.

Tsai et al., "M-ANCHORO: Mobile Anchor Node-Based Path Optimization for Full Coverage Path
Planning Algorithm", 2024, doi 10.1155/2024/7347796. The abstract gives the pipeline (split the
field by the obstacle layout, beacon points on an equilateral-triangle lattice, SCAN order into
a full-coverage path, remove redundant beacon points); the details are ours (docs/baselines.md):

1. Lattice (:func:`triangle_lattice`): rows ``a sqrt(3)/2`` apart (at most), alternate rows
   offset by ``a/2`` and closed by points on the field's shrunk border. Any point of a lattice
   triangle is at most ``a`` from each of its three (non-collinear) vertices; a point of the
   field lies at most ``sqrt(2) * edge_margin`` outside the lattice's hull, so
   ``a = R - sqrt(2) * edge_margin`` (:func:`lattice_side`) lets every point hear three.
2. Points inside obstacles dilated by the link clearance (anchor radius + detour margin +
   ``LINK_MARGIN``) are dropped, and so are points the follower cannot reach (outside the main
   free space at its own clearance,
   :func:`~aoass_env.planning.baselines.common.main_free_part`); candidate points every
   ``a/2`` along the boundary of that dilated region, where the follower reaches them, are
   added greedily (most uncovered samples first) while they restore triple coverage of free
   sample points (:func:`restore_coverage`): a candidate is kept when it covers a sample or
   gives an uncovered sample that hears fewer than three points one more, so coverage that
   needs several new points at once is built up (step 4 removes what did not lead to it).
3. SCAN: points are grouped by the nearest lattice row and visited row by row, alternating
   direction (boustrophedon); consecutive points without a straight collision-free link are
   joined by the shortest detour (same clearance) of
   :class:`~aoass_env.planning.detour.DetourPlanner` (no
   explicit cell decomposition: the detours do its work); where no detour exists at that
   clearance, at half the link margin, then at the follower's own clearance, as OTPP's links
   (:func:`~aoass_env.planning.baselines.common.linked_path`); a point unreachable even so is
   skipped, so no planned link cuts through an obstacle.
4. Pruning (:func:`prune`): points are removed greedily (those heard by the fewest samples
   first) when every sample they covered still hears >= 3 non-collinear remaining points.

Coverage of a sample (Eq. 18, line of sight and range as the radio model) is decided by
:class:`~aoass_env.network.Network` itself, fed with beacons at the points only. In the
simulator the anchor beacons every ``beacon_interval`` along the whole path (the common rule),
which can only add coverage.
"""

from __future__ import annotations

import math

import numpy as np
import shapely

from aoass_env.config import AOASSConfig
from aoass_env.maps import ObstacleMap
from aoass_env.network import Network
from aoass_env.planning.baselines.common import (
    LINK_MARGIN,
    free_region,
    link_clearances,
    linked_path,
    main_free_part,
)
from aoass_env.planning.detour import DETOUR_MARGIN
from aoass_env.planning.path import WaypointPath
from aoass_env.planning.sweep import PlannedMethod
from aoass_env.radio import Radio
from aoass_env.validators import positive, real

#: Spacing (m) of the free sample points coverage is checked on.
SAMPLE_SPACING = 2.0


def lattice_side(radio_range: float, margin: float) -> float:
    """Triangle side a (m) = R - sqrt(2) * margin: a field point hears the three vertices of
    its lattice triangle even in a corner outside the lattice (module docstring)."""
    r = positive("radio_range", radio_range, "m")
    margin = real("margin", margin, "m", low=0.0, high=r / math.sqrt(2.0), high_open=True,
                  doc=f"for radio_range={r:g} m")
    return r - math.sqrt(2.0) * margin


def triangle_lattice(width: float, height: float, side: float, margin: float
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Equilateral-triangle lattice over the field shrunk by ``margin`` (m).

    Rows are fitted to the shrunk field (spacing <= ``side`` sqrt(3)/2, points <= ``side``
    apart); odd rows are offset by half a step and closed by points on the left and right
    border. Returns (points (P, 2) (m), row index (P,)), bottom row first, left to right.
    """
    w, h, a = (positive(n, v, "m") for n, v in (("width", width), ("height", height),
                                                ("side", side)))
    margin = real("margin", margin, "m", low=0.0, high=min(w, h) / 2, high_open=True)
    span_x, span_y = w - 2 * margin, h - 2 * margin
    n_cols = max(1, math.ceil(span_x / a - 1e-9))
    n_rows = max(1, math.ceil(span_y / (a * math.sqrt(3) / 2) - 1e-9))
    dx = span_x / n_cols
    xs_even = margin + dx * np.arange(n_cols + 1)
    xs_odd = np.r_[margin, margin + dx * (np.arange(n_cols) + 0.5), w - margin]
    points, rows = [], []
    for k, y in enumerate(np.linspace(margin, h - margin, n_rows + 1)):
        xs = xs_even if k % 2 == 0 else xs_odd
        points.append(np.stack([xs, np.full(len(xs), y)], axis=1))
        rows.append(np.full(len(xs), k))
    return np.concatenate(points), np.concatenate(rows)


def free_samples(obstacle_map: ObstacleMap, spacing: float = SAMPLE_SPACING) -> np.ndarray:
    """Cell centres (S, 2) (m) of a ``spacing`` (m) grid that lie outside every obstacle."""
    s = positive("spacing", spacing, "m")
    xs = np.arange(s / 2, obstacle_map.width, s)
    ys = np.arange(s / 2, obstacle_map.height, s)
    grid = np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1).reshape(-1, 2)
    return grid[~obstacle_map.inside_obstacle(grid)]


def hearing(points: np.ndarray, samples: np.ndarray, obstacle_map: ObstacleMap,
            config: AOASSConfig) -> np.ndarray:
    """(P, S) True where sample s hears a beacon sent at point p: within ``radio_range`` and,
    with ``line_of_sight``, not blocked by an obstacle (the unit-disk radio of the config)."""
    radio = Radio(samples, obstacle_map, config.radio_range, line_of_sight=config.line_of_sight)
    heard = np.zeros((len(points), len(samples)), dtype=bool)
    for i, p in enumerate(np.asarray(points, dtype=np.float64).reshape(-1, 2)):
        heard[i, radio.receivers(p)] = True
    return heard


def triple_covered(points: np.ndarray, heard: np.ndarray, config: AOASSConfig) -> np.ndarray:
    """(S,) True where a sample hears >= 3 non-collinear beacons among ``points`` (P, 2) (m)
    with hearing matrix ``heard`` (P, S) -- Eq. 18 as :class:`Network` decides it."""
    if heard.shape[1] == 0:
        return np.zeros(0, dtype=bool)
    net = Network(heard.shape[1], config)
    for p, row in zip(np.asarray(points).reshape(-1, 2), heard, strict=True):
        net.record_beacon(p, np.flatnonzero(row))
    return net.covered.copy()


def restore_coverage(points: np.ndarray, candidates: np.ndarray, heard: np.ndarray,
                     heard_candidates: np.ndarray, config: AOASSConfig) -> np.ndarray:
    """Indices into ``candidates`` (C, 2) to add to ``points`` (P, 2) (m), greedily: each round
    the candidate heard by the most still-uncovered samples is tried and kept when the number
    of covered samples grows or when an uncovered sample that hears fewer than three points
    hears it, so coverage that needs two or three new points at once (a sample no lattice point
    reaches) is built up; ends when no untried candidate hears an uncovered sample. (Fewer
    than two would do where two heard points are far apart: a third off their line covers the
    sample and is kept for that; three leaves slack for points nearly on a line, and on fresh
    maps gave the same coverage or more.) ``heard`` (P, S) and ``heard_candidates`` (C, S) are
    the hearing matrices; :func:`prune` removes the points that led to no coverage."""
    added: list[int] = []
    tried = np.zeros(len(candidates), dtype=bool)
    pts, hrd = np.asarray(points).reshape(-1, 2), heard
    covered = triple_covered(pts, hrd, config)
    hears = hrd.sum(axis=0)
    while True:
        gain = np.where(tried, -1, (heard_candidates & ~covered).sum(axis=1))
        if len(gain) == 0 or gain.max() <= 0:
            return np.array(added, dtype=np.int64)
        best = int(np.argmax(gain))
        tried[best] = True
        row = heard_candidates[best]
        trial = triple_covered(np.vstack([pts, candidates[best]]), np.vstack([hrd, row]), config)
        if trial.sum() > covered.sum() or (row & ~covered & (hears < 3)).any():
            pts, hrd, covered = np.vstack([pts, candidates[best]]), np.vstack([hrd, row]), trial
            hears = hears + row
            added.append(best)


def prune(points: np.ndarray, heard: np.ndarray, config: AOASSConfig) -> np.ndarray:
    """Mask (P,) of the points kept after greedy removal of redundant ones: a point (fewest
    hearing samples first) goes when every sample it helped cover still hears >= 3
    non-collinear kept points. When no sample is covered (a map so dense that even the restored
    points cover no free spot) nothing is pruned: there is no coverage to preserve, and
    removing every point would leave no path."""
    pts = np.asarray(points).reshape(-1, 2)
    keep = np.ones(len(pts), dtype=bool)
    covered = triple_covered(pts, heard, config)
    if not covered.any():
        return keep
    for i in np.argsort(heard.sum(axis=1), kind="stable"):
        affected = heard[i] & covered
        keep[i] = False
        if affected.any():
            still = triple_covered(pts[keep], heard[keep][:, affected], config)
            if not still.all():
                keep[i] = True
    return keep


def scan_order(points: np.ndarray, row_y: np.ndarray) -> np.ndarray:
    """Order (P,) of ``points`` (m) by SCAN: grouped by the nearest of the rows at heights
    ``row_y`` (m), bottom row first, left to right and right to left alternately."""
    pts = np.asarray(points).reshape(-1, 2)
    rows = np.argmin(np.abs(pts[:, 1:2] - np.asarray(row_y)[None]), axis=1)
    x = np.where(rows % 2 == 0, pts[:, 0], -pts[:, 0])
    return np.lexsort((x, rows))


def boundary_points(region: shapely.Geometry, spacing: float) -> np.ndarray:
    """Points (K, 2) (m) every ``spacing`` (m) along every boundary ring of ``region``."""
    s = positive("spacing", spacing, "m")
    rings = [r for poly in shapely.get_parts(region) if not poly.is_empty
             for r in (poly.exterior, *poly.interiors)]
    pts = [shapely.get_coordinates(shapely.line_interpolate_point(r, np.arange(0.0, r.length, s)))
           for r in rings]
    return np.concatenate(pts) if pts else np.zeros((0, 2))


def beacon_points(obstacle_map: ObstacleMap, config: AOASSConfig) -> np.ndarray:
    """M-ANCHORO's beacon points (K, 2) (m) in SCAN order after pruning (steps 1-4)."""
    m = config.edge_margin
    a = lattice_side(config.radio_range, m)
    lattice, rows = triangle_lattice(obstacle_map.width, obstacle_map.height, a, m)
    row_y = np.unique(lattice[:, 1])
    clearance = config.anchor_radius + DETOUR_MARGIN + LINK_MARGIN
    # the points the follower can reach: off the dilated obstacles, in the main free space at
    # its own clearance (the candidates, on the dilated region's boundary, lie well inside it)
    main = main_free_part(obstacle_map, min(link_clearances(config)), m)
    shapely.prepare(main)

    def reachable(p: np.ndarray) -> np.ndarray:
        return p[shapely.intersects_xy(main, p[:, 0], p[:, 1])]

    points = reachable(lattice[~obstacle_map.inside_obstacle(lattice, dilation=clearance)])
    samples = free_samples(obstacle_map)
    heard = hearing(points, samples, obstacle_map, config)
    if obstacle_map.polygons:
        candidates = reachable(boundary_points(free_region(obstacle_map, clearance, m), a / 2))
        heard_c = hearing(candidates, samples, obstacle_map, config)
        extra = restore_coverage(points, candidates, heard, heard_c, config)
        points = np.vstack([points, candidates[extra]])
        heard = np.vstack([heard, heard_c[extra]])
    keep = prune(points, heard, config)
    points = points[keep]
    return points[scan_order(points, row_y)]


def plan(obstacle_map: ObstacleMap, config: AOASSConfig) -> WaypointPath:
    """The beacon points in SCAN order, joined by
    :func:`~aoass_env.planning.baselines.common.linked_path`: straight where a disc of the link
    clearance passes, else by the shortest detour, through narrower passages (down to the
    follower's own clearance) only when there is no wider way; a point unreachable even so is
    skipped, so no planned link cuts through an obstacle."""
    return linked_path(obstacle_map, beacon_points(obstacle_map, config), config)


M_ANCHORO = PlannedMethod(
    name="m-anchoro",
    label="M-ANCHORO (reconstructed)",
    source=("Tsai et al., \"M-ANCHORO: Mobile Anchor Node-Based Path Optimization for Full "
            "Coverage Path Planning Algorithm\", 2024 (Hindawi/Wiley journal, venue not "
            "retrieved), doi 10.1155/2024/7347796"),
    plan=plan,
    reconstructed=True,
)
