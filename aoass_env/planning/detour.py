"""Detours around static obstacles: shortest paths on a clearance-weighted occupancy grid.

The nominal follower steers straight at the next spiral waypoint. When an obstacle stands in the
way, :class:`DetourPlanner` finds a collision-free path for a disc of the anchor's radius: the
field is rasterised, scipy's Euclidean distance transform gives each cell its clearance, cells
with too little clearance are removed (and those whose centre lies, exactly, within the radius
of an obstacle: a wall or a spike thinner than a cell holds no cell centre), and Dijkstra
(scipy.sparse.csgraph) on the 8-connected grid, with a cost that prefers open space, finds the
path. The path is then shortened by string pulling (keep only the points needed for straight,
obstacle-free legs). A start or goal off the free cells snaps to the nearest free cell it
reaches straight without crossing an obstacle.

**Same paths from smaller searches.** Dijkstra's distances do not depend on how far it searches
or how its heap breaks ties: in floats, a cell's distance is the least left-to-right sum over the
grid paths to it (adding a weight is monotone and never decreases a sum), and a search bounded
by a limit finds every cell whose distance is within it. Its predecessor of a cell is the first
scanned neighbour through which that distance is reached. When exactly one neighbour reaches it,
for every cell of the path, every search that reaches the goal traces the same path, whatever
its heap does with ties. A search therefore first runs a compiled search that stops at the goal
(:func:`~aoass_env.planning.goal_search.forced_path`); when its path is forced at every cell it
is the answer, and only for a tie on the path does the planner run a scipy search: the bounded
one (cost up to :data:`SEARCH_FACTOR` x the straight distance + :data:`SEARCH_SLACK`) when the
goal lies within it, else the whole grid's, as it always did, whose heap settles the tie.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable

import numpy as np
import shapely
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from aoass_env.jit import njit
from aoass_env.maps import MapError, ObstacleMap
from aoass_env.planning.goal_search import FORCED, UNREACHABLE, forced_path
from aoass_env.segments import CLEAR, CROSSES, EdgeGrid
from aoass_env.validators import positive, real, vec2

#: A detour search first explores paths of cost up to SEARCH_FACTOR x the straight distance +
#: SEARCH_SLACK (m; cost = length x (1 + 1/clearance), at most about twice the length), and
#: searches the whole grid only when the goal lies beyond.
SEARCH_FACTOR = 4.0
SEARCH_SLACK = 40.0
#: Cost factor of grid moves inside a keep-out (:meth:`DetourPlanner.path`).
KEEPOUT_COST = 25.0
#: Extra clearance (m) the nominal follower's detours keep from obstacles beyond the anchor
#: radius, room for the turn-rate-limited anchor to round the corners of a detour.
DETOUR_MARGIN = 0.3
#: How far (m) a start must lead out, through cells of exact clearance, to count as open
#: (:meth:`DetourPlanner.leads_out`).
LEAD_OUT = 10.0
#: Most snaps of points off the free cells a map's planners remember (:meth:`DetourPlanner.
#: _cell`); the memory is emptied when full, so a long training run on one map stays bounded.
SNAPS_KEPT = 4096


class DetourPlanner:
    """Collision-free paths for a disc among the static obstacles of a map.

    Args:
        obstacle_map: the field and obstacles.
        radius: disc radius to keep clear of obstacles and border (m).
        resolution: grid cell size (m).
    """

    def __init__(self, obstacle_map: ObstacleMap, radius: float, resolution: float = 0.5):
        radius, resolution = (positive(name, value, "m") for name, value in
                              (("radius", radius), ("resolution", resolution)))
        self.radius, self.res = float(radius), float(resolution)
        nx = max(1, math.ceil(obstacle_map.width / resolution))
        ny = max(1, math.ceil(obstacle_map.height / resolution))
        self.shape = (nx, ny)
        self._size = (float(obstacle_map.width), float(obstacle_map.height))
        self._leads: dict[tuple[float, float, float], bool] = {}   # shared by copies
        self._snaps: dict[tuple[float, float], int] = {}     # _cell's searches, shared too
        xs, ys = (np.arange(nx) + 0.5) * resolution, (np.arange(ny) + 0.5) * resolution
        gx, gy = np.meshgrid(xs, ys, indexing="ij")
        self.centres = np.stack([gx.ravel(), gy.ravel()], axis=1)
        occupied = obstacle_map.inside_obstacle(self.centres).reshape(nx, ny)
        padded = np.pad(~occupied, 1, constant_values=False)   # the border is an obstacle
        clearance = ndimage.distance_transform_edt(padded)[1:-1, 1:-1] * resolution
        clearance = np.minimum(clearance, np.minimum(np.minimum(gx, obstacle_map.width - gx),
                                                     np.minimum(gy, obstacle_map.height - gy)))
        self._obstacles = obstacle_map.union if obstacle_map.polygons else shapely.Polygon()
        shapely.prepare(self._obstacles)       # the map's own union: prepared once for all
        self._blocker = shapely.buffer(self._obstacles, radius)
        shapely.prepare(self._blocker)
        # a cell is free when its centre is clear of the grid's occupied centres by radius plus
        # half a cell and, exactly, of the obstacles grown by the radius: an obstacle part
        # thinner than a cell (a wall, a union's spike) holds no cell centre, and the grid
        # alone would plan through it
        self.free = clearance > radius + 0.5 * resolution
        fx, fy = self.centres[self.free.ravel()].T
        self.free[self.free] = ~shapely.intersects_xy(self._blocker, fx, fy)
        if not self.free.any():
            raise MapError(f"no cell of the {resolution:g} m grid leaves a disc of radius "
                           f"{radius:g} m clear of the obstacles and the border: nowhere to plan")
        # nearest free cell of every cell, to snap starts and goals onto the grid
        _, nearest = ndimage.distance_transform_edt(~self.free, return_indices=True)
        self._nearest = np.ravel_multi_index((nearest[0], nearest[1]), self.shape).ravel()
        cost = 1.0 + 1.0 / np.maximum(clearance, 1e-3)
        self._graph = self._build_graph(cost)
        # the compiled search's A* slope: every edge weighs its length x the mean cost of its
        # two cells, so at least its length x the least cost of a free cell; 0.1 % below it
        self._slope = 0.999 * float(cost[self.free].min(initial=1.0))
        # the largest 8-connected region of free cells: where most of the field can be reached
        labels, count = ndimage.label(self.free, structure=np.ones((3, 3), dtype=bool))
        sizes = np.bincount(labels.ravel(), minlength=count + 1)[1:]
        self._main = (labels == 1 + int(np.argmax(sizes))).ravel() if count else self.free.ravel()
        self._blocker_edges = EdgeGrid(_ring_edges(self._blocker))
        self._last_inside = (math.nan, math.nan, False)   # (x, y, answer) of _inside
        # (start cell, limit) of the kept shortest-path tree, and its (dist, pred) arrays once a
        # search has needed them (a forced quick path needs no tree)
        self._tree: tuple[int, float] | None = None
        self._arrays: tuple[np.ndarray, np.ndarray] | None = None
        self._nearest_main: np.ndarray | None = None     # built on first use (main_point)
        # entry (j, i) of every entry (i, j) of the graph, for keep-out searches: built on first
        # use, shared by copies (for_map)
        self._reverse: dict[str, np.ndarray] = {}

    @classmethod
    def for_map(cls, obstacle_map: ObstacleMap, radius: float,
                resolution: float = 0.5) -> DetourPlanner:
        """A planner for ``obstacle_map`` with a fresh search state; the grid, its graph and the
        buffered obstacles are built once per map (maps are immutable) and shared by the
        planners of every episode on it (a reset on a named map, or a generated map drawn
        again from the same seed, does not rebuild them)."""
        template = obstacle_map.derived(
            ("detour planner", cls, float(radius), float(resolution)),
            lambda: cls(obstacle_map, radius, resolution))
        planner = copy.copy(template)
        planner._tree = planner._arrays = None
        return planner

    def _build_graph(self, cost: np.ndarray) -> csr_matrix:
        """8-connected graph of the free cells with both directions of every edge (so Dijkstra
        needs no symmetrising per search), edge weight = length x mean cost
        (:func:`_grid_graph`)."""
        nx, ny = self.shape
        indptr, indices, data = _grid_graph(self.free, cost, math.hypot(1, 0) * self.res,
                                            math.hypot(1, 1) * self.res)
        return csr_matrix((data, indices, indptr), shape=(nx * ny, nx * ny))

    def _index(self, point: np.ndarray) -> int:
        """Flat index of the grid cell holding ``point`` (clipped to the field)."""
        i = min(max(int(point[0] / self.res), 0), self.shape[0] - 1)
        j = min(max(int(point[1] / self.res), 0), self.shape[1] - 1)
        return i * self.shape[1] + j

    def _cell(self, point: np.ndarray) -> int:
        """The free cell ``point`` (m) snaps to: its own when free, else the nearest free cell
        whose centre it reaches straight without crossing an obstacle (the nearest alone may
        lie behind a wall thinner than the planner's radius: an anchor in a corridor narrower
        than the planner's disc planned its first leg through the wall); the nearest free cell
        when no free cell is reached so."""
        index = self._index(point)
        cell = int(self._nearest[index])
        if cell == index or self._reaches(point, cell):
            return cell
        key = (float(point[0]), float(point[1]))
        if key not in self._snaps:            # the map is immutable: once per point
            if len(self._snaps) >= SNAPS_KEPT:   # an anchor's positions never repeat for long
                self._snaps.clear()
            self._snaps[key] = self._reached_cell(point, index, cell)
        return self._snaps[key]

    def _reaches(self, point: np.ndarray, cell: int) -> bool:
        """Whether the segment from ``point`` (m) to the centre of ``cell`` meets no obstacle."""
        return self._obstacles.is_empty or not shapely.intersects(
            self._obstacles, shapely.linestrings([point, self.centres[cell]]))

    def _reached_cell(self, point: np.ndarray, index: int, nearest: int) -> int:
        """The nearest free cell (ties: the lower flat index) whose centre ``point`` (m, in cell
        ``index``) reaches (:meth:`_reaches`), searched in squares of cells around ``index``
        that double until one holds it within the radius the square surely covers; ``nearest``
        when none does."""
        nx, ny = self.shape
        i, j = divmod(index, ny)
        free = self.free.ravel()
        k = 4
        while True:
            rows = np.arange(max(0, i - k), min(nx, i + k + 1))
            cols = np.arange(max(0, j - k), min(ny, j + k + 1))
            block = (rows[:, None] * ny + cols[None, :]).ravel()
            block = block[free[block]]
            dist = np.hypot(*(self.centres[block] - point).T)
            whole = len(rows) == nx and len(cols) == ny
            sure = math.inf if whole else k * self.res      # every cell nearer is in the square
            inside = np.flatnonzero(dist <= sure)
            if len(inside):
                legs = np.empty((len(inside), 2, 2))
                legs[:, 0], legs[:, 1] = point, self.centres[block[inside]]
                reached = inside[~shapely.intersects(self._obstacles, shapely.linestrings(legs))]
                if len(reached):          # the nearest; ties: the first, the lower flat index
                    return int(block[reached[np.argmin(dist[reached])]])
            if whole:
                return nearest
            k *= 2

    def costs(self, start: np.ndarray, goals: np.ndarray) -> np.ndarray:
        """(K,) cost of the planner's way (m, weighted as its searches: length x (1 + 1 /
        clearance), so at least the length) from ``start`` to each of ``goals`` (K, 2), each
        snapped to its nearest free grid cell as :meth:`path` does; inf where there is no way.
        One search for all the goals."""
        vec2("start", start, "m")
        goals = np.asarray(goals, dtype=np.float64).reshape(-1, 2)
        if not np.isfinite(goals).all():     # a NaN goal would read another cell's cost
            raise ValueError("goals must be finite (m)")
        dist, _ = self._tree_from(self._cell(start), math.inf)
        i = np.clip((goals[:, 0] / self.res).astype(np.int64), 0, self.shape[0] - 1)
        j = np.clip((goals[:, 1] / self.res).astype(np.int64), 0, self.shape[1] - 1)
        return dist[self._nearest[i * self.shape[1] + j]]

    def main_cells(self, step: int = 1) -> np.ndarray:
        """(M, 2) the centres (m) of the free grid cells in the largest connected region, where
        the anchor can stand and most of the field is reached; with ``step`` > 1 only every
        step-th cell along each axis (a thinned lattice)."""
        i, j = np.unravel_index(np.flatnonzero(self._main), self.shape)
        keep = (i % step == 0) & (j % step == 0)
        return self.centres[(i * self.shape[1] + j)[keep]]

    def main_point(self, point: np.ndarray) -> np.ndarray:
        """(2,) the centre (m) of the free grid cell nearest to ``point`` in the largest
        connected free region (where :meth:`can_start` holds): where an anchor the planner
        sees shut in a pocket heads to rejoin the field."""
        if self._nearest_main is None:
            main = self._main.reshape(self.shape)
            _, near = ndimage.distance_transform_edt(~main, return_indices=True)
            self._nearest_main = np.ravel_multi_index((near[0], near[1]), self.shape).ravel()
        return self.centres[self._nearest_main[self._index(point)]].copy()

    def can_start(self, point: np.ndarray, clearance: float) -> bool:
        """Whether the field is reachable from ``point`` (m): the free cell the planner snaps it
        to lies in the largest connected free region, and a disc of radius ``clearance`` (m)
        can move straight from ``point`` to that cell. False for a point shut in a pocket, or
        wedged where the first leg of every detour would cut an obstacle's corner."""
        cell = self._cell(point)
        if not self._main[cell]:
            return False
        leg = shapely.LineString([point, self.centres[cell]])
        return bool(self._obstacles.is_empty
                    or shapely.distance(self._obstacles, leg) >= clearance)

    def leads_out(self, point: np.ndarray, reach: float = LEAD_OUT) -> bool:
        """Whether a disc of the planner's radius gets farther than ``reach`` (m) from ``point``
        through grid cells whose *exact* clearance (distance to the obstacles and the border)
        is at least that radius, from the cell ``point`` snaps to (8-connected). The grid's own
        clearance is a distance transform to occupied cell centres, which misses obstacle
        parts thinner than a cell: a point in a nook can look open to the grid while its exit
        is narrower than the radius (a start the anchor inside the safety stack never left)."""
        point = np.asarray(point, dtype=np.float64)
        key = (float(point[0]), float(point[1]), float(reach))
        if key not in self._leads:            # the map is immutable: once per point
            self._leads[key] = self._leads_out(point, reach)
        return self._leads[key]

    def _leads_out(self, point: np.ndarray, reach: float) -> bool:
        """:meth:`leads_out` by a depth-first search from the start cell over the cells of
        the window ``reach`` around it, farthest neighbour first, that measures the exact
        clearance of a cell only when the search reaches it (a few cells on the way out in
        the open, a pocket's cells in a pocket): the same answer as labelling every cell of
        the window, with each cell's clearance the same floats."""
        nx, ny = self.shape
        k = math.ceil(reach / self.res) + 1
        si, sj = divmod(self._cell(point), ny)
        i_lo, i_hi = max(0, si - k), min(nx, si + k + 1)
        j_lo, j_hi = max(0, sj - k), min(ny, sj + k + 1)
        px, py = float(point[0]), float(point[1])
        res, far = self.res, reach * reach
        seen = {(si, sj)}
        stack = [(si, sj)]                    # the anchor stands on the start cell already
        while stack:
            i, j = stack.pop()
            dx, dy = (i + 0.5) * res - px, (j + 0.5) * res - py
            if dx * dx + dy * dy > far:
                return True
            cells = [(a, b) for a in (i - 1, i, i + 1) for b in (j - 1, j, j + 1)
                     if i_lo <= a < i_hi and j_lo <= b < j_hi and (a, b) not in seen]
            if not cells:
                continue
            seen.update(cells)
            cells.sort(key=lambda c: ((c[0] + 0.5) * res - px) ** 2
                       + ((c[1] + 0.5) * res - py) ** 2)
            stack.extend(c for c, ok in zip(cells, self._clear(cells), strict=True) if ok)
        return False

    def _clear(self, cells: list[tuple[int, int]]) -> np.ndarray:
        """Whether each grid cell's centre is at least the planner's radius from the field's
        border and, by exact distance, from every obstacle."""
        gi, gj = np.array(cells, dtype=np.int64).T
        cx, cy = (gi + 0.5) * self.res, (gj + 0.5) * self.res
        width, height = self._size
        clear = np.minimum(np.minimum(cx, width - cx), np.minimum(cy, height - cy))
        ok = clear >= self.radius
        if ok.any() and not self._obstacles.is_empty:
            ok[ok] = shapely.distance(self._obstacles, shapely.points(cx[ok], cy[ok])) \
                >= self.radius
        return ok

    def visible(self, a: np.ndarray, b: np.ndarray) -> bool:
        """True when a disc of the planner's radius can move straight from ``a`` to ``b``: the
        segment does not meet the obstacles grown by the radius (shapely's ``intersects``).
        The exact segment test against the grown obstacles' edges
        (:class:`~aoass_env.segments.EdgeGrid`) settles most segments: a crossing meets them,
        and a segment clear of every edge meets them when ``a`` does; contacts go to
        shapely."""
        (ax, ay), (bx, by) = vec2("a", a, "m"), vec2("b", b, "m")   # NaN read as visible
        status = self._blocker_edges.status(ax, ay, bx, by)
        if status == CROSSES:
            return False
        if status == CLEAR or (ax == bx and ay == by):
            return not self._inside(ax, ay)
        return not shapely.intersects(self._blocker, shapely.linestrings([a, b]))

    def _inside(self, x: float, y: float) -> bool:
        """Whether the point (x, y) (m) meets the grown obstacles (shapely's
        ``intersects_xy``). The answer for the last point asked is kept: string pulling asks
        about one start point against many ends."""
        last = self._last_inside
        if last[0] == x and last[1] == y:
            return last[2]
        # shapely.intersects_xy's own ufunc, without its wrapper (the blocker is prepared)
        inside = bool(shapely.lib.intersects_xy(self._blocker, x, y))
        self._last_inside = (x, y, inside)
        return inside

    def path(self, start: np.ndarray, goal: np.ndarray, keepout: np.ndarray | None = None,
             keepout_radius: float = 0.0) -> np.ndarray | None:
        """Shortened collision-free path (K, 2) from ``start`` to ``goal`` (both included), or
        None when no path exists (the goal lies in a pocket the disc cannot enter).

        ``keepout`` (P, 2): places (m) the path keeps more than ``keepout_radius`` (m) away
        from unless going round them is much longer (where a follower got stuck). The
        shortest-path tree of the last start cell is kept for searches without
        keep-outs, so trying several goals from one place costs one search.
        """
        vec2("start", start, "m")
        vec2("goal", goal, "m")
        if keepout is not None and len(keepout):
            keepout = np.asarray(keepout, float)
            if not np.isfinite(keepout).all():
                raise ValueError("keepout must be finite (m)")
            return self._path_avoiding(start, goal, keepout,
                                       real("keepout_radius", keepout_radius, "m", low=0.0))
        s, g = self._cell(start), self._cell(goal)
        straight = math.hypot(goal[0] - start[0], goal[1] - start[1])
        limit = SEARCH_FACTOR * straight + SEARCH_SLACK
        kept = self._tree is not None and self._tree[0] == s and self._tree[1] >= limit
        if not (kept and self._arrays is not None):
            status, cells, cost = self._forced_path(s, g)
            # the tree the searches below would keep, built when a tie needs it: the bounded
            # search's (the kept one's) if it reaches g, else the whole grid's
            if cost > (self._tree[1] if kept else limit):
                self._tree, self._arrays = (s, math.inf), None
            elif not kept:
                self._tree, self._arrays = (s, limit), None
            if status == FORCED:
                return self._pull(self._trace(start, goal, cells))
            if status == UNREACHABLE:
                return None
        dist, pred = self._tree_from(s, limit)
        if not np.isfinite(dist[g]):
            dist, pred = self._tree_from(s, math.inf)
        if not np.isfinite(dist[g]):
            return None
        return self._pull(self._trace(start, goal, self._cells(s, g, pred)))

    def _forced_path(self, s: int, g: int, near: np.ndarray | None = None,
                     factor: float = 1.0) -> tuple[int, list[int], float]:
        """(status, cells, cost) of :func:`~aoass_env.planning.goal_search.forced_path` on
        the grid graph (reweighted by ``factor`` at the ``near`` cells); ``cells`` (``g``
        first) when the status is FORCED."""
        graph = self._graph
        status, cells, cost = forced_path(graph.indptr, graph.indices, graph.data, s, g,
                                          xy=self.centres, slope=self._slope, near=near,
                                          factor=factor)
        return status, cells.tolist(), cost

    @staticmethod
    def _cells(s: int, g: int, pred: np.ndarray) -> list[int]:
        """The cells of the path from cell ``s`` to cell ``g`` of a shortest-path tree
        (predecessors ``pred``), ``g`` first."""
        cells = [g]
        while cells[-1] != s:
            cells.append(int(pred[cells[-1]]))
        return cells

    def _trace(self, start: np.ndarray, goal: np.ndarray, cells: list[int]) -> np.ndarray:
        """The grid path of ``cells`` (goal's cell first) with the exact start and goal at its
        ends."""
        return np.vstack([start, self.centres[cells[::-1]], goal])

    def _path_avoiding(self, start: np.ndarray, goal: np.ndarray, keepout: np.ndarray,
                       radius: float) -> np.ndarray | None:
        """:meth:`path` on the grid whose cells within ``radius`` (m) of ``keepout`` cost
        :data:`KEEPOUT_COST` times more (a path crosses a keep-out only when going round it is
        much longer); legs of the shortened path keep clear of the keep-outs where the grid
        path does."""
        near = self._near(keepout, radius)
        s, g = self._cell(start), self._cell(goal)
        # the compiled search first; on a tie, scipy's bounded search if it reaches g, else the
        # whole grid's, as in path()
        status, cells, cost = self._forced_path(s, g, near, math.sqrt(KEEPOUT_COST))
        if status == UNREACHABLE:
            return None
        if status != FORCED:
            straight = math.hypot(goal[0] - start[0], goal[1] - start[1])
            limit = SEARCH_FACTOR * straight + SEARCH_SLACK
            graph = self._reweighted(near, math.sqrt(KEEPOUT_COST))
            dist, pred = dijkstra(graph, indices=s, return_predecessors=True,
                                  limit=limit if cost <= limit else math.inf)
            if not np.isfinite(dist[g]):
                dist, pred = dijkstra(graph, indices=s, return_predecessors=True)
            if not np.isfinite(dist[g]):
                return None
            cells = self._cells(s, g, pred)
        pts = self._trace(start, goal, cells)
        zones = shapely.buffer(shapely.multipoints(keepout), radius)
        return self._pull(pts, lambda a, b: self.visible(a, b) and not shapely.intersects(
            zones, shapely.LineString([a, b])))

    def _near(self, points: np.ndarray, radius: float) -> np.ndarray:
        """(cells,) mask of the cells whose centre lies within ``radius`` (m) of a point of
        ``points`` (P, 2): ``hypot(centre - point) <= radius``, evaluated on the block of cells
        around each point only (every cell outside it is farther than ``radius``)."""
        nx, ny = self.shape
        res = self.res
        near = np.zeros(len(self.centres), dtype=bool)
        for p in points:
            x, y = float(p[0]), float(p[1])
            i0 = min(max(math.floor((x - radius) / res - 0.5) - 1, 0), nx)
            i1 = min(max(math.ceil((x + radius) / res - 0.5) + 2, 0), nx)
            j0 = min(max(math.floor((y - radius) / res - 0.5) - 1, 0), ny)
            j1 = min(max(math.ceil((y + radius) / res - 0.5) + 2, 0), ny)
            if i0 >= i1 or j0 >= j1:
                continue
            block = (np.arange(i0, i1)[:, None] * ny + np.arange(j0, j1)[None, :]).ravel()
            near[block] |= np.hypot(*(self.centres[block] - p).T) <= radius
        return near

    def _reweighted(self, cells: np.ndarray, factor: float) -> csr_matrix:
        """The grid graph with every edge weight multiplied by ``factor`` once for each end in
        the mask ``cells``: the entries of ``F @ graph @ F`` for the diagonal F of ``factor``
        on ``cells`` (1 elsewhere), the same floats ((f_i w) f_j) in the same order, without
        two sparse products. Only the entries of the masked cells' rows are touched, and of
        their columns, which are those rows' entries reversed (the graph holds both
        directions of every edge)."""
        graph = self._graph
        reverse = self._reverse.get("entries")
        if reverse is None:
            reverse = self._reverse["entries"] = _reverse_entries(graph)
        own = _row_entries(graph.indptr, np.flatnonzero(cells))
        data = graph.data.copy()
        data[own] *= factor
        data[reverse[own]] *= factor
        return csr_matrix((data, graph.indices, graph.indptr), shape=graph.shape)

    def _tree_from(self, s: int, limit: float) -> tuple[np.ndarray, np.ndarray]:
        """Shortest-path distances and predecessors from cell ``s``, searched up to path cost
        ``limit`` (cells beyond it are unreached: inf). Within the limit Dijkstra settles cells
        in the same order as an unlimited search, so the paths it finds are the same; the tree
        of the last start is kept and reused while its limit suffices."""
        if self._tree is None or self._tree[0] != s or self._tree[1] < limit:
            self._tree, self._arrays = (s, limit), None
        if self._arrays is None:
            self._arrays = dijkstra(self._graph, indices=s, return_predecessors=True,
                                    limit=self._tree[1])
        return self._arrays

    def _pull(self, pts: np.ndarray,
              clear: Callable[[np.ndarray, np.ndarray], bool] | None = None) -> np.ndarray:
        """String pulling: from each kept point, jump to the last point still ``clear``
        (default: :meth:`visible`)."""
        clear = clear or self.visible
        out, i = [pts[0]], 0
        while i < len(pts) - 1:
            j = i + 1
            while j + 1 < len(pts) and clear(pts[i], pts[j + 1]):
                j += 1
            out.append(pts[j])
            i = j
        return np.array(out)


@njit
def _grid_graph(free: np.ndarray, cost: np.ndarray, straight: float,
                diagonal: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(indptr, indices, data) of the CSR graph of the (nx, ny) grid's ``free`` cells (flat
    index i ny + j): an entry (u, v) for every pair of 8-neighbours both free, each row's
    columns in increasing order, weighing ``step * 0.5 * (cost[u] + cost[v])`` with ``step``
    the ``straight`` or ``diagonal`` move (m) -- the canonical CSR form scipy's ``tocsr`` gives
    the same entries, the same floats."""
    nx, ny = free.shape
    indptr = np.zeros(nx * ny + 1, dtype=np.int32)
    indices = np.empty(8 * nx * ny, dtype=np.int32)
    data = np.empty(8 * nx * ny)
    k = 0
    for i in range(nx):
        for j in range(ny):
            if free[i, j]:
                for di in range(-1, 2):          # neighbours in increasing flat index
                    for dj in range(-1, 2):
                        ni, nj = i + di, j + dj
                        if ((di or dj) and 0 <= ni < nx and 0 <= nj < ny and free[ni, nj]):
                            step = diagonal if di and dj else straight
                            indices[k] = ni * ny + nj
                            data[k] = step * 0.5 * (cost[i, j] + cost[ni, nj])
                            k += 1
            indptr[i * ny + j + 1] = k
    return indptr, indices[:k].copy(), data[:k].copy()


def _row_entries(indptr: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Indices of the entries of the CSR rows ``rows`` (given by ``indptr``), row by row."""
    starts = indptr[rows]
    counts = indptr[rows + 1] - starts
    offsets = np.cumsum(counts) - counts       # where each row's entries begin in the answer
    return np.repeat(starts - offsets, counts) + np.arange(counts.sum())


def _reverse_entries(graph: csr_matrix) -> np.ndarray:
    """(nnz,) for each entry (i, j) of ``graph``, the index of its entry (j, i); ValueError
    when some entry has none (the structure is not symmetric)."""
    n = graph.shape[0]
    rows = np.repeat(np.arange(n, dtype=np.int64), np.diff(graph.indptr))
    cols = graph.indices.astype(np.int64)
    key = rows * n + cols
    order = np.argsort(key, kind="stable")
    where = np.searchsorted(key[order], cols * n + rows).clip(max=max(len(key) - 1, 0))
    reverse = order[where]
    if len(key) and not np.array_equal(key[reverse], cols * n + rows):
        raise ValueError("the grid graph must hold both directions of every edge")
    return reverse


def _ring_edges(area: shapely.Geometry) -> np.ndarray:
    """(E, 2, 2) the edges (m) of every ring, outer and inner, of the polygons of ``area``."""
    parts = shapely.get_parts(area)
    rings = shapely.get_rings(parts[~shapely.is_empty(parts)]) if len(parts) else parts
    coords, ring = shapely.get_coordinates(rings, return_index=True)
    same = ring[:-1] == ring[1:]
    return np.stack([coords[:-1], coords[1:]], axis=1)[same] if len(coords) \
        else np.zeros((0, 2, 2))
