"""The map generator: random obstacles at an exact density with connected, passable free space.

:func:`generate_map` draws rotated rectangles, convex polygons, L-shapes and walls until the
obstacle union reaches the requested density, rejecting every shape that would enclose a pocket
of free space or close a passage narrower than the clearance. The algorithm and its guarantees
are described in ``docs/maps.md``.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Callable

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from aoass_env.maps.obstacle_map import MapError, ObstacleMap, _check_rng, _field_dims
from aoass_env.validators import real

#: Highest obstacle density :func:`generate_map` accepts.
MAX_DENSITY = 0.6
#: :func:`generate_map` returns maps whose density is within this of the request.
DENSITY_TOL = 5e-4
#: Generated maps have their vertices snapped to this grid (m) unless snapping would break a
#: guarantee (then the exact union is kept); map files stay short.
GRID = 1e-3

# Shape sizes of the generator: sqrt(shape area) is log-uniform in this range, as a fraction of
# the field's shorter side (3 to 12 m on a 100 m field).
_SIZE_RANGE = (0.03, 0.12)
# A candidate must add at least this fraction of its own area (else it is mostly hidden).
_MIN_GAIN = 0.25
# Candidate budget: this many times the number of average-sized shapes the target area needs
# (8 to 25 times suffice at density 0.6). Every _WINDOW candidates the generator gives up when
# the progress of the last window, kept up, would not reach the target within the budget.
_CANDIDATE_BUDGET = 60
_WINDOW = 500
# Slack of the room's lower bound per accepted shape, as a fraction of the field area (_Room).
_ROOM_SLACK = 1e-6
# Whole-map draws before giving up when a finished draw fails the final verification.
_MAX_DRAWS = 5


def _box(aspect: float) -> np.ndarray:
    a = math.sqrt(aspect)
    return np.array([[-a, -1 / a], [a, -1 / a], [a, 1 / a], [-a, 1 / a]])


def _rectangle(rng: np.random.Generator) -> np.ndarray:
    return _box(rng.uniform(1.0, 3.0))


def _wall(rng: np.random.Generator) -> np.ndarray:
    return _box(rng.uniform(6.0, 15.0))


def _convex(rng: np.random.Generator) -> np.ndarray:
    k = int(rng.integers(5, 9))
    angle = rng.uniform(0.0, 2 * math.pi, k)
    radius = rng.uniform(0.6, 1.0, k)
    pts = shapely.multipoints(np.column_stack([radius * np.cos(angle), radius * np.sin(angle)]))
    return shapely.get_coordinates(shapely.convex_hull(pts))[:-1]


def _l_shape(rng: np.random.Generator) -> np.ndarray:
    a, b = rng.uniform(2.0, 4.0, 2)
    return np.array([[0, 0], [a, 0], [a, 1], [1, 1], [1, b], [0, b]], dtype=np.float64)


_SHAPES: tuple[tuple[float, Callable[[np.random.Generator], np.ndarray]], ...] = (
    (0.35, _rectangle), (0.30, _convex), (0.15, _l_shape), (0.20, _wall))
_SHAPE_P = np.array([w for w, _ in _SHAPES])
# rng.choice(len(_SHAPES), p=_SHAPE_P) is this cumulative table searched with one rng.random()
# draw: the same shape from the same stream, without choice's per-call checks
_SHAPE_CDF = _SHAPE_P.cumsum()
_SHAPE_CDF /= _SHAPE_CDF[-1]


def _unit_shape(rng: np.random.Generator) -> np.ndarray:
    """Random obstacle outline of area 1 m^2, centroid at the origin, random orientation."""
    v = _SHAPES[int(_SHAPE_CDF.searchsorted(rng.random(), side="right"))][1](rng)
    poly = shapely.polygons(v)
    v = (v - shapely.get_coordinates(shapely.centroid(poly))) / math.sqrt(shapely.area(poly))
    t = rng.uniform(0.0, math.pi)
    c, s = math.cos(t), math.sin(t)
    return v @ np.array([[c, s], [-s, c]])


def _connected(adjacency: np.ndarray) -> bool:
    """Is the small undirected graph given by a dense boolean adjacency matrix connected?

    (A few nodes only: a breadth-first sweep costs microseconds, where scipy's csgraph spends
    most of its time validating the input.)
    """
    reached = adjacency[0].copy()
    reached[0] = True
    while True:
        grown = reached | adjacency[reached].any(axis=0)
        if np.array_equal(grown, reached):
            return bool(reached.all())
        reached = grown


class _BlockedSet:
    """A frame (a ring around the free region) plus accepted shapes, grouped into touching
    components with union-find.

    Adding a simply connected shape (every candidate is one) splits the free region exactly
    when the shape meets some component in two or more separate pieces (Mayer-Vietoris: each
    extra piece closes a loop around free space). So a test only intersects the new shape with
    the members whose bounding boxes it overlaps -- no map-wide geometry; a shape that meets
    nothing is accepted after the bounding-box filter. Touching (a shared boundary point)
    counts as meeting, since it already cuts the open free space.
    """

    def __init__(self, frame: BaseGeometry) -> None:
        # members and their bounds (x0, y0, x1, y1 rows), in arrays grown by doubling: the
        # first ``_size`` columns are in use
        self._geoms = np.empty(64, dtype=object)
        self._bounds = np.empty((4, 64))
        self._size = 0
        self._parent: list[int] = []
        self.add(frame, np.empty(0, dtype=np.intp))

    def _root(self, i: int) -> int:
        while self._parent[i] != i:
            self._parent[i] = self._parent[self._parent[i]]
            i = self._parent[i]
        return i

    def contacts(self, shape: BaseGeometry) -> tuple[np.ndarray, np.ndarray]:
        """Indices of the members ``shape`` meets and the (non-empty) intersections."""
        x0, y0, x1, y1 = shapely.bounds(shape)
        b = self._bounds[:, :self._size]
        near = np.flatnonzero((b[0] <= x1) & (b[2] >= x0) & (b[1] <= y1) & (b[3] >= y0))
        geoms = self._geoms[near]
        # the exact predicate first: overlays only of the members the shape really meets
        meets = shapely.intersects(geoms, shape)
        near, geoms = near[meets], geoms[meets]
        pieces = shapely.intersection(geoms, shape)
        met = ~shapely.is_empty(pieces)
        return near[met], pieces[met]

    def encloses(self, members: np.ndarray, pieces: np.ndarray) -> bool:
        """Would a shape meeting ``members`` in ``pieces`` enclose a new free region?"""
        parts, owner = shapely.get_parts(pieces, return_index=True)
        if len(parts) < 2:
            return False         # one piece cannot close a loop
        groups: dict[int, list[int]] = {}  # the parts of each component met
        for k, j in enumerate(owner.tolist()):
            groups.setdefault(self._root(int(members[j])), []).append(k)
        for group in groups.values():
            if len(group) > 1:
                grouped = parts[group]
                if not _connected(shapely.intersects(grouped[:, None], grouped[None, :])):
                    return True
        return False

    def add(self, shape: BaseGeometry, members: np.ndarray) -> None:
        """Make ``shape``, which meets ``members``, a member."""
        new = self._size
        if new == len(self._geoms):
            self._geoms = np.concatenate([self._geoms, np.empty(new, dtype=object)])
            self._bounds = np.concatenate([self._bounds, np.empty((4, new))], axis=1)
        self._geoms[new] = shape
        self._bounds[:, new] = shapely.bounds(shape)
        self._size = new + 1
        self._parent.append(new)
        for i in members:
            self._parent[self._root(int(i))] = new


def _room_left(room: float, grown_area: float, pieces: np.ndarray) -> float:
    """The eroded free area (m^2) left after adding a grown shape of area ``grown_area`` (m^2)
    that meets the eroded set in ``pieces``, from ``room`` (m^2) before it."""
    return room - grown_area + (shapely.union_all(pieces).area if len(pieces) else 0.0)


class _Room:
    """The area (m^2) of the eroded free region, :func:`_room_left` chained over the accepted
    shapes, summed only when a test needs it.

    Its one use is the test ``room_left >= minimum``. Each term lowers the room by at most
    the grown shape's area less its largest piece's (the union of the pieces covers each
    piece), so a lower bound decides the test while it stays clear of ``minimum``; ``slack``
    (m^2, orders of magnitude above the rounding of these areas and sums) keeps the bound
    below the exact sums. Only when the bound cannot decide are the pending terms summed, in
    order, as the eager sum would be: the same room, the same answers, without a union per
    candidate.
    """

    def __init__(self, room: float, minimum: float, slack: float) -> None:
        self._exact = room
        self._pending: list[tuple[float, np.ndarray]] = []  # terms of accepted shapes not summed
        self._floor = room     # lower bound of the room with the pending terms
        self._minimum = minimum
        self._slack = slack

    def fits(self, grown_area: float, pieces: np.ndarray) -> bool:
        """Is ``_room_left(room, grown_area, pieces) >= minimum``?"""
        if self._floor - grown_area - self._slack >= self._minimum:
            return True
        for term in self._pending:
            self._exact = _room_left(self._exact, *term)
        self._pending.clear()
        self._floor = self._exact
        return _room_left(self._exact, grown_area, pieces) >= self._minimum

    def take(self, grown_area: float, pieces: np.ndarray) -> None:
        """Add an accepted shape's term."""
        self._pending.append((grown_area, pieces))
        largest = shapely.area(pieces).max() if len(pieces) else 0.0
        self._floor -= grown_area - largest + self._slack


def _draw_obstacles(width: float, height: float, density: float, rng: np.random.Generator,
                    clearance: float) -> list[BaseGeometry]:
    """Accepted candidate shapes (inside the field) whose union has the requested density.

    Two blocked sets watch the topology: ``raw`` holds the shapes and the field border (no
    pocket of free space may be enclosed); ``eroded`` holds the shapes grown by clearance/2 and
    the border moved in by clearance/2, so its free region is where the anchor's centre fits
    (no passage narrower than ``clearance`` may cut it). A shape farther than ``clearance``
    from every obstacle and from the border meets nothing in either set.
    """
    field_box = shapely.box(0.0, 0.0, width, height)
    half = clearance / 2
    pad = clearance + 1.0
    outer = shapely.box(-pad, -pad, width + pad, height + pad)
    raw = _BlockedSet(shapely.difference(outer, field_box))
    eroded_box = shapely.box(half, half, width - half, height - half)
    eroded = _BlockedSet(shapely.difference(outer, eroded_box))
    # area of the eroded free region (m^2); kept >= clearance^2
    room = _Room(eroded_box.area, clearance**2, _ROOM_SLACK * width * height)
    target = density * width * height
    tol = DENSITY_TOL * width * height
    lo, hi = (f * min(width, height) for f in _SIZE_RANGE)
    mean_area = (hi**2 - lo**2) / (2 * math.log(hi / lo))  # E[side^2], side log-uniform
    budget = math.ceil(_CANDIDATE_BUDGET * target / mean_area)
    covered = 0.0
    accepted: list[BaseGeometry] = []
    drawn = 0
    checkpoint = covered
    while target - covered > tol:
        if drawn and drawn % _WINDOW == 0:  # the last window's pace must finish in the budget
            if (covered - checkpoint) * (budget - drawn) / _WINDOW < target - covered:
                raise MapError(
                    f"cannot reach density={density} on a {width:g} x {height:g} m field with "
                    f"clearance={clearance:g} m: stuck at {covered / (width * height):.4f} after "
                    f"{drawn} candidate shapes; lower the density or the clearance")
            checkpoint = covered
        drawn += 1
        side = math.exp(rng.uniform(math.log(lo), math.log(hi)))
        shape_area = min(side * side, target - covered)  # never overshoot the target
        # the centre as rng.uniform((0, 0), (width, height)) draws it: x, then y, each
        # 0 + side * next double (the scalar calls skip the broadcasting machinery)
        x, y = rng.uniform(0.0, width), rng.uniform(0.0, height)
        outline = _unit_shape(rng) * math.sqrt(shape_area)
        outline[:, 0] += x
        outline[:, 1] += y
        shape = shapely.intersection(shapely.polygons(outline), field_box)
        if shape.geom_type != "Polygon" or shape.is_empty:
            continue  # an L-shape cut in two by the border
        members, pieces = raw.contacts(shape)
        gain = shape.area - (shapely.union_all(pieces).area if len(pieces) else 0.0)
        if not _MIN_GAIN * shape.area <= gain <= target - covered:
            continue  # mostly hidden by existing obstacles (or a rounding-error overshoot)
        if raw.encloses(members, pieces):
            continue
        grown = shapely.buffer(shape, half)
        grown_members, grown_pieces = eroded.contacts(grown)
        grown_area = grown.area
        if (not room.fits(grown_area, grown_pieces)
                or eroded.encloses(grown_members, grown_pieces)):
            continue  # no room left for the anchor, or a pocket cut off
        covered += gain
        room.take(grown_area, grown_pieces)
        raw.add(shape, members)
        eroded.add(grown, grown_members)
        accepted.append(shape)
    return accepted


def generate_map(field_size: float | tuple[float, float], density: float,
                 rng: np.random.Generator, *, clearance: float = 2.5,
                 name: str = "") -> ObstacleMap:
    """A random obstacle map with obstacle density ``density`` (fraction of the field area).

    Obstacles are rotated rectangles, convex polygons, L-shapes and walls; overlapping shapes
    merge into concave obstacles. The result satisfies ``check_traversable(clearance)`` and
    ``abs(density - requested) <= DENSITY_TOL``; vertices lie on a ``GRID`` (m) lattice where
    snapping keeps these guarantees.

    Args:
        field_size: side (m) of a square field, or (width, height).
        density: obstacle area / field area, in [0, MAX_DENSITY].
        rng: the only source of randomness; the same seed gives the same map.
        clearance: narrowest passage (m) kept open for the anchor, > 0.
        name: label of the map.
    """
    width, height = _field_dims(field_size)
    density = real("density", density, low=0.0, high=MAX_DENSITY,
                   doc="obstacle area / field area", error=MapError)
    clearance = real("clearance", clearance, "m", low=0.0, high=min(width, height) / 2,
                     low_open=True, high_open=True, doc=f"for a {width:g} x {height:g} m field",
                     error=MapError)
    _check_rng(rng)
    if density == 0.0:
        return ObstacleMap(width, height, (), name)
    key = _state_key(rng)
    if key is not None:
        key = (width, height, density, clearance, name, key)
        found = _GENERATED.get(key)
        if found is not None:        # the same draw: its map, and the generator after it
            _GENERATED.move_to_end(key)
            rng.bit_generator.state = found[1]
            return found[0]
    obstacle_map = _generate(width, height, density, rng, clearance, name)
    if key is not None:
        _GENERATED[key] = (obstacle_map, rng.bit_generator.state)
        while len(_GENERATED) > _GENERATED_MAX:
            _GENERATED.popitem(last=False)
    return obstacle_map


#: Maps generated lately: (field, density, clearance, name, generator state before) -> (map,
#: generator state after), newest last. A generator in the same state draws the same map (the
#: generator is its only source of randomness), so a reset with the same seed reuses it and
#: leaves the generator where the draw would have; maps are immutable and may be shared. Few
#: are kept: each keeps its detour planner's grid alive (about 5 MB at 100 m, 20 MB at 200 m).
_GENERATED: OrderedDict[tuple, tuple[ObstacleMap, dict]] = OrderedDict()
_GENERATED_MAX = 4


def clear_cache() -> None:
    """Forget the maps :func:`generate_map` keeps, so the next call with any generator state
    draws its map anew (a benchmark timing fresh resets, or memory back after large fields)."""
    _GENERATED.clear()


def _state_key(rng: np.random.Generator) -> tuple | None:
    """A hashable copy of the generator's whole state, or None when it has an unknown shape
    (no caching then)."""
    def freeze(value: object) -> object:
        if isinstance(value, dict):
            return tuple((k, freeze(v)) for k, v in sorted(value.items()))
        if isinstance(value, np.ndarray):
            return (value.dtype.str, value.shape, value.tobytes())
        if isinstance(value, (int, float, str, bool, type(None))):
            return value
        raise TypeError(type(value).__name__)
    try:
        return freeze(rng.bit_generator.state)
    except TypeError:
        return None


def _generate(width: float, height: float, density: float, rng: np.random.Generator,
              clearance: float, name: str) -> ObstacleMap:
    """:func:`generate_map` after its checks: draw maps until one verifies."""
    failures: list[str] = []
    for _ in range(_MAX_DRAWS):
        exact = shapely.union_all(_draw_obstacles(width, height, density, rng, clearance))
        for union in (shapely.set_precision(exact, GRID), exact):
            try:
                return _verified_map(union, width, height, density, clearance, name)
            except MapError as err:
                failures.append(str(err))
    raise MapError(f"generate_map(density={density}, clearance={clearance}) failed to verify "
                   f"{_MAX_DRAWS} draws: {'; '.join(failures)}")


def _verified_map(union: BaseGeometry, width: float, height: float, density: float,
                  clearance: float, name: str) -> ObstacleMap:
    """The map whose obstacles are the parts of ``union``; MapError unless it keeps the
    promises of :func:`generate_map`."""
    parts = shapely.get_parts(union)
    if any(p.interiors for p in parts):
        raise MapError("an obstacle encloses a hole")
    obstacle_map = ObstacleMap(
        width, height, tuple(shapely.get_coordinates(p.exterior)[:-1] for p in parts), name)
    obstacle_map.check_traversable(clearance)
    if abs(obstacle_map.density - density) > DENSITY_TOL:
        raise MapError(f"density {obstacle_map.density:.5f} misses {density} by more than "
                       f"{DENSITY_TOL}")
    return obstacle_map
