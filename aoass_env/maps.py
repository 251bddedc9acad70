"""Obstacle maps: the field, its static obstacle polygons, a generator and the map text format.

An :class:`ObstacleMap` is a rectangular field ``[0, width] x [0, height]`` (m) with simple
polygons (possibly concave, no holes) as static obstacles. Polygons are stored counter-clockwise
without a repeated closing vertex, as RVO2 and pymunk expect.

Maps come from :func:`generate_map` (random obstacles at an exact density, free space kept
connected and passable) or from files in the IMR-CIIRC planning-map text format
(:func:`read_map`, :func:`write_map`, :func:`load_map` for the maps shipped in ``maps/``).
The algorithm and the guarantees are described in ``docs/maps.md``.
"""

from __future__ import annotations

import difflib
import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from numbers import Integral, Real
from pathlib import Path

import numpy as np
import shapely
from pymunk import autogeometry
from shapely.geometry.base import BaseGeometry
from shapely.geometry.polygon import orient

from aoass_env.atomic import write_text_atomic

#: Folder of the shipped maps (``train/`` and ``test/``), at the top of the repository.
MAPS_DIR = Path(__file__).resolve().parents[1] / "maps"
#: Splits of the shipped maps.
SPLITS = ("train", "test")
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
# Whole-map draws before giving up when a finished draw fails the final verification.
_MAX_DRAWS = 5


class MapError(ValueError):
    """A map cannot be used: bad geometry, disconnected free space or too little room."""


class MapFormatError(MapError):
    """A map file is malformed; ``path`` and the 1-based ``line`` say where."""

    def __init__(self, path: Path, line: int, message: str) -> None:
        super().__init__(f"{path}:{line}: {message}")
        self.path = path
        self.line = line
        self.message = message

    def __reduce__(self) -> tuple:  # picklable across processes despite the custom __init__
        return type(self), (self.path, self.line, self.message)


def _as_ccw(vertices: np.ndarray) -> np.ndarray:
    """(k, 2) float64 vertices in counter-clockwise order, closing duplicate removed."""
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 2)
    if len(v) > 1 and np.array_equal(v[0], v[-1]):
        v = v[:-1]
    x, y = v[:, 0], v[:, 1]
    signed_area = 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
    return v[::-1].copy() if signed_area < 0 else v.copy()


def _real(name: str, value: object) -> float:
    """``value`` as a finite float, or a MapError naming the parameter."""
    if isinstance(value, bool) or not isinstance(value, Real) or not math.isfinite(value):
        raise MapError(f"{name}={value!r} must be a finite number")
    return float(value)


def _field_dims(field_size: float | tuple[float, float]) -> tuple[float, float]:
    """(width, height) in m from a side length or a (width, height) pair."""
    sizes = tuple(field_size) if np.ndim(field_size) > 0 else (field_size, field_size)
    if len(sizes) != 2:
        raise MapError(f"field_size={field_size!r} must be a number or a (width, height) pair")
    w, h = (_real("field_size", s) for s in sizes)
    if w <= 0 or h <= 0:
        raise MapError(f"field_size={field_size!r} must be positive (m)")
    return w, h


@dataclass(frozen=True, eq=False)
class ObstacleMap:
    """A field of ``width`` x ``height`` metres with static obstacle polygons.

    Args:
        width, height: field size (m).
        polygons: obstacle polygons, each an array-like of (x, y) vertices (m); stored as
            counter-clockwise (k, 2) float64 arrays without a closing vertex.
        name: a label (the file stem for maps read from disk).
    """

    width: float
    height: float
    polygons: tuple[np.ndarray, ...] = field(default=())
    name: str = ""

    def __post_init__(self) -> None:
        for label, value in (("width", self.width), ("height", self.height)):
            if not np.isfinite(value) or value <= 0:
                raise MapError(f"map {label}={value!r} must be a positive number of metres")
        polys = []
        for i, p in enumerate(self.polygons):
            v = _as_ccw(p)
            if len(v) < 3 or not np.all(np.isfinite(v)):
                raise MapError(f"obstacle {i}: a polygon needs >= 3 finite vertices, got {p!r}")
            poly = shapely.Polygon(v)
            if not poly.is_valid or poly.area <= 0:
                reason = shapely.is_valid_reason(poly)
                raise MapError(f"obstacle {i} is not a simple polygon with area ({reason})")
            polys.append(v)
        object.__setattr__(self, "width", float(self.width))
        object.__setattr__(self, "height", float(self.height))
        object.__setattr__(self, "polygons", tuple(polys))

    # --- shapely views (cached; the map is immutable) -------------------------------------
    @cached_property
    def field_polygon(self) -> shapely.Polygon:
        return shapely.box(0.0, 0.0, self.width, self.height)

    @cached_property
    def shapes(self) -> np.ndarray:
        """The obstacles as an array of shapely Polygons."""
        return np.array([shapely.Polygon(p) for p in self.polygons], dtype=object)

    @cached_property
    def union(self) -> BaseGeometry:
        """Union of all obstacles clipped to the field (prepared for fast point queries)."""
        if not self.polygons:
            return shapely.Polygon()
        geom = shapely.intersection(shapely.union_all(self.shapes), self.field_polygon)
        shapely.prepare(geom)
        return geom

    @cached_property
    def free_space(self) -> BaseGeometry:
        """The field minus the obstacles."""
        return shapely.difference(self.field_polygon, self.union)

    @cached_property
    def free_space_loops(self) -> tuple[np.ndarray, ...]:
        """The boundary of free space as closed (k, 2) vertex loops (m) with free space to the
        right of every directed edge: outer boundaries clockwise, the obstacles inside them
        counter-clockwise (RVO2's obstacle convention; used by ORCA)."""
        loops: list[np.ndarray] = []
        for poly in shapely.get_parts(self.free_space):
            if not isinstance(poly, shapely.Polygon) or poly.is_empty:
                continue
            poly = orient(poly, sign=-1.0)
            loops.extend(np.asarray(ring.coords)[:-1]
                         for ring in (poly.exterior, *poly.interiors))
        return tuple(loops)

    @property
    def area(self) -> float:
        """Field area (m^2)."""
        return self.width * self.height

    @cached_property
    def density(self) -> float:
        """Exact obstacle density: area of the obstacle union inside the field / field area."""
        return float(self.union.area) / self.area

    # --- geometry for the other modules ---------------------------------------------------
    @cached_property
    def edges(self) -> np.ndarray:
        """All obstacle edges as an (E, 2, 2) float64 array of (start, end) points (m)."""
        if not self.polygons:
            return np.zeros((0, 2, 2))
        return np.concatenate([np.stack([p, np.roll(p, -1, axis=0)], axis=1)
                               for p in self.polygons])

    @cached_property
    def convex_parts(self) -> tuple[np.ndarray, ...]:
        """Exact convex decomposition of every obstacle (for pymunk), CCW (k, 2) arrays."""
        parts: list[np.ndarray] = []
        for p in self.polygons:
            if shapely.Polygon(p).equals(shapely.convex_hull(shapely.Polygon(p))):
                parts.append(p)
                continue
            closed = [tuple(v) for v in p] + [tuple(p[0])]
            for piece in autogeometry.convex_decomposition(closed, 0.0):
                parts.append(_as_ccw(np.array([(q.x, q.y) for q in piece])))
        return tuple(parts)

    def inside_obstacle(self, points: np.ndarray, dilation: float = 0.0) -> np.ndarray:
        """Boolean mask of points (M, 2) lying in an obstacle dilated by ``dilation`` (m).

        With ``dilation > 0`` a point counts when its exact distance to an obstacle is at most
        ``dilation``; with 0, when it lies strictly inside an obstacle.
        """
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if not self.polygons:
            return np.zeros(len(pts), dtype=bool)
        if dilation > 0:
            return shapely.dwithin(self.union, shapely.points(pts), dilation)
        return shapely.contains_xy(self.union, pts[:, 0], pts[:, 1])

    def bounds_contain(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Mask of points (M, 2) inside the field shrunk by ``margin`` (m)."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        return ((pts[:, 0] >= margin) & (pts[:, 0] <= self.width - margin)
                & (pts[:, 1] >= margin) & (pts[:, 1] <= self.height - margin))

    # --- room checks ----------------------------------------------------------------------
    def check_traversable(self, clearance: float) -> None:
        """Raise MapError unless an anchor of diameter ``clearance`` (m) can reach all free space.

        Passes when the free space (field minus obstacles) is one connected polygon (no pockets
        enclosed by obstacles) and, for ``clearance > 0``, stays one polygon after erosion by
        ``clearance / 2``: every passage between obstacles, or between an obstacle and the
        border, is at least ``clearance`` wide (up to shapely's buffer approximation, < 0.5 %).
        """
        clearance = _real("clearance", clearance)
        if clearance < 0:
            raise MapError(f"clearance={clearance!r} must be >= 0 m")
        label = f"map {self.name!r}" if self.name else "map"
        free = self.free_space
        if free.is_empty:
            raise MapError(f"{label} has no free space: obstacles cover the whole field")
        if free.geom_type != "Polygon":
            raise MapError(f"{label}: obstacles enclose part of the free space; "
                           f"{_regions_text(free)}")
        if clearance == 0:
            return
        eroded = shapely.buffer(free, -clearance / 2)
        if eroded.is_empty:
            raise MapError(f"{label}: no point of the free space is {clearance / 2:g} m from "
                           f"obstacles and border; an anchor needing clearance={clearance:g} m "
                           f"cannot move")
        if eroded.geom_type != "Polygon":
            raise MapError(f"{label}: passages narrower than clearance={clearance:g} m cut the "
                           f"free space; {_regions_text(eroded)}")

    def sample_free_points(self, n: int, rng: np.random.Generator,
                           clearance: float = 0.0) -> np.ndarray:
        """``n`` points (n, 2) uniform in the free space, at least ``clearance`` (m) from every
        obstacle and from the border (rejection sampling in vectorised batches)."""
        if isinstance(n, bool) or not isinstance(n, Integral) or n < 0:
            raise MapError(f"n={n!r} must be a non-negative integer")
        _check_rng(rng)
        clearance = _real("clearance", clearance)
        if clearance < 0:
            raise MapError(f"clearance={clearance!r} must be >= 0 m")
        label = f"map {self.name!r}" if self.name else "map"
        lo = np.array([clearance, clearance])
        hi = np.array([self.width - clearance, self.height - clearance])
        if np.any(hi <= lo):
            raise MapError(f"clearance={clearance:g} m leaves no room inside the "
                           f"{self.width:g} x {self.height:g} m field of {label}")
        chunks = [np.empty((0, 2))]
        found = drawn = 0
        rate = max(self.free_space.area / self.area, 1e-3)
        while found < n:
            batch = int(min(max(1.25 * (n - found) / rate, 256), 200_000))
            pts = rng.uniform(lo, hi, size=(batch, 2))
            keep = pts[~self.inside_obstacle(pts, clearance)]
            chunks.append(keep)
            found += len(keep)
            drawn += batch
            rate = max(found, 1) / drawn
            if drawn >= 100_000 and rate < 1e-4:
                raise MapError(
                    f"cannot place {n} points in {label}: only {found} of {drawn} uniform "
                    f"samples lie in free space at least {clearance:g} m from obstacles and "
                    f"the border (free area too small)")
        return np.concatenate(chunks)[:n]


def _regions_text(geom: BaseGeometry) -> str:
    """'N separate regions; cut-off ones e.g. around (x, y), ...' for a multi-part geometry."""
    parts = sorted(shapely.get_parts(geom), key=lambda g: -g.area)
    spots = ", ".join(f"({p.x:.1f}, {p.y:.1f})"
                      for p in shapely.point_on_surface(np.array(parts[1:4], dtype=object)))
    return (f"{len(parts)} separate regions; cut-off ones e.g. around {spots} m "
            f"(largest region {parts[0].area:.1f} m^2)")


def _check_rng(rng: object) -> None:
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator (np.random.default_rng(seed)), "
                        f"got {type(rng).__name__}")


# =========================================================================================
# Generator
# =========================================================================================
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


def _unit_shape(rng: np.random.Generator) -> np.ndarray:
    """Random obstacle outline of area 1 m^2, centroid at the origin, random orientation."""
    v = _SHAPES[int(rng.choice(len(_SHAPES), p=_SHAPE_P))][1](rng)
    poly = shapely.Polygon(v)
    v = (v - shapely.get_coordinates(poly.centroid)) / math.sqrt(poly.area)
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
        self._geoms: list[BaseGeometry] = [frame]
        self._bounds = np.array([frame.bounds])
        self._parent = [0]

    def _root(self, i: int) -> int:
        while self._parent[i] != i:
            self._parent[i] = self._parent[self._parent[i]]
            i = self._parent[i]
        return i

    def contacts(self, shape: BaseGeometry) -> tuple[np.ndarray, np.ndarray]:
        """Indices of the members ``shape`` meets and the (non-empty) intersections."""
        x0, y0, x1, y1 = shape.bounds
        b = self._bounds
        near = np.flatnonzero((b[:, 0] <= x1) & (b[:, 2] >= x0) & (b[:, 1] <= y1)
                              & (b[:, 3] >= y0))
        geoms = np.empty(len(near), dtype=object)
        geoms[:] = [self._geoms[i] for i in near]
        pieces = shapely.intersection(geoms, shape)
        met = ~shapely.is_empty(pieces)
        return near[met], pieces[met]

    def encloses(self, members: np.ndarray, pieces: np.ndarray) -> bool:
        """Would a shape meeting ``members`` in ``pieces`` enclose a new free region?"""
        parts, owner = shapely.get_parts(pieces, return_index=True)
        roots = np.array([self._root(int(members[j])) for j in owner])
        for root in np.unique(roots):
            group = parts[roots == root]
            if len(group) > 1:
                if not _connected(shapely.intersects(group[:, None], group[None, :])):
                    return True
        return False

    def add(self, shape: BaseGeometry, members: np.ndarray) -> None:
        new = len(self._geoms)
        self._geoms.append(shape)
        self._bounds = np.vstack([self._bounds, shape.bounds])
        self._parent.append(new)
        for i in members:
            self._parent[self._root(int(i))] = new


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
    room = eroded_box.area  # area of the eroded free region (m^2); kept >= clearance^2
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
        centre = rng.uniform((0.0, 0.0), (width, height))
        outline = _unit_shape(rng) * math.sqrt(shape_area) + centre
        shape = shapely.intersection(shapely.Polygon(outline), field_box)
        if shape.geom_type != "Polygon" or shape.is_empty:
            continue  # an L-shape cut in two by the border
        members, pieces = raw.contacts(shape)
        gain = shape.area - shapely.union_all(pieces).area
        if not _MIN_GAIN * shape.area <= gain <= target - covered:
            continue  # mostly hidden by existing obstacles (or a rounding-error overshoot)
        if raw.encloses(members, pieces):
            continue
        grown = shapely.buffer(shape, half)
        grown_members, grown_pieces = eroded.contacts(grown)
        room_left = room - grown.area + shapely.union_all(grown_pieces).area
        if room_left < clearance**2 or eroded.encloses(grown_members, grown_pieces):
            continue  # no room left for the anchor, or a pocket cut off
        covered += gain
        room = room_left
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
    density = _real("density", density)
    if not 0.0 <= density <= MAX_DENSITY:
        raise MapError(f"density={density!r} must be in [0, {MAX_DENSITY}]")
    clearance = _real("clearance", clearance)
    if not 0.0 < clearance < min(width, height) / 2:
        raise MapError(f"clearance={clearance!r} must be in (0, {min(width, height) / 2:g}) m "
                       f"for a {width:g} x {height:g} m field")
    _check_rng(rng)
    if density == 0.0:
        return ObstacleMap(width, height, (), name)
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


# =========================================================================================
# IMR-CIIRC text format
# =========================================================================================
_SECTIONS = ("[SCALE]", "[BORDER]", "[OBSTACLE]")


_Rows = list[tuple[int, list[float]]]  # (line number, values) of one section


def _parse_sections(path: Path, lines: list[str]) -> list[tuple[str, int, _Rows]]:
    """[(section, header line number, rows), ...] of a map file, in file order."""
    sections: list[tuple[str, int, _Rows]] = []
    for number, raw in enumerate(lines, start=1):
        text = raw.strip()
        if not text:
            continue
        if text.startswith("["):
            if text not in _SECTIONS:
                raise MapFormatError(path, number, f"unknown section {text!r}; valid sections "
                                                   f"are {', '.join(_SECTIONS)}")
            if text != "[OBSTACLE]" and any(s[0] == text for s in sections):
                raise MapFormatError(path, number, f"second {text} section")
            sections.append((text, number, []))
            continue
        if not sections:
            raise MapFormatError(path, number, f"{text!r} before the first section "
                                               f"(the file must start with [SCALE])")
        kind, _, rows = sections[-1]
        values = []
        for token in text.split():
            try:
                value = float(token)
            except ValueError:
                raise MapFormatError(path, number, f"{token!r} is not a number") from None
            if not math.isfinite(value):
                raise MapFormatError(path, number, f"{token!r} is not a finite number")
            values.append(value)
        want = 1 if kind == "[SCALE]" else 2
        if len(values) != want:
            what = "one number" if want == 1 else "two numbers 'x y'"
            raise MapFormatError(path, number, f"expected {what} in {kind}, got {len(values)}")
        if kind == "[SCALE]" and rows:
            raise MapFormatError(path, number, "[SCALE] holds a single number")
        rows.append((number, values))
    return sections


def _polygon(path: Path, kind: str, line: int, rows: _Rows, scale: float) -> np.ndarray:
    """Validated (k, 2) vertices (m) of a [BORDER] or [OBSTACLE] section."""
    if len(rows) < 3:
        raise MapFormatError(path, line, f"{kind} has {len(rows)} vertices; a polygon needs >= 3")
    v = np.array([values for _, values in rows]) * scale
    poly = shapely.Polygon(v)
    if not poly.is_valid:
        raise MapFormatError(path, line, f"{kind} is not a simple polygon "
                                         f"({shapely.is_valid_reason(poly)})")
    if poly.area <= 0:
        raise MapFormatError(path, line, f"{kind} has zero area")
    return v


def read_map(path: str | os.PathLike, field_size: float | tuple[float, float] | None = None
             ) -> ObstacleMap:
    """Read an IMR-CIIRC map file (``[SCALE]``, ``[BORDER]``, ``[OBSTACLE]`` sections).

    Coordinates are scaled to metres (value x scale) and the border's bounding box is moved to
    the origin; it becomes the field. With ``field_size`` (m, side or (width, height)) the map
    is stretched per axis to that size. Parts of the bounding box outside a non-rectangular
    border become obstacles; obstacles are clipped to the field. Malformed files raise
    :class:`MapFormatError` naming the file and line.
    """
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except UnicodeDecodeError as err:
        raise MapError(f"{path}: not a UTF-8 text map file ({err.reason})") from None
    sections = _parse_sections(path, lines)
    end = max(len(lines), 1)
    found = {kind: (line, rows) for kind, line, rows in sections if kind != "[OBSTACLE]"}
    for kind in ("[SCALE]", "[BORDER]"):
        if kind not in found:
            raise MapFormatError(path, end, f"missing {kind} section")
    header_line, scale_rows = found["[SCALE]"]
    if not scale_rows:
        raise MapFormatError(path, header_line, "[SCALE] has no value")
    value_line, (scale,) = scale_rows[0]
    if scale <= 0:
        raise MapFormatError(path, value_line, f"scale {scale!r} must be positive")
    border = _polygon(path, "[BORDER]", *found["[BORDER]"], scale)
    obstacles = [_polygon(path, kind, line, rows, scale)
                 for kind, line, rows in sections if kind == "[OBSTACLE]"]

    low = border.min(axis=0)
    span = border.max(axis=0) - low
    if field_size is None:
        size = span
        border, obstacles = border - low, [v - low for v in obstacles]
    else:  # (v - low) / span is exactly 0 and 1 on the border's bounding box
        size = np.array(_field_dims(field_size))
        border = (border - low) / span * size
        obstacles = [(v - low) / span * size for v in obstacles]

    width, height = float(size[0]), float(size[1])
    field_box = shapely.box(0.0, 0.0, width, height)
    polygons = []
    for v in obstacles:
        if np.all(v >= 0) and np.all(v <= size):
            polygons.append(v)
            continue
        clipped = shapely.intersection(shapely.Polygon(v), field_box)
        polygons += [shapely.get_coordinates(p.exterior)[:-1]
                     for p in shapely.get_parts(clipped) if p.area > 0]
    outside = shapely.difference(field_box, shapely.Polygon(border))
    polygons += [shapely.get_coordinates(p.exterior)[:-1]
                 for p in shapely.get_parts(outside) if p.area > 0]
    return ObstacleMap(width, height, tuple(polygons), path.stem)


def write_map(obstacle_map: ObstacleMap, path: str | os.PathLike) -> None:
    """Write ``obstacle_map`` as an IMR-CIIRC text file (SCALE 1, metres), atomically.

    Floats are written exactly (``repr``), so ``read_map`` gives back the same polygons.
    """
    w, h = obstacle_map.width, obstacle_map.height
    out = ["[SCALE]", "1", "", "[BORDER]", "0 0", f"{w!r} 0", f"{w!r} {h!r}", f"0 {h!r}"]
    for p in obstacle_map.polygons:
        out += ["", "[OBSTACLE]"]
        out += [f"{float(x)!r} {float(y)!r}" for x, y in p]
    write_text_atomic(Path(path), "\n".join(out) + "\n")


def list_maps(split: str, *, field_size: float | None = None,
              densities: tuple[float, float] | None = None) -> list[str]:
    """Names (``"<split>/<stem>"``) of the shipped maps of ``split`` ("train" or "test").

    Shipped stems read ``d<density>_f<field size>_s<seed>``; ``field_size`` (m) keeps the maps
    of that field size, ``densities`` = (low, high) those whose density lies in [low, high]."""
    if split not in SPLITS:
        raise MapError(f"split={split!r} must be one of {SPLITS}")
    folder = MAPS_DIR / split
    if not folder.is_dir():
        raise MapError(f"shipped map folder {folder} is missing (it comes with the repository)")
    names = []
    for p in sorted(folder.glob("*.txt")):
        if field_size is not None or densities is not None:
            parts = dict((f[0], f[1:]) for f in p.stem.split("_") if f)
            if field_size is not None and float(parts.get("f", "nan")) != field_size:
                continue
            if densities is not None and not (
                    densities[0] - 1e-9 <= float(parts.get("d", "nan")) <= densities[1] + 1e-9):
                continue
        names.append(f"{split}/{p.stem}")
    return names


def validation_split(names: list[str]) -> tuple[list[str], list[str]]:
    """(fit, validation): shipped map names split for model selection. The map with the
    highest seed of every (density, field size) group is held out for validation (1 in 5 of
    the shipped training maps), the others are for fitting; ``names`` as from
    :func:`list_maps`."""
    groups: dict[tuple[str, str], list[str]] = {}
    for name in names:
        parts = dict((f[0], f[1:]) for f in name.rsplit("/", 1)[-1].split("_") if f)
        groups.setdefault((parts.get("d", ""), parts.get("f", "")), []).append(name)
    held = {max(group, key=lambda n: int(n.rsplit("_s", 1)[-1])) for group in groups.values()
            if len(group) > 1}
    return [n for n in names if n not in held], [n for n in names if n in held]


def load_map(name_or_path: str | os.PathLike,
             field_size: float | tuple[float, float] | None = None) -> ObstacleMap:
    """A map from a file path, or a shipped map by name ("test/d0.30_f100_s500" or its stem)."""
    path = Path(name_or_path)
    if path.is_file():
        return read_map(path, field_size)
    key = str(name_or_path).removesuffix(".txt")
    names = [n for split in SPLITS if (MAPS_DIR / split).is_dir() for n in list_maps(split)]
    matches = [n for n in names if key in (n, n.split("/", 1)[1])]
    if len(matches) == 1:
        return read_map(MAPS_DIR / f"{matches[0]}.txt", field_size)
    if matches:
        raise MapError(f"map name {key!r} is ambiguous: {', '.join(matches)}")
    by_stem = {n.split("/", 1)[1]: n for n in names}
    close = difflib.get_close_matches(key.rsplit("/", 1)[-1], list(by_stem), n=3, cutoff=0.5)
    examples = [by_stem[stem] for stem in close] or names[:3]
    raise MapError(f"unknown map {str(name_or_path)!r}: no such file and no shipped map of that "
                   f"name in {MAPS_DIR}; e.g. {', '.join(examples) or '(none shipped)'} "
                   f"(see list_maps('train'), list_maps('test'))")
