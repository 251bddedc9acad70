"""OTPP (reconstructed): Z-curve basic squares whose beacon points move beside obstacles.

R.-G. Tsai & P.-H. Tsai, "An Obstacle-Tolerant Path Planning Algorithm for Mobile-Anchor-Node-
Assisted Localization", Sensors 18(3):889, 2018, doi 10.3390/s18030889. The publication [V]:
OTPP extends the Z-curve; the field is divided into basic squares, each split into four
identical sub-squares; the mobile anchor broadcasts at beacon points so that every unknown node
receives three non-collinear beacon positions. A basic square holds at most one obstacle, whose
centre lies on the square's centre beacon point ``c0``; the optimal locations of a beacon point
for a sub-square (those that reach every node of it) form ``reg``, and any three non-collinear
points of ``reg`` localize the whole sub-square (Lemma 2). Without obstacles the range needed is
bounded by the sub-square's diagonal (Lemma 1). The path is a Z per basic square that bends
into a V around the obstacle [R]. No code was published; steps 1-4 are our reading [I]
(docs/baselines.md):

1. Basic squares (:func:`basic_square_side`, :func:`half_lines`): side at most
   ``b = sqrt(2) * (R - sqrt(2) * edge_margin)``, n = ceil(span / b) equal squares per axis of
   the field shrunk by the edge margin (span = width - 2 edge_margin). A sub-square (side at
   most ``b/2``) has diagonal at most ``b / sqrt(2) = R - sqrt(2) * edge_margin``, so each of
   its points is within that distance of each of its corners, and a field point lies at most
   ``sqrt(2) * edge_margin`` outside the shrunk field (the reasoning of
   :func:`~aoass_env.planning.baselines.m_anchoro.lattice_side`): every field point is within R
   of the beacon points on its sub-square's corners (Lemma 1 with the margin).
2. The Z (:func:`z_defaults`): per basic square seven default beacon points, visited bottom-left,
   bottom-middle, bottom-right, ``c0``, top-left, top-middle, top-right (the orientation of
   :func:`~aoass_env.planning.classical.z_curve_vertices`: the first stroke runs along the
   bottom), basic squares in Morton order (:func:`~aoass_env.planning.classical.morton_cells`).
   Each sub-square owns three of its corners (:func:`sub_square_slots`), the vertices of a
   right triangle: its outer corner, ``c0`` and the edge midpoint the Z's horizontal stroke
   passes through.
3. Obstacle tolerance (:func:`choose_points`): a point *serves* a sub-square when every free
   sample point (2 m grid; samples outside the shrunk field belong to the nearest border
   sub-square) hears it (range and line of sight, the decision of
   :func:`~aoass_env.planning.baselines.m_anchoro.hearing`, vectorised in
   :func:`hearing_pairs`). Candidates: a field-aligned ``CANDIDATE_SPACING`` grid over the
   sub-square and a band of ``R - sub-square side + 2 m`` around it (no point farther out is
   within R of the samples along the far edge), inside
   :func:`~aoass_env.planning.baselines.common.reachable_region` (the field
   shrunk by the edge margin minus the obstacles dilated by the link clearance, anchor radius +
   detour margin + ``LINK_MARGIN``, and only where the follower's clearance connects it to the
   largest free part). ``reg`` = the candidates that serve the sub-square, found on that grid
   rather than by extending the obstacle's sides as the paper does. Its three defaults
   are checked in Z order; one outside the region, not serving, or too close to collinear with
   the points already chosen (:func:`spread` below ``NONCOLLINEAR_FACTOR`` x
   ``collinearity_tol``) is replaced by the ``reg`` point nearest to it that keeps the points
   apart. When ``reg`` is empty (dense maps: the one-obstacle assumption broken) the candidate
   heard by the most of the samples that also hear the points chosen so far is taken, nearest
   first among ties. Sub-squares without free samples get no points.
4. Order and links (:func:`beacon_points`, :func:`plan`): the points in Z/Morton order, a moved
   point in the slot of the default it replaces (several replacements of one slot, e.g. ``c0``
   moved four ways, in the order of the shortest chain from the previous point to the next
   default); a position already visited is not visited again (shared corners included).
   Consecutive points are joined straight when a disc of the link clearance passes and by the
   shortest detour of :class:`~aoass_env.planning.detour.DetourPlanner` otherwise (the V bend
   around the obstacle); when no detour exists at that clearance, at half the link margin, then
   at the follower's own clearance
   (:func:`~aoass_env.planning.baselines.common.link_clearances`); a point unreachable even so
   is skipped.

In the simulator the anchor beacons every ``beacon_interval`` along the whole path (the common
rule), which can only add coverage.
"""

from __future__ import annotations

import itertools
import math
from typing import NamedTuple

import numpy as np
import shapely

from aoass_env.config import AOASSConfig
from aoass_env.maps import ObstacleMap
from aoass_env.planning.baselines.common import (
    LINK_MARGIN,
    link_clearances,
    linked_path,
    reachable_region,
)
from aoass_env.planning.baselines.m_anchoro import SAMPLE_SPACING, free_samples, lattice_side
from aoass_env.planning.classical import morton_cells
from aoass_env.planning.detour import DETOUR_MARGIN
from aoass_env.planning.path import WaypointPath
from aoass_env.planning.sweep import PlannedMethod
from aoass_env.radio import LineOfSight
from aoass_env.validators import positive, real

#: Spacing (m) of the grid of candidate positions a beacon point may move to.
CANDIDATE_SPACING = 1.5
#: Candidates whose hearing is computed at a time, nearest first (the search for the nearest
#: point of reg usually ends in the first batch).
SEARCH_BATCH = 16
#: Three points count as non-collinear when the root of the smallest eigenvalue of their
#: scatter is at least this times ``collinearity_tol`` (Eq. 18 with slack); two points must be
#: twice that apart (:func:`spread`).
NONCOLLINEAR_FACTOR = 2.0
#: The Z of one basic square in half-side units from its lower-left corner: bottom-left,
#: bottom-middle, bottom-right, centre c0, top-left, top-middle, top-right.
Z_OFFSETS = np.array([[0, 0], [1, 0], [2, 0], [1, 1], [0, 2], [1, 2], [2, 2]])


def basic_square_side(radio_range: float, margin: float) -> float:
    """Largest basic-square side b (m) = sqrt(2) * (R - sqrt(2) * margin): a sub-square's
    diagonal plus a field point's distance outside the shrunk field stays within R."""
    return math.sqrt(2.0) * lattice_side(radio_range, margin)


def half_lines(extent: float, side: float, margin: float) -> np.ndarray:
    """(2n + 1,) coordinates (m) of the basic squares' edges and midlines along one axis of
    ``extent`` (m) shrunk by ``margin``: n = ceil(span / side) equal basic squares."""
    e, s = positive("extent", extent, "m"), positive("side", side, "m")
    margin = real("margin", margin, "m", low=0.0, high=e / 2, high_open=True)
    n = max(1, math.ceil((e - 2 * margin) / s - 1e-9))
    return np.linspace(margin, e - margin, 2 * n + 1)


def z_defaults(hx: np.ndarray, hy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The Z's default beacon points over the half-lines ``hx``, ``hy`` (m): (7C, 2) positions
    (m) and (7C, 2) integer half-grid nodes, basic squares in Morton order, each in the order
    of :data:`Z_OFFSETS`. Shared corners appear once per basic square."""
    cells = morton_cells((len(hx) - 1) // 2, (len(hy) - 1) // 2)
    nodes = (2 * cells[:, None, :] + Z_OFFSETS[None]).reshape(-1, 2)
    return np.stack([hx[nodes[:, 0]], hy[nodes[:, 1]]], axis=1), nodes


def sub_square_slots(sub: tuple[int, int]) -> list[tuple[int, int]]:
    """The half-grid nodes of sub-square ``sub`` (column, row in half-squares) that carry its
    default beacon points, in Z order: its corners except the middle of the basic square's
    left or right edge (the Z does not pass there)."""
    base = (sub[0] // 2 * 2, sub[1] // 2 * 2)
    corners = {(sub[0] + dx, sub[1] + dy) for dx in (0, 1) for dy in (0, 1)}
    return [(base[0] + int(ox), base[1] + int(oy)) for ox, oy in Z_OFFSETS
            if (base[0] + ox, base[1] + oy) in corners]


def sub_square_of(points: np.ndarray, hx: np.ndarray, hy: np.ndarray) -> np.ndarray:
    """(M, 2) sub-square (column, row) of each point (m); points outside the shrunk field
    belong to the nearest border sub-square."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    col = np.clip(np.searchsorted(hx, pts[:, 0], side="right") - 1, 0, len(hx) - 2)
    row = np.clip(np.searchsorted(hy, pts[:, 1], side="right") - 1, 0, len(hy) - 2)
    return np.stack([col, row], axis=1)


def spread(chosen: np.ndarray, candidates: np.ndarray) -> np.ndarray:
    """(C,) how far from collinear each candidate (C, 2) makes it with ``chosen`` (k, 2) (m):
    with k >= 2 the root of the smallest eigenvalue of the scatter of all k + 1 points (Eq. 18's
    measure); with k = 1 half the distance to the chosen point (a third point can bring two
    points D apart to at most D / sqrt(2), so this leaves it room); with k = 0 infinite."""
    c = np.asarray(candidates, dtype=np.float64).reshape(-1, 2)
    k = len(chosen)
    if k == 0:
        return np.full(len(c), np.inf)
    if k == 1:
        return np.linalg.norm(c - chosen[0], axis=1) / 2
    pts = np.concatenate([np.broadcast_to(chosen, (len(c), k, 2)), c[:, None]], axis=1)
    d = pts - pts.mean(axis=1, keepdims=True)
    sxx, syy, sxy = (d[..., 0] ** 2).sum(1), (d[..., 1] ** 2).sum(1), (d[..., 0] * d[..., 1]).sum(1)
    low = (sxx + syy) / 2 - np.hypot((sxx - syy) / 2, sxy)
    return np.sqrt(np.maximum(low, 0.0))


def candidate_grid(box: tuple[float, float, float, float], region: shapely.Geometry,
                   spacing: float = CANDIDATE_SPACING) -> np.ndarray:
    """Points (C, 2) (m) of the field-aligned ``spacing`` grid inside ``box`` (x0, y0, x1, y1)
    and ``region``."""
    x0, y0, x1, y1 = box
    xs = spacing * np.arange(math.ceil(x0 / spacing), math.floor(x1 / spacing) + 1)
    ys = spacing * np.arange(math.ceil(y0 / spacing), math.floor(y1 / spacing) + 1)
    grid = np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1).reshape(-1, 2)
    return grid[shapely.intersects_xy(region, grid[:, 0], grid[:, 1])]


def hearing_pairs(points: np.ndarray, samples: np.ndarray, los: LineOfSight | None,
                  radio_range: float) -> np.ndarray:
    """(P, S) True where sample s hears a beacon at point p: the decision of
    :func:`~aoass_env.planning.baselines.m_anchoro.hearing` (unit disk, line of sight when
    ``los`` is given), with one line-of-sight query for all pairs in range."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    d = pts[:, None] - samples[None]
    heard = (d ** 2).sum(axis=2) <= radio_range * radio_range
    if los is not None and heard.any():
        i, j = np.nonzero(heard)
        blocked = los.blocked(samples[j], pts[i], start_inside=np.zeros(len(j), dtype=bool))
        heard[i[blocked], j[blocked]] = False
    return heard


class _Candidates:
    """Candidate positions of one sub-square with their hearing rows, computed on demand."""

    def __init__(self, points: np.ndarray, samples: np.ndarray, los: LineOfSight | None,
                 radio_range: float) -> None:
        self.points, self.samples, self.los, self.radio_range = points, samples, los, radio_range
        self.heard = np.zeros((len(points), len(samples)), dtype=bool)
        self.known = np.zeros(len(points), dtype=bool)

    def rows(self, index: np.ndarray) -> np.ndarray:
        """Hearing rows (len(index), S) of the candidates ``index``."""
        todo = index[~self.known[index]]
        if len(todo):
            self.heard[todo] = hearing_pairs(self.points[todo], self.samples, self.los,
                                             self.radio_range)
            self.known[todo] = True
        return self.heard[index]

    def nearest(self, p: np.ndarray, pool: np.ndarray, joint: np.ndarray) -> int:
        """The candidate of ``pool`` heard by every sample in ``joint`` nearest to ``p`` (a
        point of reg), else the one heard by the most of them, nearest first among ties.
        Candidates are tried nearest first in batches, so the search usually stops early."""
        pool = pool[np.argsort(np.linalg.norm(self.points[pool] - p, axis=1), kind="stable")]
        far = np.linalg.norm(self.points[pool, None] - self.samples[None, joint], axis=2)
        in_range = (far <= self.radio_range).all(axis=1)
        for batch in np.array_split(pool[in_range], max(1, in_range.sum() // SEARCH_BATCH)):
            full = np.flatnonzero(self.rows(batch)[:, joint].all(axis=1))
            if len(full):
                return int(batch[full[0]])
        score = self.rows(pool)[:, joint].sum(axis=1)
        return int(pool[np.argmax(score)])


def choose_points(defaults: np.ndarray, samples: np.ndarray, box: tuple[float, ...],
                  region: shapely.Geometry, los: LineOfSight | None, config: AOASSConfig
                  ) -> np.ndarray:
    """One sub-square's three beacon points (3, 2) (m) from its ``defaults`` (3, 2) and free
    ``samples`` (S, 2) (step 3 of the module docstring); candidates come from ``box``, hearing
    from ``los`` (None: no line of sight) and ``config.radio_range``. A row is NaN where a
    default lies outside the region and ``box`` holds no candidate (no point for that slot)."""
    min_spread = NONCOLLINEAR_FACTOR * config.collinearity_tol
    free = shapely.dwithin(region, shapely.points(defaults), 1e-9)
    heard = hearing_pairs(defaults, samples, los, config.radio_range)
    chosen, joint = np.zeros((0, 2)), np.ones(len(samples), dtype=bool)
    cand: _Candidates | None = None
    out = np.full((len(defaults), 2), np.nan)
    for k, (p, ok, row) in enumerate(zip(defaults, free, heard, strict=True)):
        if not (ok and row.all() and spread(chosen, p)[0] >= min_spread):
            if cand is None:
                cand = _Candidates(candidate_grid(box, region), samples, los,
                                   config.radio_range)
            room = spread(chosen, cand.points)
            if len(room):
                pool = np.flatnonzero(room >= min(min_spread, room.max()))
                best = cand.nearest(p, pool, joint)
                p, row = cand.points[best], cand.rows(np.array([best]))[0]
            elif not ok:
                continue
        out[k] = p
        chosen, joint = np.vstack([chosen, p]), joint & row
    return out


def _chain(points: list[np.ndarray], start: np.ndarray | None, end: np.ndarray | None
           ) -> list[np.ndarray]:
    """``points`` (a few) in the order of the shortest chain from ``start`` to ``end``."""
    def length(order: tuple[int, ...]) -> float:
        seq = [start] * (start is not None) + [points[i] for i in order] + [end] * (end is not None)
        return sum(float(np.hypot(*(b - a))) for a, b in itertools.pairwise(seq))
    return [points[i] for i in min(itertools.permutations(range(len(points))), key=length)]


class _SubSquares(NamedTuple):
    """What steps 1-3 share for one map: the Z's defaults and their grid nodes, the region the
    points may move in, line of sight (None without it) and, per sub-square with free samples
    in Z order, (sub-square, its three slots, its candidates' box, its samples)."""
    defaults: np.ndarray
    nodes: np.ndarray
    region: shapely.Geometry
    los: LineOfSight | None
    squares: list[tuple[tuple[int, int], list[tuple[int, int]], tuple[float, ...], np.ndarray]]


def _sub_squares(obstacle_map: ObstacleMap, config: AOASSConfig) -> _SubSquares:
    """Steps 1-2 and the inputs of step 3 for every sub-square (module docstring)."""
    m, r = config.edge_margin, config.radio_range
    side = basic_square_side(r, m)
    hx, hy = (half_lines(e, side, m) for e in (obstacle_map.width, obstacle_map.height))
    defaults, nodes = z_defaults(hx, hy)
    region = reachable_region(obstacle_map, config.anchor_radius + DETOUR_MARGIN + LINK_MARGIN, m,
                              min(link_clearances(config)))
    samples = free_samples(obstacle_map)
    los = LineOfSight(obstacle_map) if config.line_of_sight else None
    owner = sub_square_of(samples, hx, hy)
    squares = []
    for sub in sorted({tuple(s) for s in owner.tolist()}):
        reach = r - min(hx[sub[0] + 1] - hx[sub[0]], hy[sub[1] + 1] - hy[sub[1]]) \
            + SAMPLE_SPACING
        box = (hx[sub[0]] - reach, hy[sub[1]] - reach, hx[sub[0] + 1] + reach,
               hy[sub[1] + 1] + reach)
        mine = samples[(owner[:, 0] == sub[0]) & (owner[:, 1] == sub[1])]
        squares.append((sub, sub_square_slots(sub), box, mine))
    return _SubSquares(defaults, nodes, region, los, squares)


def served_sub_squares(obstacle_map: ObstacleMap, config: AOASSConfig) -> tuple[int, int]:
    """(sub-squares whose ``reg`` is not empty, sub-squares with free samples): how often
    Lemma 2's premise holds on ``obstacle_map`` (some candidate serves every sample of the
    sub-square); docs/baselines.md reports it per density
    (``scripts/baselines_table.py --table otpp``)."""
    shared = _sub_squares(obstacle_map, config)
    served = sum(
        bool(hearing_pairs(candidate_grid(box, shared.region), mine, shared.los,
                           config.radio_range).all(axis=1).any())
        for _, _, box, mine in shared.squares)
    return served, len(shared.squares)


def beacon_points(obstacle_map: ObstacleMap, config: AOASSConfig) -> np.ndarray:
    """OTPP's beacon points (K, 2) (m) in Z/Morton order (steps 1-4 without the links)."""
    shared = _sub_squares(obstacle_map, config)
    defaults, nodes = shared.defaults, shared.nodes
    default_at = {tuple(n): p for n, p in zip(nodes.tolist(), defaults, strict=True)}
    chosen: dict[tuple[tuple[int, int], tuple[int, int]], np.ndarray] = {}
    for sub, slots, box, mine in shared.squares:
        points = choose_points(np.array([default_at[s] for s in slots]), mine, box,
                               shared.region, shared.los, config)
        chosen.update({(sub, s): p for s, p in zip(slots, points, strict=True)
                       if not np.isnan(p).any()})
    ordered: list[np.ndarray] = []
    seen: set[tuple[float, float]] = set()
    for k, node in enumerate(map(tuple, nodes.tolist())):
        offset = Z_OFFSETS[k % len(Z_OFFSETS)]
        base = (node[0] - int(offset[0]), node[1] - int(offset[1]))
        subs = [(base[0] + i, base[1] + j) for i in (0, 1) for j in (0, 1)]
        here = {tuple(chosen[(s, node)]) for s in subs if (s, node) in chosen} - seen
        nxt = defaults[k + 1] if k + 1 < len(defaults) else None
        ordered.extend(_chain([np.array(q) for q in sorted(here)],
                              ordered[-1] if ordered else None, nxt))
        seen |= here
    return np.array(ordered).reshape(-1, 2)


def plan(obstacle_map: ObstacleMap, config: AOASSConfig) -> WaypointPath:
    """The beacon points in Z/Morton order, joined by
    :func:`~aoass_env.planning.baselines.common.linked_path` (straight where a disc of the link
    clearance passes, else the shortest detour, through narrower passages only when there is no
    wider way; points unreachable even so are skipped)."""
    return linked_path(obstacle_map, beacon_points(obstacle_map, config), config)


#: The publication OTPP is rebuilt from.
SOURCE = ("R.-G. Tsai & P.-H. Tsai, \"An Obstacle-Tolerant Path Planning Algorithm for "
          "Mobile-Anchor-Node-Assisted Localization\", Sensors 18(3):889, 2018, "
          "doi 10.3390/s18030889")

OTPP = PlannedMethod(name="otpp", label="OTPP (reconstructed)", source=SOURCE, plan=plan,
                     reconstructed=True)
