"""ORCA: optimal reciprocal collision avoidance for the anchor (Eq. 8-10).

ORCA (van den Berg, Guy, Lin, Manocha, "Reciprocal n-Body Collision Avoidance", ISRR 2009 /
Springer Tracts in Advanced Robotics 70, 2011; reference library RVO2) turns every obstacle
near the anchor into a half-plane of *permitted* velocities, then picks the permitted velocity
closest to the preferred one:

* Eq. 8-9, the ORCA condition: for a moving disc B, the velocity obstacle VO(tau) holds the
  relative velocities that bring the two discs into contact within the horizon ``tau``; u is
  the smallest change of the current relative velocity that leaves it, n the outward normal at
  the exit point, and ORCA = {v : (v - (v_A + r u)) . n >= 0} where r is the anchor's share of
  the avoidance (``responsibility``: 1 for obstacles that do not reciprocate, as here; RVO2's
  agent-agent case is 1/2). A static polygon edge gives a half-plane the same way with r = 1
  and its own horizon ``time_horizon_obst``.
* Eq. 10: v* = argmin over V_safe of |v - v_pref|, V_safe being the intersection of the
  half-planes and the disc |v| <= max_speed. It is solved by RVO2's incremental 2-D linear
  program (``linearProgram1/2``: the lines are added one by one and the optimum moves onto a
  line only when it violates it). When V_safe is empty, the static-obstacle half-planes stay
  hard and the moving-obstacle ones are relaxed: v* minimises the largest penetration of a
  moving-obstacle half-plane (RVO2's ``linearProgram3``, a 3-D LP solved by projection).

The construction follows RVO2's ``Agent::computeNewVelocity`` case by case: static edges
within ``time_horizon_obst * max_speed + radius`` (m) of the anchor, nearest first, seen from
their free side only (back-face culling); edges whose velocity obstacle earlier static lines
already cover are skipped; collisions with a vertex or a segment give a line through the
origin that forbids going deeper; otherwise the velocity obstacle's cut-off line, cut-off
circles and legs (one vertex's legs when the edge is seen obliquely, the cut-off line's
extension at a non-convex vertex, a neighbouring edge's direction for a leg pointing into it,
in which case projecting on that "foreign" leg adds no line). Moving discs give RVO2's three
cases: projection on the cut-off circle or on a leg, and, when the discs already overlap, on the
cut-off circle of time ``time_step`` (a velocity that separates them within one step).

Static obstacles do not push the anchor out: when it already overlaps an edge, the line only
forbids the velocities that take it deeper (as in RVO2).

Conventions (RVO2's):

* a line is a point ``p`` and a unit direction ``d`` in velocity space (m/s); the permitted
  half-plane lies to the LEFT of ``d``: v is permitted when ``det(d, p - v) <= 0`` with
  ``det(a, b) = a_x b_y - a_y b_x``;
* static obstacles are vertex loops with free space to the RIGHT of every directed edge: a
  solid obstacle is listed counter-clockwise, an enclosure (field border, a hole of free space)
  clockwise (:attr:`aoass_env.maps.ObstacleMap.free_space_loops` has this orientation);
* units: metres, seconds, metres per second.

Differences from RVO2, all numerical: computations are in float64 (RVO2: float32), so the
parallel-line tolerance of the 2-D LP is 1e-10 instead of RVO_EPSILON = 1e-5. The 2-D LP
declares a line infeasible only when the best point on it violates an earlier line by more than
1e-9 m/s (RVO2 gives up on any round-off, e.g. when the lines through the origin of two
collisions leave zero velocity alone, and its fallback then breaks a static line). Degenerate
directions that RVO2 would divide by zero on (a velocity exactly at a cut-off centre, discs
exactly concentric) take a defined fallback. An anchor whose centre projects exactly on the end
of an edge (s = 1) counts as colliding with that end vertex (RVO2 would take the square root of
a negative number there). Moving obstacles are all used: filter far ones before the call (RVO2
keeps the ``max_neighbors`` nearest within ``neighbor_dist``); they are ordered nearest first
as RVO2 orders its neighbours. Static edges at equal distance keep index order (RVO2: its
kd-tree's order; that tree also splits edges crossing its partition lines, which this module
does not need). A double-precision transcription of RVO2's ``Agent.cpp`` gave the same lines
on 12,000 random scenes and the same velocities except where its round-off gave up (above).

Speed: the lines are built compiled (numba: the edge query, RVO2's cases and the moving discs,
:func:`_compiled_lines`), and so are the linear programs (:func:`_solve`), each with the floats
of the Python code it replaced (kept as the tests' oracle).
Build :class:`StaticObstacles` once per map and pass it in; a sequence of loops is converted
on every call. ``python3 benchmarks/orca.py`` prints microseconds per call (``--reference FILE``:
against another version of this module, in the same run).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from aoass_env.jit import njit
from aoass_env.trig import hypot
from aoass_env.validators import positive, real, vec2

__all__ = ["OrcaAgent", "OrcaLines", "StaticObstacles", "active_constraints", "orca_lines",
           "orca_velocity", "solve_velocity"]

#: RVO2's RVO_EPSILON: slack of the "already covered" test (m/s) and the parallel-line
#: tolerance of the 3-D LP's projection (a |det| of unit vectors).
_EPS = 1e-5
#: Parallel-line tolerance of the 2-D LP (|det| of unit directions; float64).
_PARALLEL = 1e-10
#: Round-off slack (m/s) of the 2-D LP's infeasibility tests: a point that violates earlier
#: lines by at most this much is accepted rather than declaring the program infeasible.
_SLACK = 1e-9
#: Relative excess over the speed limit beyond which a solution is pulled back onto the speed
#: circle, toward the origin (which keeps it inside every half-plane the zero velocity meets).
#: A point on the circle computed in float64 exceeds it by a few ulps (~1e-16); a chord end of
#: a line far from the origin (linearProgram3's projected lines of near-antiparallel pairs) can
#: lose ~1e-6 to cancellation in ``dot^2 + r^2 - |p|^2``, as in RVO2.
_OVERSHOOT = 1e-12

#: A line: (point x, point y, direction x, direction y), velocity space (m/s).
_Line = tuple[float, float, float, float]

#: Side (m) of the edge grid's cells (:class:`_EdgeCache`): about the reach of an ORCA or
#: envelope query, so that a query visits a few cells.
_CELL = 4.0


# --------------------------------------------------------------------------------------------
# input checks
# --------------------------------------------------------------------------------------------

def _positive(name: str, value: Any, unit: str, high: float | None = None) -> float:
    """:func:`~aoass_env.validators.positive`, with a fast path for a plain float in range
    (the validators' checks cost about a microsecond each, per ORCA call)."""
    if isinstance(value, float) and 0.0 < value < math.inf and (high is None or value <= high):
        return float(value)
    return positive(name, value, unit, high=high)


#: No moving obstacles, as the compiled lines read them.
_NO_MOVING = np.zeros((0, 5))


def _moving(value: Any) -> np.ndarray:
    """Moving obstacles as a checked (k, 5) float64 array of rows [x, y, vx, vy, radius]."""
    if value is None:
        return _NO_MOVING
    try:
        rows = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError("moving_obstacles must be None or an (n, 5) array of "
                         "[x, y, vx, vy, radius] (m, m/s, m)") from None
    if rows.size == 0:
        return _NO_MOVING
    if rows.ndim != 2 or rows.shape[1] != 5:
        raise ValueError(f"moving_obstacles must have shape (n, 5) [x, y, vx, vy, radius], "
                         f"got {rows.shape}")
    if not np.isfinite(rows).all():
        raise ValueError("moving_obstacles must be finite (NaN or inf found)")
    if (rows[:, 4] < 0.0).any():
        raise ValueError(f"moving_obstacles radii (column 4) must be >= 0 (m), got "
                         f"{rows[:, 4].min()}")
    return rows


# --------------------------------------------------------------------------------------------
# static obstacles
# --------------------------------------------------------------------------------------------

@njit
def _cell(value: float, origin: float, inv: float, count: float) -> int:
    """The grid column (or row) of the coordinate ``value`` (m), clamped to the grid."""
    c = math.floor((value - origin) * inv)
    return int(min(max(c, 0.0), count - 1.0))


@njit
def _edge_cells(edges: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """:class:`_EdgeCache`'s ``cells``: each edge listed in every cell its bounding box meets
    (the cells of its corners by :func:`_cell`, which the query uses too)."""
    x0, y0, inv, nx, ny = grid[0], grid[1], grid[2], grid[3], grid[4]
    columns = int(nx)
    n_cells = columns * int(ny)
    counts = np.zeros(n_cells + 1, np.int64)
    for phase in range(2):
        if phase == 1:                  # offsets past the header, then fill
            total = n_cells + 1
            for c in range(n_cells + 1):
                counts[c], total = total, total + counts[c]
            out = np.empty(total, np.int64)
            fill = np.empty(n_cells + 1, np.int64)
            for c in range(n_cells + 1):    # (a slice copy would compile numba's error text)
                out[c] = fill[c] = counts[c]
        for i in range(edges.shape[0]):
            ax, ay, bx, by = edges[i, 0], edges[i, 1], edges[i, 2], edges[i, 3]
            c0, c1 = _cell(min(ax, bx), x0, inv, nx), _cell(max(ax, bx), x0, inv, nx)
            r0, r1 = _cell(min(ay, by), y0, inv, ny), _cell(max(ay, by), y0, inv, ny)
            for r in range(r0, r1 + 1):
                for c in range(c0, c1 + 1):
                    if phase == 0:
                        counts[r * columns + c] += 1
                    else:
                        out[fill[r * columns + c]] = i
                        fill[r * columns + c] += 1
    return out


@dataclass(frozen=True, eq=False)
class _EdgeCache:
    """What the per-call geometry of :class:`StaticObstacles` reads, built once per obstacle set:
    the compiled code's tables (:func:`_compiled_lines`, :meth:`near`), read-only.

    Vertex i starts edge i, which ends at vertex ``next[i]``; coordinates in m.

    Attributes:
        edges: (V, 9) rows [ax, ay, bx, by, ex, ey, inv_len2, dx, dy]: each edge's start and
            end, its vector end - start, 1 / its squared length (1/m^2) and its unit direction.
        links: (V, 3) int64 rows [next, prev, convex]: the neighbouring vertices and RVO2's
            ``isConvex_``.
        bbox: (4,) bounding box (x0, y0, x1, y1) of the vertices (zeros when empty).
        grid: (5,) a uniform grid of square cells over the bounding box: [x0, y0, 1 / cell
            side (1/m), columns, rows].
        cells: int64 the grid's edge lists: ``cells[c]`` to ``cells[c + 1]`` index the entries
            of cell c (row-major) further on in the same array, the edges whose bounding box
            meets the cell.
    """

    edges: np.ndarray
    links: np.ndarray
    bbox: np.ndarray
    grid: np.ndarray
    cells: np.ndarray
    #: :meth:`StaticObstacles.segments_near`'s read-only (starts, ends) arrays by edge list
    segments: dict = field(default_factory=dict, repr=False)

    @classmethod
    def build(cls, point: np.ndarray, direction: np.ndarray, nxt: np.ndarray, prv: np.ndarray,
              convex: np.ndarray) -> _EdgeCache:
        """From checked (V, 2) points (m), unit directions, (V,) next/prev indices and convexity;
        a ValueError when an edge has zero length."""
        ax, ay = point[:, 0], point[:, 1]
        ex, ey = point[nxt, 0] - ax, point[nxt, 1] - ay
        len2 = ex * ex + ey * ey
        if (len2 <= 0.0).any():
            raise ValueError("StaticObstacles has a zero-length edge (a vertex repeated)")
        lo, hi = ((point.min(axis=0), point.max(axis=0)) if len(point)
                  else (np.zeros(2), np.zeros(2)))
        edges = np.column_stack([ax, ay, point[nxt, 0], point[nxt, 1], ex, ey, 1.0 / len2,
                                 direction]).reshape(-1, 9)
        bbox = np.concatenate([lo, hi])
        grid = np.array([lo[0], lo[1], 1.0 / _CELL,
                         max(math.ceil((hi[0] - lo[0]) / _CELL), 1),
                         max(math.ceil((hi[1] - lo[1]) / _CELL), 1)])
        cache = cls(edges, np.column_stack([nxt, prv, convex]).astype(np.int64).reshape(-1, 3),
                    bbox, grid, _edge_cells(edges, grid) if len(edges)
                    else np.full(2, 2, np.int64))      # no edges: one empty cell
        for array in (cache.edges, cache.links, cache.bbox, cache.grid, cache.cells):
            array.flags.writeable = False
        return cache

    def near(self, px: float, py: float, reach: float) -> list[int]:
        """:meth:`StaticObstacles.edges_near` on checked floats (m), as a list
        (:func:`_near_compiled`)."""
        return _near_compiled(self.edges, self.bbox, self.grid, self.cells, px, py,
                              reach).tolist()


#: How far from unit length (or from its edge's unit vector) a given direction may be
#: (round-off of a normalisation; far below any geometric meaning).
_UNIT_TOLERANCE = 1e-9


@dataclass(frozen=True, eq=False)
class StaticObstacles:
    """RVO2-style obstacle vertices. Each loop is a closed polygon chain; free space lies to the
    RIGHT of each directed edge: a solid obstacle is listed counter-clockwise (as in RVO2), an
    enclosure (field border, a hole) clockwise.

    Vertex i starts edge i, which ends at vertex ``next[i]``.

    Attributes:
        point: (V, 2) float64 vertices (m).
        direction: (V, 2) unit vector from vertex i to ``next[i]``.
        next: (V,) int64 index of the next vertex of the loop.
        prev: (V,) int64 index of the previous vertex of the loop.
        convex: (V,) bool, RVO2's ``isConvex_``: ``leftOf(prev, cur, next) >= 0`` (vertices of
            two-vertex loops are convex).

    The arrays are copied and stored read-only; what each call reads is derived from them once,
    in ``_cache`` (:class:`_EdgeCache`).
    """

    point: np.ndarray
    direction: np.ndarray
    next: np.ndarray
    prev: np.ndarray
    convex: np.ndarray
    _cache: _EdgeCache = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        point = np.array(self.point, dtype=np.float64)        # copies: stored read-only
        v = len(point) if point.ndim == 2 else -1
        if point.ndim != 2 or point.shape[1] != 2 or not np.isfinite(point).all():
            raise ValueError(f"StaticObstacles.point must be a finite (V, 2) array (m), got "
                             f"shape {point.shape}")
        direction = np.array(self.direction, dtype=np.float64)
        if direction.shape != (v, 2) or not np.isfinite(direction).all():
            raise ValueError(f"StaticObstacles.direction must be a finite ({v}, 2) array, got "
                             f"shape {direction.shape}")
        links = {}
        for name in ("next", "prev"):
            index = np.asarray(getattr(self, name))
            if index.shape != (v,) or (v and (not np.issubdtype(index.dtype, np.integer)
                                              or index.min() < 0 or index.max() >= v)):
                raise ValueError(f"StaticObstacles.{name} must be ({v},) integer indices in "
                                 f"[0, {v}), got shape {index.shape}")
            links[name] = index.astype(np.int64)
        if v and (links["next"][links["prev"]] != np.arange(v)).any():
            raise ValueError("StaticObstacles.next and .prev must be inverse permutations")
        if v:
            # the solver reads direction as the edge's unit vector: any other vector (a
            # hand-built one) gave another velocity, silently
            edge = point[links["next"]] - point
            length = np.hypot(edge[:, 0], edge[:, 1])
            if (length == 0.0).any():
                raise ValueError("StaticObstacles.point repeats a vertex (a zero-length edge)")
            if np.abs(direction - edge / length[:, None]).max() > _UNIT_TOLERANCE:
                raise ValueError("StaticObstacles.direction must be the unit vector of each "
                                 "edge, (point[next] - point) / its length (from_loops "
                                 "builds it)")
        convex = np.asarray(self.convex)
        if convex.shape != (v,):
            raise ValueError(f"StaticObstacles.convex must be a ({v},) bool array, got shape "
                             f"{convex.shape}")
        convex = convex.astype(bool)
        for name, array in (("point", point), ("direction", direction), ("next", links["next"]),
                            ("prev", links["prev"]), ("convex", convex)):
            array.setflags(write=False)
            object.__setattr__(self, name, array)

        object.__setattr__(self, "_cache", _EdgeCache.build(
            point, direction, links["next"], links["prev"], convex))

    def __len__(self) -> int:
        """Number of vertices (= number of edges)."""
        return len(self.point)

    @classmethod
    def from_loops(cls, loops: Sequence[ArrayLike]) -> StaticObstacles:
        """Build from vertex loops, each a (k, 2) array (m) with k >= 2.

        Loops follow the orientation convention of the class (solid obstacle counter-clockwise,
        enclosure clockwise). A closing vertex equal to the first one (shapely's ring
        convention) is dropped; any other repeated consecutive vertex is an error.
        """
        if isinstance(loops, np.ndarray) and loops.ndim == 2:
            raise ValueError("static_obstacles must be a sequence of (k, 2) vertex loops, got "
                             f"one array of shape {loops.shape}; wrap it in a list")
        points, nexts, prevs, convexes = [], [], [], []
        start = 0
        for i, loop in enumerate(loops):
            what = (f"static_obstacles[{i}] must be a finite (k, 2) array of vertices (m) "
                    f"with k >= 2")
            try:
                vertices = np.array(loop, dtype=np.float64)
            except (TypeError, ValueError):
                raise ValueError(f"{what}, got {type(loop).__name__}") from None
            if vertices.ndim != 2 or vertices.shape[1] != 2:
                raise ValueError(f"{what}, got shape {vertices.shape}")
            if not np.isfinite(vertices).all():
                raise ValueError(f"{what}, got NaN or inf")
            if len(vertices) > 2 and (vertices[0] == vertices[-1]).all():
                vertices = vertices[:-1]
            k = len(vertices)
            if k < 2:
                raise ValueError(f"{what}, got {k} distinct vertices")
            following = np.roll(vertices, -1, axis=0)
            if ((following - vertices) == 0.0).all(axis=1).any():
                raise ValueError(f"static_obstacles[{i}] repeats a vertex (zero-length edge); "
                                 f"consecutive vertices must differ")
            if k == 2:
                convex = np.ones(2, dtype=bool)
            else:
                preceding = np.roll(vertices, 1, axis=0)
                # RVO2's leftOf(prev, cur, next) = det(prev - next, cur - prev) >= 0
                a, b = preceding - following, vertices - preceding
                convex = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0] >= 0.0
            index = np.arange(start, start + k, dtype=np.int64)
            points.append(vertices)
            nexts.append(np.roll(index, -1))
            prevs.append(np.roll(index, 1))
            convexes.append(convex)
            start += k
        if not points:
            return cls.empty()
        point = np.concatenate(points)
        nxt = np.concatenate(nexts)
        edge = point[nxt] - point
        direction = edge / np.hypot(edge[:, 0], edge[:, 1])[:, None]
        return cls(point, direction, nxt, np.concatenate(prevs), np.concatenate(convexes))

    @classmethod
    def empty(cls) -> StaticObstacles:
        """No static obstacles."""
        return cls(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0, np.int64),
                   np.zeros(0, np.int64), np.zeros(0, bool))

    def edges_near(self, position: ArrayLike, reach: float) -> np.ndarray:
        """Indices i of edges (point[i] -> point[next[i]]) whose distance to position is < reach,
        sorted by distance (vectorised numpy).

        Args:
            position: (2,) query point (m).
            reach: distance bound (m), >= 0.

        Returns:
            (m,) int64 edge indices, nearest first (ties in index order).
        """
        return np.array(self._near(position, reach), dtype=np.int64)

    def _near(self, position: ArrayLike, reach: float) -> list[int]:
        """:meth:`edges_near`'s indices as a list, the arguments checked."""
        px, py = vec2("position", position, "m")
        if not (type(reach) is float and 0.0 <= reach < math.inf):
            reach = real("reach", reach, "m", low=0.0)
        return self._cache.near(px, py, reach)

    def segments_near(self, position: ArrayLike, reach: float) -> tuple[np.ndarray, np.ndarray]:
        """(starts, ends): the end points (m), (m, 2) each, of the :meth:`edges_near` edges
        in its order, ``point[near]`` and ``point[next[near]]``.

        The anchor finds the same few edges period after period: the two arrays are built
        once per list of edges (the last 4096 lists) and shared, read-only.
        """
        return self._segments(tuple(self._near(position, reach)))

    def segments_near_any(self, positions: ArrayLike, reaches: ArrayLike
                          ) -> tuple[np.ndarray, np.ndarray]:
        """(starts, ends) (m), (m, 2) each, of the edges closer than ``reaches[k]`` (m) to
        ``positions[k]`` (m) for some k, in index order: the union of :meth:`segments_near`'s
        edges over the (k, 2) ``positions`` and (k,) ``reaches`` (none for k = 0)."""
        positions = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
        reaches = np.asarray(reaches, dtype=np.float64).reshape(-1)
        if len(reaches) != len(positions):
            raise ValueError(f"reaches must hold one distance per position: {len(positions)} "
                             f"positions, {len(reaches)} reaches")
        union: set[int] = set()
        for position, reach in zip(positions, reaches.tolist(), strict=True):
            union.update(self._near(position, reach))
        return self._segments(tuple(sorted(union)))

    def _segments(self, near: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
        """The shared read-only (starts, ends) of the edges ``near`` (indices, in order)."""
        cache = self._cache
        pair = cache.segments.get(near)
        if pair is None:
            index = np.array(near, dtype=np.int64)
            pair = self.point[index], self.point[self.next[index]]
            for array in pair:
                array.flags.writeable = False
            if len(cache.segments) >= 4096:
                cache.segments.clear()
            cache.segments[near] = pair
        return pair


def _static(value: Any) -> StaticObstacles | None:
    if value is None or isinstance(value, StaticObstacles):
        return value
    if isinstance(value, (str, bytes)):
        raise ValueError("static_obstacles must be None, a StaticObstacles or a sequence of "
                         f"(k, 2) vertex loops, got {value!r}")
    try:
        iter(value)
    except TypeError:
        raise ValueError("static_obstacles must be None, a StaticObstacles or a sequence of "
                         f"(k, 2) vertex loops, got {type(value).__name__}") from None
    return StaticObstacles.from_loops(value)


# --------------------------------------------------------------------------------------------
# ORCA lines
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class OrcaLines:
    """ORCA half-planes in velocity space.

    Attributes:
        point: (n, 2) a point on each line (m/s).
        direction: (n, 2) unit direction; the permitted half-plane is to the LEFT of the
            direction (RVO2 convention): v is permitted when ``det(direction, point - v) <= 0``.
        n_static: the first ``n_static`` lines come from static obstacles (hard constraints).
    """

    point: np.ndarray
    direction: np.ndarray
    n_static: int
    #: the (n, 4) rows [px, py, dx, dy] whose views ``point`` and ``direction`` are, kept (read
    #: only) by :func:`orca_lines` so that :func:`solve_velocity` need not check and copy them
    #: again; None: built elsewhere, checked by the solver
    table: np.ndarray | None = field(default=None, repr=False, compare=False)

    def __len__(self) -> int:
        return len(self.point)


#: No static obstacles, as the compiled lines read them.
_NO_STATIC = StaticObstacles.empty()


@dataclass(frozen=True)
class OrcaAgent:
    """The anchor's side of :func:`orca_lines`, checked once: its radius and speed limit (m,
    m/s), the horizons against moving and static obstacles (s), the control period (s) and its
    share of the avoidance of moving obstacles, in (0, 1]. For a caller that builds lines with
    the same settings period after period (the safety stack): :meth:`lines` checks only what
    changes.

    Raises:
        ValueError: a setting that is not a positive finite number (naming it).
    """

    radius: float
    max_speed: float
    time_horizon: float = 2.0
    time_horizon_obst: float = 2.0
    time_step: float = 0.5
    responsibility: float = 1.0

    def __post_init__(self) -> None:
        for name, unit in (("radius", "m"), ("max_speed", "m/s"), ("time_horizon", "s"),
                           ("time_horizon_obst", "s"), ("time_step", "s")):
            object.__setattr__(self, name, _positive(name, getattr(self, name), unit))
        object.__setattr__(self, "responsibility", _positive(
            "responsibility", self.responsibility, "fraction", high=1.0))

    def lines(self, position: ArrayLike, velocity: ArrayLike,
              static_obstacles: StaticObstacles | Sequence[ArrayLike] | None = None,
              moving_obstacles: ArrayLike | None = None) -> OrcaLines:
        """:func:`orca_lines` with these settings: the anchor at ``position`` (2,) (m) moving
        at ``velocity`` (2,) (m/s) among the obstacles."""
        return _read_only_lines(*_compiled_lines(
            *self._arguments(position, velocity, static_obstacles, moving_obstacles)))

    def velocity(self, position: ArrayLike, velocity: ArrayLike, preferred_velocity: ArrayLike,
                 static_obstacles: StaticObstacles | Sequence[ArrayLike] | None = None,
                 moving_obstacles: ArrayLike | None = None) -> tuple[OrcaLines, np.ndarray]:
        """(:meth:`lines`, Eq. 10's velocity (2,) (m/s) in them closest to
        ``preferred_velocity`` (2,) (m/s)): ``solve_velocity(lines, preferred_velocity,
        max_speed)``'s floats, the lines and the program in one compiled call."""
        args = self._arguments(position, velocity, static_obstacles, moving_obstacles)
        ox, oy = vec2("preferred_velocity", preferred_velocity, "m/s")
        array, n_static, x, y = _lines_and_velocity(*args, ox, oy)
        return _read_only_lines(array, n_static), np.array([x, y])

    def _arguments(self, position: Any, velocity: Any, static_obstacles: Any,
                   moving_obstacles: Any) -> tuple[Any, ...]:
        """:func:`_compiled_lines`'s arguments: the inputs checked, with these settings."""
        px, py = vec2("position", position, "m")
        vx, vy = vec2("velocity", velocity, "m/s")
        static = _static(static_obstacles)
        cache = (static if static is not None else _NO_STATIC)._cache
        return (cache.edges, cache.links, cache.bbox, cache.grid, cache.cells, px, py, vx, vy,
                self.radius, self.max_speed, self.time_horizon_obst, _moving(moving_obstacles),
                self.time_horizon, self.time_step, self.responsibility)


def _read_only_lines(array: np.ndarray, n_static: int) -> OrcaLines:
    """The lines of the compiled (n, 4) rows [px, py, dx, dy], made read-only: the views and
    the solver's rows stay these floats."""
    array.flags.writeable = False
    return OrcaLines(array[:, :2], array[:, 2:], n_static, array)


def orca_lines(position: ArrayLike, velocity: ArrayLike, radius: float, max_speed: float, *,
               static_obstacles: StaticObstacles | Sequence[ArrayLike] | None = None,
               moving_obstacles: ArrayLike | None = None, time_horizon: float = 2.0,
               time_horizon_obst: float = 2.0, time_step: float = 0.5,
               responsibility: float = 1.0) -> OrcaLines:
    """The anchor's ORCA half-planes (Eq. 8-9), static-obstacle lines first
    (:meth:`OrcaAgent.lines` with the settings checked once, for a caller that builds them
    period after period).

    Args:
        position: (2,) anchor position (m).
        velocity: (2,) current anchor velocity (m/s); the lines are built around it.
        radius: anchor radius (m), > 0.
        max_speed: anchor speed limit (m/s), > 0; with ``time_horizon_obst`` it sets how far
            static edges are considered (``time_horizon_obst * max_speed + radius``).
        static_obstacles: None, a :class:`StaticObstacles`, or a sequence of (k, 2) loops.
        moving_obstacles: None or (n, 5) rows [x, y, vx, vy, radius] (m, m/s, m); they do not
            reciprocate.
        time_horizon: horizon against moving obstacles (s).
        time_horizon_obst: horizon against static obstacles (s).
        time_step: control period (s); an overlap with a moving disc is resolved within it.
        responsibility: the anchor's share of the avoidance of moving obstacles, in (0, 1]
            (RVO2's agent-agent case: 0.5).
    """
    agent = OrcaAgent(radius, max_speed, time_horizon, time_horizon_obst, time_step,
                      responsibility)
    return agent.lines(position, velocity, static_obstacles, moving_obstacles)


# --------------------------------------------------------------------------------------------
# linear programs (Eq. 10)
# --------------------------------------------------------------------------------------------

# RVO2's linear programs, compiled on the lines' (n, 4) rows [px, py, dx, dy]. Until issue 20's
# tenth round they ran on Python floats; that code is the tests' oracle
# (tests/safety/orca_floats.py, ``reference_solve``), whose floats these give bit for bit (the
# norms from the correctly rounded ``hypot``, as Python's ``math.hypot`` since 3.11).

@njit
def _lp1(lines: np.ndarray, k: int, speed: float, ox: float, oy: float,
         along_direction: bool) -> tuple[bool, float, float]:
    """(found, x, y): the best point on line k inside the speed disc and lines 0..k-1 (found
    False if there is none): the extreme along (ox, oy) when ``along_direction``, else the
    nearest to (ox, oy)."""
    px, py, dx, dy = lines[k, 0], lines[k, 1], lines[k, 2], lines[k, 3]
    mid = px * dx + py * dy
    disc = mid * mid + speed * speed - (px * px + py * py)
    if disc < 0.0:
        return False, 0.0, 0.0  # the speed disc misses the line
    half = math.sqrt(disc)
    lo, hi = -mid - half, -mid + half
    for i in range(k):
        qx, qy, ex, ey = lines[i, 0], lines[i, 1], lines[i, 2], lines[i, 3]
        cross = dx * ey - dy * ex           # det(d_k, d_i)
        gap = ex * (py - qy) - ey * (px - qx)  # det(d_i, p_k - p_i)
        if -_PARALLEL <= cross <= _PARALLEL:
            if gap < -_SLACK:
                return False, 0.0, 0.0  # parallel, and line k lies in line i's forbidden side
            continue
        cut = gap / cross
        if cross > 0.0:
            if cut < hi:
                hi = cut
        elif cut > lo:
            lo = cut
    if lo > hi:
        # empty interval; accept its middle when that is only round-off (a feasible set that
        # shrank to a point, e.g. lines through the origin), else there is no solution
        t = 0.5 * (lo + hi)
        x, y = px + t * dx, py + t * dy
        for i in range(k):
            qx, qy, ex, ey = lines[i, 0], lines[i, 1], lines[i, 2], lines[i, 3]
            if ex * (qy - y) - ey * (qx - x) > _SLACK:
                return False, 0.0, 0.0
        return True, x, y
    if along_direction:
        t = hi if ox * dx + oy * dy > 0.0 else lo
    else:
        t = dx * (ox - px) + dy * (oy - py)
        t = lo if t < lo else hi if t > hi else t
    return True, px + t * dx, py + t * dy


@njit
def _lp2(lines: np.ndarray, count: int, speed: float, ox: float, oy: float,
         along_direction: bool) -> tuple[int, float, float]:
    """RVO2's linearProgram2 on the first ``count`` lines: (index of the first line that
    cannot be met, or ``count``; x, y). On failure (x, y) is the optimum of the lines before
    that index."""
    if along_direction:
        rx, ry = ox * speed, oy * speed
    elif ox * ox + oy * oy > speed * speed:
        scale = speed / hypot(ox, oy)
        rx, ry = ox * scale, oy * scale
    else:
        rx, ry = ox, oy
    for k in range(count):
        px, py, dx, dy = lines[k, 0], lines[k, 1], lines[k, 2], lines[k, 3]
        if dx * (py - ry) - dy * (px - rx) > 0.0:
            found, x, y = _lp1(lines, k, speed, ox, oy, along_direction)
            if not found:
                return k, rx, ry
            rx, ry = x, y
    return count, rx, ry


@njit
def _lp3(lines: np.ndarray, n_static: int, begin: int, speed: float, rx: float,
         ry: float) -> tuple[float, float]:
    """RVO2's linearProgram3: keep lines[:n_static] hard and minimise the largest violation of
    the others, starting from line ``begin`` with the partial result (rx, ry)."""
    depth = 0.0
    projected = np.empty(lines.shape)
    for i in range(n_static):               # element by element: a slice assignment would
        for j in range(4):                  # make numba compile its shape-error formatting
            projected[i, j] = lines[i, j]
    for i in range(begin, lines.shape[0]):
        px, py, dx, dy = lines[i, 0], lines[i, 1], lines[i, 2], lines[i, 3]
        if dx * (py - ry) - dy * (px - rx) <= depth:
            continue
        # lines of equal violation of line i and each earlier relaxed line j
        count = n_static
        for j in range(n_static, i):
            qx, qy, ex, ey = lines[j, 0], lines[j, 1], lines[j, 2], lines[j, 3]
            cross = dx * ey - dy * ex
            if -_EPS <= cross <= _EPS:
                if dx * ex + dy * ey > 0.0:
                    continue  # same direction: line j adds nothing
                mx, my = 0.5 * (px + qx), 0.5 * (py + qy)
            else:
                along = (ex * (py - qy) - ey * (px - qx)) / cross
                mx, my = px + along * dx, py + along * dy
            nx, ny = ex - dx, ey - dy
            norm = hypot(nx, ny)
            projected[count, 0] = mx
            projected[count, 1] = my
            projected[count, 2] = nx / norm
            projected[count, 3] = ny / norm
            count += 1
        fail, sx, sy = _lp2(projected, count, speed, -dy, dx, True)
        if fail == count:
            rx, ry = sx, sy
        # else: round-off; keep the current result (as RVO2)
        depth = dx * (py - ry) - dy * (px - rx)
    return rx, ry


@njit
def _solve(lines: np.ndarray, n_static: int, px: float, py: float,
           max_speed: float) -> tuple[float, float]:
    """Eq. 10 on the (n, 4) rows ``lines``: linearProgram2, then 3 when it fails; a result
    beyond the speed disc by more than round-off is pulled back onto it (:data:`_OVERSHOOT`)."""
    fail, x, y = _lp2(lines, lines.shape[0], max_speed, px, py, False)
    if fail < lines.shape[0]:
        x, y = _lp3(lines, n_static, fail, max_speed, x, y)
    norm = hypot(x, y)
    if norm > max_speed * (1.0 + _OVERSHOOT):
        scale = max_speed / norm
        x, y = x * scale, y * scale
    return x, y


@njit
def _active(lines: np.ndarray, n_static: int, vx: float, vy: float,
            slack: float) -> tuple[int, int]:
    """(lines, static lines) that ``(vx, vy)`` lies on (within ``slack``, m/s) or violates:
    ``det(d, p - v) > -slack``."""
    active = active_static = 0
    for i in range(lines.shape[0]):
        if lines[i, 2] * (lines[i, 1] - vy) - lines[i, 3] * (lines[i, 0] - vx) > -slack:
            active += 1
            if i < n_static:
                active_static += 1
    return active, active_static


def solve_velocity(lines: OrcaLines, preferred_velocity: ArrayLike,
                   max_speed: float) -> np.ndarray:
    """Eq. 10: the velocity (m/s) in the ORCA half-planes and the disc |v| <= ``max_speed``
    closest to ``preferred_velocity`` (m/s).

    RVO2's linearProgram2 (incremental 2-D LP in the max-speed disc, closest to preferred
    velocity), and linearProgram3 fallback when infeasible (static lines stay hard,
    moving-obstacle lines relaxed by minimising the max penetration).

    Returns:
        (2,) float64 velocity (m/s).
    """
    table = _table(lines)
    ox, oy = vec2("preferred_velocity", preferred_velocity, "m/s")
    max_speed = _positive("max_speed", max_speed, "m/s")
    x, y = _solve(table, lines.n_static, ox, oy, max_speed)
    return np.array([x, y])


def active_constraints(lines: OrcaLines, velocity: ArrayLike,
                       slack: float = 1e-6) -> tuple[int, int]:
    """(all, static): how many of ``lines`` the velocity (2,) (m/s) lies on, within ``slack``
    (m/s), or violates (``det(direction, point - v) > -slack``), and how many of those are
    static lines."""
    table = _table(lines)
    vx, vy = vec2("velocity", velocity, "m/s")
    if not (isinstance(slack, float) and 0.0 <= slack < math.inf):
        slack = real("slack", slack, "m/s", low=0.0)
    return _active(table, lines.n_static, vx, vy, slack)


def _table(lines: OrcaLines) -> np.ndarray:
    """The checked (n, 4) rows [px, py, dx, dy] of ``lines`` (read only): orca_lines' own, or
    built from ``point`` and ``direction`` after checking them and ``n_static``."""
    if not isinstance(lines, OrcaLines):
        raise ValueError(f"lines must be an OrcaLines (from orca_lines), got "
                         f"{type(lines).__name__}")
    if lines.table is not None:     # orca_lines' own (checked, read-only)
        return lines.table
    point = np.asarray(lines.point, dtype=np.float64)
    direction = np.asarray(lines.direction, dtype=np.float64)
    n = len(point)
    if point.shape != (n, 2) or direction.shape != (n, 2):
        raise ValueError(f"lines.point and lines.direction must both have shape (n, 2), got "
                         f"{point.shape} and {direction.shape}")
    if n and not (np.isfinite(point).all() and np.isfinite(direction).all()):
        raise ValueError("lines must be finite (NaN or inf found)")
    if n and np.abs(np.hypot(direction[:, 0], direction[:, 1]) - 1.0).max() > _UNIT_TOLERANCE:
        # the solver assumes unit directions: a longer one gave a velocity off its half-plane
        raise ValueError("lines.direction must hold unit vectors")
    n_static = lines.n_static
    if isinstance(n_static, bool) or not isinstance(n_static, (int, np.integer)) \
            or not 0 <= n_static <= n:
        raise ValueError(f"lines.n_static must be an integer in [0, {n}], got {n_static!r}")
    table = np.concatenate([point, direction], axis=1)
    table.flags.writeable = False
    return table


def orca_velocity(position: ArrayLike, velocity: ArrayLike, preferred_velocity: ArrayLike,
                  radius: float, max_speed: float, *,
                  static_obstacles: StaticObstacles | Sequence[ArrayLike] | None = None,
                  moving_obstacles: ArrayLike | None = None, time_horizon: float = 2.0,
                  time_horizon_obst: float = 2.0, time_step: float = 0.5,
                  responsibility: float = 1.0) -> np.ndarray:
    """= solve_velocity(orca_lines(...), preferred_velocity, max_speed). Returns (2,) float64
    m/s. Arguments as in :func:`orca_lines`; ``preferred_velocity`` (2,) in m/s."""
    agent = OrcaAgent(radius, max_speed, time_horizon, time_horizon_obst, time_step,
                      responsibility)
    return agent.velocity(position, velocity, preferred_velocity, static_obstacles,
                          moving_obstacles)[1]


# --------------------------------------------------------------------------------------------
# the lines (Eq. 8-9), compiled
# --------------------------------------------------------------------------------------------
# `_compiled_lines` is RVO2's `Agent::computeNewVelocity` case by case, compiled with numba.
# Until issue 20's ninth round it ran on Python floats; that code is the tests' oracle
# (tests/safety/orca_floats.py), whose floats the compiled lines give bit for bit. The norms it
# took from Python's `math.hypot`, correctly rounded since Python 3.11, come from
# `aoass_env.trig.hypot`, correctly rounded as well (the C library's hypot, which numba would
# call, is not): the lines are the same on every Python version.

@njit
def _stable_order(keys: np.ndarray) -> np.ndarray:
    """The indices that sort ``keys`` (no NaN), equal keys in index order: ``np.argsort(keys,
    kind="stable")``, by insertion (a few dozen keys; numba compiles it far faster than its
    merge sort)."""
    order = np.arange(len(keys))
    for i in range(1, len(keys)):
        j, k = i, order[i]
        while j > 0 and keys[order[j - 1]] > keys[k]:
            order[j] = order[j - 1]
            j -= 1
        order[j] = k
    return order


@njit
def _near_compiled(edges: np.ndarray, bbox: np.ndarray, grid: np.ndarray, cells: np.ndarray,
                   px: float, py: float, reach: float) -> np.ndarray:
    """Indices of the edges closer than ``reach`` (m) to (px, py), nearest first, from the
    :class:`_EdgeCache` tables: each edge's parameter of its point nearest the query (clipped to
    [0, 1]) and the squared distance to it. With two or more, an edge nearest at its end vertex
    is measured from that vertex itself, so that two edges nearest at their shared vertex tie
    exactly and keep index order (a stable sort).

    Only the edges listed in the grid cells that a square of half side ``reach`` (padded well
    beyond round-off) meets are measured: an edge closer than ``reach`` has its bounding box in
    that square, and the cells of both come from :func:`_cell`, which never decreases with the
    coordinate. The answer is the whole list's, measured in index order."""
    n = edges.shape[0]
    if (n == 0 or px < bbox[0] - reach or px > bbox[2] + reach
            or py < bbox[1] - reach or py > bbox[3] + reach):
        return np.empty(0, dtype=np.int64)
    x0, y0, inv, nx, ny = grid[0], grid[1], grid[2], grid[3], grid[4]
    columns = int(nx)
    pad = reach * (1.0 + 1e-9) + 1e-9
    c0, c1 = _cell(px - pad, x0, inv, nx), _cell(px + pad, x0, inv, nx)
    r0, r1 = _cell(py - pad, y0, inv, ny), _cell(py + pad, y0, inv, ny)
    seen = np.zeros(n, np.bool_)
    candidates = np.empty(n, np.int64)
    count = 0
    for r in range(r0, r1 + 1):
        for c in range(c0, c1 + 1):
            cell = r * columns + c
            for k in range(cells[cell], cells[cell + 1]):
                i = cells[k]
                if not seen[i]:
                    seen[i] = True
                    candidates[count] = i
                    count += 1
    candidates = np.sort(candidates[:count])
    s = np.empty(count)
    dist2 = np.empty(count)
    hits = np.empty(count, np.int64)
    m = 0
    for i in candidates:
        ax, ay, ex, ey = edges[i, 0], edges[i, 1], edges[i, 4], edges[i, 5]
        rx, ry = px - ax, py - ay
        si = (rx * ex + ry * ey) * edges[i, 6]
        si = min(max(si, 0.0), 1.0)
        rx -= si * ex
        ry -= si * ey
        d2 = rx * rx + ry * ry
        if d2 < reach * reach:
            hits[m], s[m], dist2[m] = i, si, d2
            m += 1
    hits, s, dist2 = hits[:m], s[:m], dist2[:m]
    if m > 1:
        for k in range(m):
            if s[k] >= 1.0:
                qx, qy = px - edges[hits[k], 2], py - edges[hits[k], 3]
                dist2[k] = qx * qx + qy * qy
        hits = hits[_stable_order(dist2)]
    return hits


@njit
def _leg(x: float, y: float, dist2: float, radius: float, rad2: float,
         left: bool) -> tuple[float, float]:
    """Unit direction of the left leg (``left``) or the right one: from the anchor, tangent on
    that side to the disc of ``radius`` (m) around the vertex at (x, y) m (squared distance
    ``dist2``)."""
    leg = math.sqrt(max(dist2 - rad2, 0.0))
    if left:
        return (x * leg - y * radius) / dist2, (x * radius + y * leg) / dist2
    return (x * leg + y * radius) / dist2, (y * leg - x * radius) / dist2


@njit
def _push(lines: np.ndarray, n: int, px: float, py: float, dx: float, dy: float) -> int:
    lines[n, 0], lines[n, 1], lines[n, 2], lines[n, 3] = px, py, dx, dy
    return n + 1


@njit
def _on_circle_compiled(lines: np.ndarray, n: int, wx: float, wy: float, cx: float,
                        cy: float, rad: float) -> int:
    """Append the line tangent to the cut-off circle (centre (cx, cy), radius ``rad``, m/s) at
    the point nearest the velocity (cx + wx, cy + wy); a velocity exactly at the centre (RVO2
    divides by zero) takes the side facing the origin. Returns the line count."""
    ux, uy, _ = _unit_or_away(wx, wy, cx, cy)
    return _push(lines, n, cx + rad * ux, cy + rad * uy, uy, -ux)


@njit
def _unit_or_away(wx: float, wy: float, cx: float, cy: float) -> tuple[float, float, float]:
    """(ux, uy, |w|): the unit vector along (wx, wy); for w = 0, the one along -(cx, cy), the
    way away from a centre at (cx, cy) (RVO2 divides by zero there), or (-1, 0) when that is 0
    too."""
    norm = hypot(wx, wy)
    if norm > 0.0:
        return wx / norm, wy / norm, norm
    away = hypot(cx, cy)
    if away > 0.0:
        return -cx / away, -cy / away, norm
    return -1.0, 0.0, norm


@njit
def _compiled_lines(edges: np.ndarray, links: np.ndarray, bbox: np.ndarray, grid: np.ndarray,
                    cells: np.ndarray, px: float,
                    py: float, vx: float, vy: float, radius: float, max_speed: float,
                    tau_obst: float, moving: np.ndarray, tau: float, step: float,
                    share: float) -> tuple[np.ndarray, int]:
    """(lines (n, 4) as (px, py, dx, dy) rows, n_static): the anchor's ORCA lines, static ones
    first, for :meth:`OrcaAgent._arguments`' checked floats; ``edges``, ``links``, ``bbox``,
    ``grid``, ``cells``: an :class:`_EdgeCache`'s tables (empty for no static obstacles),
    ``moving``: (k, 5) rows.

    RVO2's obstacle part: the edges within ``tau_obst * max_speed + radius`` (m), nearest
    first, seen from their free side only (back-face culling), skipped when earlier lines
    forbid both their cut-off discs already; an anchor overlapping a vertex or the edge gets a
    line through the origin that forbids going deeper (none at a non-convex vertex, or one the
    next edge handles); otherwise the velocity obstacle's legs (one vertex's legs when the edge
    is seen obliquely, the cut-off line's extension at a non-convex vertex, a neighbouring
    edge's direction for a "foreign" leg pointing into it) and the projection of the velocity
    on its boundary: a cut-off circle, the cut-off line or a leg (a foreign leg adds no line).
    Then the moving discs (:func:`_moving_compiled`)."""
    near = _near_compiled(edges, bbox, grid, cells, px, py, tau_obst * max_speed + radius)
    lines = np.empty((len(near) + moving.shape[0], 4))
    n = 0
    inv_tau = 1.0 / tau_obst
    rad2 = radius * radius
    rad_tau = radius * inv_tau
    for first in near:
        second = links[first, 0]
        x1, y1 = edges[first, 0] - px, edges[first, 1] - py
        x2, y2 = edges[second, 0] - px, edges[second, 1] - py
        ex, ey = x2 - x1, y2 - y1
        if x1 * ey - y1 * ex >= 0.0:           # back-face culling: the anchor must lie right
            continue
        # RVO2's "already covered": earlier lines forbid both cut-off discs entirely
        c1x, c1y, c2x, c2y = x1 * inv_tau, y1 * inv_tau, x2 * inv_tau, y2 * inv_tau
        covered = False
        for k in range(n):
            lx, ly, ldx, ldy = lines[k, 0], lines[k, 1], lines[k, 2], lines[k, 3]
            if ((c1x - lx) * ldy - (c1y - ly) * ldx - rad_tau >= -_EPS
                    and (c2x - lx) * ldy - (c2y - ly) * ldx - rad_tau >= -_EPS):
                covered = True
                break
        if covered:
            continue
        dist2_1 = x1 * x1 + y1 * y1
        dist2_2 = x2 * x2 + y2 * y2
        s = -(x1 * ex + y1 * ey) / (ex * ex + ey * ey)
        fx, fy = -x1 - s * ex, -y1 - s * ey
        dist2_line = fx * fx + fy * fy
        # the anchor already overlaps the edge: forbid moving deeper
        if s < 0.0 and dist2_1 <= rad2:
            if links[first, 2]:
                norm = math.sqrt(dist2_1)
                n = _push(lines, n, 0.0, 0.0, -y1 / norm, x1 / norm)
            continue
        if s >= 1.0 and dist2_2 <= rad2:
            if links[second, 2] and x2 * edges[second, 8] - y2 * edges[second, 7] >= 0.0:
                norm = math.sqrt(dist2_2)
                n = _push(lines, n, 0.0, 0.0, -y2 / norm, x2 / norm)
            continue
        if 0.0 <= s < 1.0 and dist2_line <= rad2:
            n = _push(lines, n, 0.0, 0.0, -edges[first, 7], -edges[first, 8])
            continue
        # no collision: the legs ("obliquely": one vertex's two tangents), then the projection
        if s < 0.0 and dist2_line <= rad2:
            if not links[first, 2]:
                continue
            left = right = first
            llx, lly = _leg(x1, y1, dist2_1, radius, rad2, True)
            rlx, rly = _leg(x1, y1, dist2_1, radius, rad2, False)
        elif s > 1.0 and dist2_line <= rad2:
            if not links[second, 2]:
                continue
            left = right = second
            llx, lly = _leg(x2, y2, dist2_2, radius, rad2, True)
            rlx, rly = _leg(x2, y2, dist2_2, radius, rad2, False)
        else:
            left, right = first, second
            if links[first, 2]:
                llx, lly = _leg(x1, y1, dist2_1, radius, rad2, True)
            else:
                llx, lly = -edges[first, 7], -edges[first, 8]
            if links[second, 2]:
                rlx, rly = _leg(x2, y2, dist2_2, radius, rad2, False)
            else:
                rlx, rly = edges[first, 7], edges[first, 8]
        # a leg at a convex vertex may not point into the neighbouring edge ("foreign")
        left_foreign = right_foreign = False
        before = links[left, 1]
        if links[left, 2] and llx * -edges[before, 8] - lly * -edges[before, 7] >= 0.0:
            llx, lly = -edges[before, 7], -edges[before, 8]
            left_foreign = True
        if links[right, 2] and rlx * edges[right, 8] - rly * edges[right, 7] <= 0.0:
            rlx, rly = edges[right, 7], edges[right, 8]
            right_foreign = True
        # project the velocity on the velocity obstacle's boundary: the cut-off centres are
        # the vertices over tau (m/s), with radius rad_tau
        lcx, lcy = (edges[left, 0] - px) * inv_tau, (edges[left, 1] - py) * inv_tau
        rcx, rcy = (edges[right, 0] - px) * inv_tau, (edges[right, 1] - py) * inv_tau
        cx, cy = rcx - lcx, rcy - lcy
        single = left == right
        wlx, wly = vx - lcx, vy - lcy
        t = 0.5 if single else (wlx * cx + wly * cy) / (cx * cx + cy * cy)
        t_left = wlx * llx + wly * lly
        wrx, wry = vx - rcx, vy - rcy
        t_right = wrx * rlx + wry * rly
        if (t < 0.0 and t_left < 0.0) or (single and t_left < 0.0 and t_right < 0.0):
            n = _on_circle_compiled(lines, n, wlx, wly, lcx, lcy, rad_tau)
            continue
        if t > 1.0 and t_right < 0.0:
            n = _on_circle_compiled(lines, n, wrx, wry, rcx, rcy, rad_tau)
            continue
        if t < 0.0 or t > 1.0 or single:
            d2_cut = math.inf
        else:
            qx, qy = wlx - t * cx, wly - t * cy
            d2_cut = qx * qx + qy * qy
        if t_left < 0.0:
            d2_left = math.inf
        else:
            qx, qy = wlx - t_left * llx, wly - t_left * lly
            d2_left = qx * qx + qy * qy
        if t_right < 0.0:
            d2_right = math.inf
        else:
            qx, qy = wrx - t_right * rlx, wry - t_right * rly
            d2_right = qx * qx + qy * qy
        if d2_cut <= d2_left and d2_cut <= d2_right:
            dx, dy = -edges[left, 7], -edges[left, 8]
            n = _push(lines, n, lcx - rad_tau * dy, lcy + rad_tau * dx, dx, dy)
        elif d2_left <= d2_right:
            if not left_foreign:
                n = _push(lines, n, lcx - rad_tau * lly, lcy + rad_tau * llx, llx, lly)
        elif not right_foreign:
            dx, dy = -rlx, -rly
            n = _push(lines, n, rcx - rad_tau * dy, rcy + rad_tau * dx, dx, dy)
    n_static = n
    if moving.shape[0]:
        n = _moving_compiled(lines, n, moving, px, py, vx, vy, radius, tau, step, share)
    return lines[:n], n_static


@njit
def _moving_compiled(lines: np.ndarray, n: int, moving: np.ndarray, px: float, py: float,
                     vx: float, vy: float, radius: float, tau: float, step: float,
                     share: float) -> int:
    """Append RVO2's agent lines for the moving discs ``moving`` (k, 5) [x, y, vx, vy,
    radius], nearest first (ties in row order): the relative velocity projected on the cut-off
    circle or on a leg of the velocity obstacle of horizon ``tau`` (s); a disc already
    overlapping: on the cut-off circle of time ``step`` (a velocity that separates them within
    one step; a relative velocity exactly at the centre pushes straight away). The anchor takes
    ``share`` of the avoidance. Returns the line count."""
    inv_tau = 1.0 / tau
    k = moving.shape[0]
    dist2s = np.empty(k)
    for i in range(k):
        rx, ry = moving[i, 0] - px, moving[i, 1] - py
        dist2s[i] = rx * rx + ry * ry
    for i in _stable_order(dist2s):
        ox, oy, ovx, ovy, orad = moving[i, 0], moving[i, 1], moving[i, 2], moving[i, 3], \
            moving[i, 4]
        rx, ry = ox - px, oy - py
        dist2 = dist2s[i]
        wvx, wvy, rad = vx - ovx, vy - ovy, radius + orad
        rad2 = rad * rad
        if dist2 > rad2:
            wx, wy = wvx - rx * inv_tau, wvy - ry * inv_tau
            w2 = wx * wx + wy * wy
            dot = wx * rx + wy * ry
            if dot < 0.0 and dot * dot > rad2 * w2:
                w_len = math.sqrt(w2)
                ux, uy = wx / w_len, wy / w_len
                dx, dy = uy, -ux
                grow = rad * inv_tau - w_len
                ux, uy = grow * ux, grow * uy
            else:
                leg = math.sqrt(dist2 - rad2)
                if rx * wy - ry * wx > 0.0:
                    dx, dy = (rx * leg - ry * rad) / dist2, (rx * rad + ry * leg) / dist2
                else:
                    dx, dy = -(rx * leg + ry * rad) / dist2, (rx * rad - ry * leg) / dist2
                along = wvx * dx + wvy * dy
                ux, uy = along * dx - wvx, along * dy - wvy
        else:
            inv_step = 1.0 / step
            wx, wy = wvx - rx * inv_step, wvy - ry * inv_step
            ux, uy, w_len = _unit_or_away(wx, wy, rx, ry)
            dx, dy = uy, -ux
            grow = rad * inv_step - w_len
            ux, uy = grow * ux, grow * uy
        n = _push(lines, n, vx + share * ux, vy + share * uy, dx, dy)
    return n


@njit
def _lines_and_velocity(edges: np.ndarray, links: np.ndarray, bbox: np.ndarray,
                        grid: np.ndarray, cells: np.ndarray, px: float, py: float, vx: float,
                        vy: float, radius: float, max_speed: float, tau_obst: float,
                        moving: np.ndarray, tau: float, step: float, share: float, ox: float,
                        oy: float) -> tuple[np.ndarray, int, float, float]:
    """(lines, n_static, v*x, v*y): :func:`_compiled_lines`, then :func:`_solve` for the
    preferred velocity (ox, oy) (m/s) in them (:meth:`OrcaAgent.velocity`)."""
    lines, n_static = _compiled_lines(edges, links, bbox, grid, cells, px, py, vx, vy, radius,
                                      max_speed, tau_obst, moving, tau, step, share)
    x, y = _solve(lines, n_static, ox, oy, max_speed)
    return lines, n_static, x, y
