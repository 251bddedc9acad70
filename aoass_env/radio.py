"""Link model: which nodes hear a beacon, and which node pairs hear each other.

A link between two points exists when they are within radio range and, with line of sight on,
no obstacle blocks the straight segment between them (docs/radio.md).

**Line of sight.** A segment is *blocked* when its open interior meets the interior of an
obstacle polygon, i.e. shapely's ``relate(segment, polygon)`` matches ``'T********'``. In the
generic case this means the segment properly crosses an obstacle edge. Touching a vertex from
outside, running along an edge, or ending on an obstacle's boundary does not block; a segment
through an obstacle from vertex to vertex (a square's diagonal) or lying inside an obstacle does.
:class:`LineOfSight` decides this exactly: a grid of buckets over the edges gives each segment
the edges of the buckets it passes (a superset of those it meets), an orientation test with
Shewchuk's floating-point error bound settles every pair whose signs are certain, and the rare
segments with an uncertain or degenerate contact (a vertex on the segment, collinear overlap) are
settled in exact rational arithmetic (:func:`aoass_env.segments.meets_interior`; GEOS's
``relate``, used before, rounds and missed segments grazing a vertex by 1e-17 m). The grid walk, the
orientation tests and the range test run compiled (numba, :func:`_hear`); the answer does not
depend on which candidate edges are tested beyond those the segment meets, so it is exact.

**Radio irregularity** (DOI model, He et al. 2003): each transmitter has range factors K(theta)
at 1 degree resolution, a closed random walk with ``|K_i - K_{i-1}| <= doi`` (also from 359 to
0 degrees) clipped to ``[1 - doi, 1 + doi]``; a receiver in direction theta hears it up to
``R * K(theta)``. ``doi = 0`` is the unit disk exactly.
"""

from __future__ import annotations

from collections.abc import Sequence
from fractions import Fraction
from functools import cached_property

import numpy as np
import shapely
from scipy.spatial import cKDTree

from aoass_env.config import AOASSConfig
from aoass_env.jit import njit
from aoass_env.maps import ObstacleMap
from aoass_env.segments import CLEAR, CONTACT, CROSSES, EdgeGrid, meets_interior, segment_status
from aoass_env.validators import integer, positive, real

__all__ = ["LineOfSight", "Radio", "doi_pattern", "points_within", "range_factor",
           "receivers_at"]

#: Relative slack of kd-tree queries; candidates are then filtered with the exact criterion.
_QUERY_SLACK = 1e-9


def _points(value: object, name: str, *, single: bool = False) -> np.ndarray:
    """Finite float64 points: (M, 2), or (2,) when ``single``; errors name ``name``."""
    try:
        pts = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be numeric coordinates in metres: {exc}") from None
    if pts.shape != (2,) if single else (pts.ndim != 2 or pts.shape[1] != 2):
        shape = "(2,)" if single else "(M, 2)"
        raise ValueError(f"{name} must have shape {shape}, got {pts.shape}")
    if not np.isfinite(pts).all():
        raise ValueError(f"{name} must be finite coordinates in metres")
    return pts


#: What :func:`_hear` says of a candidate beyond :data:`~aoass_env.segments.CONTACT`.
_HEARD, _BLOCKED = 0, 1


@njit
def points_within(xs: np.ndarray, ys: np.ndarray, among: np.ndarray, x: float, y: float,
                  reach2: float) -> np.ndarray:
    """Sorted int64 indices of the points (``xs``, ``ys``) (m) that ``among`` marks whose
    squared distance to (``x``, ``y``) is at most ``reach2`` (m^2), by
    ``dx * dx + dy * dy <= reach2`` with ``dx = xs - x`` (compiled). ValueError unless the
    three arrays have one entry per point (a shorter one used to be read past its end)."""
    if len(ys) != len(xs) or len(among) != len(xs):
        raise ValueError("points_within: xs, ys and among must have one entry per point")
    out = np.empty(len(xs), dtype=np.int64)
    n = 0
    for i in range(len(xs)):
        if among[i]:
            dx = xs[i] - x
            dy = ys[i] - y
            if dx * dx + dy * dy <= reach2:
                out[n] = i
                n += 1
    return out[:n]


@njit
def _hear(xs: np.ndarray, ys: np.ndarray, among: np.ndarray, inside: np.ndarray, x: float,
          y: float, reach2: float, px: np.ndarray, py: np.ndarray, qx: np.ndarray,
          qy: np.ndarray, x0: float, y0: float, cell: float, nx: int, ny: int,
          first: np.ndarray, members: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(candidates, status) of a beacon at (``x``, ``y``): :func:`points_within`'s points, and
    for each the line of sight from the point to the beacon (:func:`~aoass_env.segments.
    segment_status`), settled by the point's side (``inside``) where it meets no edge:
    :data:`_HEARD`, :data:`_BLOCKED`, or :data:`~aoass_env.segments.CONTACT` for the exact
    rational test."""
    cand = points_within(xs, ys, among, x, y, reach2)
    status = np.empty(len(cand), dtype=np.int8)
    seen = np.full(len(px), -1, dtype=np.int64)
    for k in range(len(cand)):
        i = cand[k]
        found = segment_status(xs[i], ys[i], x, y, px, py, qx, qy, x0, y0, cell, nx, ny,
                               first, members, seen, k)
        if found == CLEAR:
            status[k] = _BLOCKED if inside[i] else _HEARD
        else:
            status[k] = _BLOCKED if found == CROSSES else CONTACT
    return cand, status


class LineOfSight:
    """Exact, vectorised line-of-sight test against the obstacles of one map.

    Args:
        obstacle_map: the static obstacles; its edges (a grid of buckets) and polygons
            (STRtree, for the exact contacts) are indexed once.
    """

    def __init__(self, obstacle_map: ObstacleMap) -> None:
        if not isinstance(obstacle_map, ObstacleMap):
            raise TypeError(f"obstacle_map must be an ObstacleMap, got {type(obstacle_map)!r}")
        self._grid = EdgeGrid(obstacle_map.edges)
        self._polygons = obstacle_map.shapes
        self._polygon_tree = shapely.STRtree(self._polygons)
        self._exact_rings: dict[int, list[list[tuple[Fraction, Fraction]]]] = {}

    @classmethod
    def for_map(cls, obstacle_map: ObstacleMap) -> LineOfSight:
        """The line-of-sight test of ``obstacle_map``, built once per map (maps are immutable):
        the radios on one map share it, so :func:`receivers_at` can test their links at once."""
        return obstacle_map.derived(("line of sight", cls), lambda: cls(obstacle_map))

    def inside(self, points: np.ndarray) -> np.ndarray:
        """Mask of points (M, 2) [m] strictly inside some obstacle polygon.

        Unlike :meth:`ObstacleMap.inside_obstacle` (interior of the union clipped to the field)
        this is per polygon and unclipped, matching the line-of-sight semantics.
        """
        pts = _points(points, "points")
        mask = np.zeros(len(pts), dtype=bool)
        if len(pts) and len(self._polygons):
            hit, _ = self._polygon_tree.query(shapely.points(pts), predicate="within")
            mask[hit] = True
        return mask

    def blocked(self, starts: np.ndarray, ends: np.ndarray, *,
                start_inside: np.ndarray | None = None) -> np.ndarray:
        """Mask (M,) of segments ``starts[m] -> ends[m]`` [m] that an obstacle blocks.

        ``starts`` and ``ends`` are (M, 2), or one of them a single point (2,) shared by all
        segments. ``start_inside`` optionally gives :meth:`inside` of the start points (M,)
        when the caller has it cached.
        """
        a, b = (np.asarray(v, dtype=np.float64) for v in (starts, ends))
        a = _points(a, "starts", single=a.ndim == 1)
        b = _points(b, "ends", single=b.ndim == 1)
        if a.ndim == b.ndim == 2 and len(a) != len(b):
            raise ValueError(f"starts {a.shape} and ends {b.shape} must have the same length")
        m = len(b) if b.ndim == 2 else len(a) if a.ndim == 2 else 1
        a, b = np.broadcast_to(a, (m, 2)), np.broadcast_to(b, (m, 2))
        if start_inside is None:
            start_inside = self.inside(a)
        else:
            start_inside = np.asarray(start_inside, dtype=bool)
            if start_inside.shape != (m,):
                raise ValueError(f"start_inside must have shape ({m},), got {start_inside.shape}")
        return self._blocked(a, b, start_inside)

    def _blocked(self, a: np.ndarray, b: np.ndarray, a_inside: np.ndarray) -> np.ndarray:
        """:meth:`blocked` of checked arrays; each segment's answer depends on it alone."""
        m = len(a)
        if m == 0 or len(self._polygons) == 0:
            return np.zeros(m, dtype=bool)
        status = self._grid.statuses(a, b)
        # No contact with any edge: the closed segment lies wholly inside or outside each
        # obstacle, like its start point.
        blocked = np.where(status == CLEAR, a_inside, status == CROSSES)
        contact = status == CONTACT
        if contact.any():
            blocked[contact] = self._blocked_exact(a[contact], b[contact])
        return blocked

    def _blocked_exact(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """The exact answer (:func:`~aoass_env.segments.meets_interior`) for the few segments
        ``a[k] -> b[k]`` ((K, 2), or ``b`` one point (2,) they share) with a degenerate contact,
        against the polygons whose bounding boxes they meet."""
        segs = np.empty((len(a), 2, 2))
        segs[:, 0] = a
        segs[:, 1] = b
        point = np.all(segs[:, 0] == segs[:, 1], axis=1)
        geoms = np.where(point, shapely.points(segs[:, 0]), shapely.linestrings(segs))
        seg, poly = self._polygon_tree.query(geoms)
        blocked = np.zeros(len(segs), dtype=bool)
        for k, j in zip(seg.tolist(), poly.tolist(), strict=True):
            if not blocked[k] and meets_interior(segs[k, 0].tolist(), segs[k, 1].tolist(),
                                                 self._rings(j)):
                blocked[k] = True
        return blocked

    def _rings(self, j: int) -> list[list[tuple[Fraction, Fraction]]]:
        """Polygon ``j``'s rings as exact vertices, converted once."""
        rings = self._exact_rings.get(j)
        if rings is None:
            polygon = self._polygons[j]
            rings = [[(Fraction(x), Fraction(y)) for x, y in shapely.get_coordinates(r).tolist()]
                     for r in (polygon.exterior, *polygon.interiors)]
            self._exact_rings[j] = rings
        return rings


def doi_pattern(doi: float, rng: np.random.Generator | None, n: int = 1) -> np.ndarray:
    """Range factors K (n, 360) of ``n`` transmitters, one per degree (DOI model).

    Each row is a closed random walk: steps uniform in ``[-doi, doi]``, the steps of the
    dominant sign shrunk proportionally so they sum to zero (the walk closes at 360 degrees),
    centred on 1 and clipped to ``[1 - doi, 1 + doi]``. Clipping is 1-Lipschitz, so
    ``|K_i - K_{i-1}| <= doi`` holds for every i, 359 -> 0 included (up to float rounding).
    ``doi = 0`` gives all ones without touching ``rng``.
    """
    d = real("doi", doi, low=0.0, high=1.0, high_open=True, doc="degree of irregularity")
    n = integer("n", n, "nodes", low=0)
    if d == 0.0:
        return np.ones((n, 360))
    if not isinstance(rng, np.random.Generator):
        raise ValueError("doi > 0 needs rng, a numpy.random.Generator")
    steps = rng.uniform(-d, d, size=(n, 360))
    pos = np.clip(steps, 0.0, None).sum(axis=1, keepdims=True)
    neg = np.clip(steps, None, 0.0).sum(axis=1, keepdims=True)
    total = pos + neg
    with np.errstate(divide="ignore", invalid="ignore"):
        shrink_pos = np.where(total > 0, -neg / pos, 1.0)
        shrink_neg = np.where(total < 0, -pos / neg, 1.0)
    steps = np.where(steps > 0, steps * shrink_pos, steps * shrink_neg)
    walk = np.concatenate([np.zeros((n, 1)), np.cumsum(steps[:, :-1], axis=1)], axis=1)
    walk += 1.0 - walk.mean(axis=1, keepdims=True)
    return np.clip(walk, 1.0 - d, 1.0 + d)


def range_factor(pattern: np.ndarray, dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
    """K of ``pattern`` (360,) or (M, 360) toward directions (dx, dy), nearest whole degree."""
    deg = np.rint(np.degrees(np.arctan2(dy, dx))).astype(np.int64) % 360
    if pattern.ndim == 1:
        return pattern[deg]
    return pattern[np.arange(len(deg)), deg]


class Radio:
    """Who hears whom among static nodes, the mobile anchor and the obstacles of one map.

    Args:
        nodes: (N, 2) node positions [m].
        obstacle_map: the static obstacles.
        radio_range: R [m]; a receiver at squared distance <= (R K(theta))^2 hears the
            transmitter (K = 1 without irregularity).
        line_of_sight: obstacles block links (see :class:`LineOfSight`).
        doi: degree of irregularity in [0, 1); 0 is the unit disk.
        rng: source of the DOI patterns, needed when ``doi > 0``: the anchor's pattern is drawn
            first, then one per node.

    Attributes:
        anchor_pattern: the anchor's K (360,), world frame, index = whole degrees from +x.
        node_patterns: each node's K (N, 360), or None when ``doi == 0``.
    """

    def __init__(self, nodes: np.ndarray, obstacle_map: ObstacleMap, radio_range: float, *,
                 line_of_sight: bool = True, doi: float = 0.0,
                 rng: np.random.Generator | None = None) -> None:
        pts = _points(nodes, "nodes").copy()
        pts.flags.writeable = False
        if not isinstance(obstacle_map, ObstacleMap):
            raise TypeError(f"obstacle_map must be an ObstacleMap, got {type(obstacle_map)!r}")
        r = positive("radio_range", radio_range, "m")
        self.nodes = pts
        self.obstacle_map = obstacle_map
        self.radio_range = r
        self.line_of_sight = bool(line_of_sight)
        self.anchor_pattern = doi_pattern(doi, rng, 1)[0]
        self.doi = float(doi)
        self.node_patterns = doi_pattern(doi, rng, len(pts)) if self.doi > 0 else None
        for pattern in (self.anchor_pattern, self.node_patterns):
            if pattern is not None:
                pattern.flags.writeable = False
        self._tree = cKDTree(pts)
        self._xs, self._ys = pts[:, 0].copy(), pts[:, 1].copy()
        self._all = np.ones(len(pts), dtype=bool)
        self._los = LineOfSight.for_map(obstacle_map) if self.line_of_sight else None
        self._node_inside = self._los.inside(pts) if self._los is not None else None

    @classmethod
    def from_config(cls, nodes: np.ndarray, obstacle_map: ObstacleMap, config: AOASSConfig,
                    rng: np.random.Generator | None = None) -> Radio:
        """A radio with ``radio_range``, ``line_of_sight`` and ``doi`` from ``config``."""
        return cls(nodes, obstacle_map, config.radio_range,
                   line_of_sight=config.line_of_sight, doi=config.doi, rng=rng)

    @property
    def max_range(self) -> float:
        """Farthest possible link, R (1 + doi) [m]."""
        return self.radio_range * (1.0 + self.doi)

    def receivers(self, point: np.ndarray, among: np.ndarray | None = None) -> np.ndarray:
        """Sorted int64 indices of the nodes that hear a beacon broadcast at ``point`` (2,) [m];
        with ``among`` (N,) bool, only of the nodes it marks (the others are not tested)."""
        return self._receivers(_points(point, "point", single=True), among)

    def receivers_many(self, points: np.ndarray) -> list[np.ndarray]:
        """:meth:`receivers` of a beacon at each of ``points`` (K, 2) [m]."""
        return [self._receivers(p, None) for p in _points(points, "points")]

    def _among(self, among: np.ndarray | None) -> np.ndarray:
        """``among`` checked: a bool flag per node (all of them when None)."""
        if among is None:
            return self._all
        if (not isinstance(among, np.ndarray) or among.dtype != bool
                or among.shape != self._all.shape):
            raise ValueError(f"among must be a bool array of shape {self._all.shape} (one flag "
                             f"per node), got {getattr(among, 'dtype', type(among))} "
                             f"{getattr(among, 'shape', '')}")
        return among

    def _receivers(self, p: np.ndarray, among: np.ndarray | None) -> np.ndarray:
        """:meth:`receivers` of the checked point ``p`` (2,) [m]: without irregularity, range
        and sight in one compiled pass (:func:`_hear`; the few contacts only exact arithmetic
        settles go to :meth:`LineOfSight._blocked_exact`)."""
        if self.doi > 0.0 or self._los is None:
            return self._in_sight(p, self._in_range(p, among))
        cand, status = _hear(self._xs, self._ys, self._among(among), self._node_inside,
                             float(p[0]), float(p[1]), self.radio_range * self.radio_range,
                             *self._los._grid.args)
        contact = status == CONTACT
        if contact.any():
            status[contact] = self._los._blocked_exact(self.nodes[cand[contact]], p)
        return cand[status == _HEARD]

    def _in_range(self, p: np.ndarray, among: np.ndarray | None) -> np.ndarray:
        """Sorted int64 indices of the nodes (of ``among``) within the anchor's range
        R K(theta) of the checked point ``p`` (2,) [m], line of sight not yet tested."""
        among = self._among(among)
        if self.doi == 0.0:
            return points_within(self._xs, self._ys, among, float(p[0]), float(p[1]),
                                 self.radio_range * self.radio_range)
        cand = np.array(self._tree.query_ball_point(p, self.max_range * (1 + _QUERY_SLACK),
                                                    return_sorted=True), dtype=np.int64)
        cand = cand[among[cand]]
        d = self.nodes[cand] - p
        dx, dy = d[:, 0], d[:, 1]
        reach = self.radio_range
        if self.doi > 0:
            reach = reach * range_factor(self.anchor_pattern, dx, dy)
        return cand[dx * dx + dy * dy <= reach * reach]

    def _in_sight(self, p: np.ndarray, cand: np.ndarray) -> np.ndarray:
        """The nodes of ``cand`` with line of sight to the checked point ``p`` (2,) [m]."""
        if self._los is not None and len(cand):
            start = self.nodes[cand]
            cand = cand[~self._los._blocked(start, np.broadcast_to(p, start.shape),
                                            self._node_inside[cand])]
        return cand

    def node_links(self) -> np.ndarray:
        """(E, 2) int64 node pairs i < j that hear each other, sorted (read-only, cached).

        With ``doi > 0`` a link needs both directions: each node within the other's range.
        """
        return self._links

    @cached_property
    def _links(self) -> np.ndarray:
        pairs = self._tree.query_pairs(self.max_range * (1 + _QUERY_SLACK),
                                       output_type="ndarray").astype(np.int64).reshape(-1, 2)
        i, j = pairs[:, 0], pairs[:, 1]
        d = self.nodes[j] - self.nodes[i]
        d2 = d[:, 0] ** 2 + d[:, 1] ** 2
        reach = np.full(len(pairs), self.radio_range)
        if self.node_patterns is not None:
            reach *= np.minimum(range_factor(self.node_patterns[i], d[:, 0], d[:, 1]),
                                range_factor(self.node_patterns[j], -d[:, 0], -d[:, 1]))
        pairs = pairs[d2 <= reach * reach]
        if self._los is not None and len(pairs):
            i, j = pairs[:, 0], pairs[:, 1]
            pairs = pairs[~self._los.blocked(self.nodes[i], self.nodes[j],
                                             start_inside=self._node_inside[i])]
        pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
        pairs.flags.writeable = False
        return pairs


def receivers_at(point: np.ndarray,
                 queries: Sequence[tuple[Radio, np.ndarray | None]]) -> list[np.ndarray]:
    """:meth:`Radio.receivers` ``(point, among)`` of each ``(radio, among)`` of ``queries``: the
    receivers of one beacon at ``point`` (2,) [m] in several radios (the nodes' and the
    coverage map's), the point checked once."""
    p = _points(point, "point", single=True)
    return [radio._receivers(p, among) for radio, among in queries]
