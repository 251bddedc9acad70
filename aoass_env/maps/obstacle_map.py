"""The map value: a rectangular field and its static obstacle polygons.

An :class:`ObstacleMap` is a rectangular field ``[0, width] x [0, height]`` (m) with simple
polygons (possibly concave, no holes) as static obstacles. Polygons are stored counter-clockwise
without a repeated closing vertex, as RVO2 and pymunk expect. It answers the geometric queries
of the other modules (shapely views, edges, convex parts, point tests) and the room checks
(:meth:`ObstacleMap.check_traversable`, :meth:`ObstacleMap.sample_free_points`).
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, TypeVar

import numpy as np
import shapely
from pymunk import autogeometry
from shapely.geometry.base import BaseGeometry
from shapely.geometry.polygon import orient

from aoass_env.validators import integer, positive, real

_T = TypeVar("_T")


class MapError(ValueError):
    """A map cannot be used: bad geometry, disconnected free space or too little room."""


def _as_ccw(vertices: np.ndarray) -> np.ndarray:
    """(k, 2) float64 vertices in counter-clockwise order, repeated vertices removed: a vertex
    equal to the one before it, and closing copies of the first (a repeated vertex is the same
    polygon, but pymunk's convex decomposition crashed the process on one)."""
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 2)
    if len(v) > 1:
        new = np.ones(len(v), dtype=bool)
        new[1:] = np.any(v[1:] != v[:-1], axis=1)
        v = v[new]
        end = len(v)
        while end > 1 and np.array_equal(v[0], v[end - 1]):
            end -= 1
        v = v[:end]
    x, y = v[:, 0], v[:, 1]
    # np.roll(., -1) by slicing (the same arrays, without np.roll's generic axis handling)
    signed_area = 0.5 * float(np.dot(x, np.concatenate((y[1:], y[:1])))
                              - np.dot(y, np.concatenate((x[1:], x[:1]))))
    return v[::-1].copy() if signed_area < 0 else v.copy()


def _convex_decomposition(closed: list[tuple[float, float]]) -> list[list[Any]]:
    """``pymunk.autogeometry.convex_decomposition(closed, 0.0)``: the same Chipmunk call and
    the same pieces, with the polyline set Chipmunk returns freed (pymunk 7 never frees it:
    about 0.6 KB leaked per concave obstacle of every freshly generated map)."""
    line = autogeometry._to_chipmunk(closed)
    pieces = autogeometry.lib.cpPolylineConvexDecomposition(line, 0.0)
    try:
        return autogeometry._from_polyline_set(pieces)
    finally:
        autogeometry.lib.cpPolylineSetFree(pieces, True)


def _field_dims(field_size: float | tuple[float, float]) -> tuple[float, float]:
    """(width, height) in m from a side length or a (width, height) pair."""
    sizes = tuple(field_size) if np.ndim(field_size) > 0 else (field_size, field_size)
    if len(sizes) != 2:
        raise MapError(f"field_size={field_size!r} must be a number or a (width, height) pair")
    w, h = (positive("field_size", s, "m", error=MapError) for s in sizes)
    return w, h


@dataclass(frozen=True, eq=False)
class ObstacleMap:
    """A field of ``width`` x ``height`` metres with static obstacle polygons.

    Args:
        width, height: field size (m).
        polygons: obstacle polygons, each an array-like of (x, y) vertices (m); stored as
            counter-clockwise (k, 2) float64 read-only arrays without a closing or repeated
            vertex (maps are shared from caches: an edit would change every later draw).
        name: a label (the file stem for maps read from disk).
    """

    width: float
    height: float
    polygons: tuple[np.ndarray, ...] = field(default=())
    name: str = ""

    def __post_init__(self) -> None:
        width = positive("map width", self.width, "m", error=MapError)
        height = positive("map height", self.height, "m", error=MapError)
        polys = []
        for i, p in enumerate(self.polygons):
            shape = np.shape(p)
            if len(shape) != 2 or shape[1] != 2:
                raise MapError(f"obstacle {i}: a polygon must be a (k, 2) array of (x, y) "
                               f"vertices (m), got shape {shape}")
            v = _as_ccw(p)
            if len(v) < 3 or not np.all(np.isfinite(v)):
                raise MapError(f"obstacle {i}: a polygon needs >= 3 distinct finite vertices, "
                               f"got {len(v)} of its {shape[0]}"
                               + ("" if np.all(np.isfinite(v)) else ", some not finite"))
            poly = shapely.Polygon(v)
            if not poly.is_valid or poly.area <= 0:
                reason = shapely.is_valid_reason(poly)
                raise MapError(f"obstacle {i} is not a simple polygon with area ({reason})")
            v.flags.writeable = False
            polys.append(v)
        object.__setattr__(self, "width", width)
        object.__setattr__(self, "height", height)
        object.__setattr__(self, "polygons", tuple(polys))

    # --- what other modules derive from the map, kept as long as the map ------------------
    def derived(self, key: Hashable, build: Callable[[], _T]) -> _T:
        """The value ``build()`` gives, built on the first call with ``key`` and kept on the map
        (maps are immutable, so the episodes on one map share it): the other modules' per-map
        caches (planner grids, static shapes, line-of-sight tests, coverage rasters).

        Kept on the map itself rather than in a module-level dictionary weakly keyed by the
        map: a value that refers back to its map (a :class:`~aoass_env.radio.Radio` does)
        would keep its key alive there, and every map with it.
        """
        store = self.__dict__.setdefault("_derived", {})
        if key not in store:
            store[key] = build()
        return store[key]

    def __getstate__(self) -> dict[str, Any]:
        """The map without what :meth:`derived` keeps (built again on demand after unpickling;
        some of it, such as a planner's compiled state, does not pickle)."""
        state = self.__dict__.copy()
        state.pop("_derived", None)
        return state

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
            for piece in _convex_decomposition(closed):
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
        clearance = real("clearance", clearance, "m", low=0.0, error=MapError)
        if clearance in self._traversable:
            return
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
        self._traversable.add(clearance)

    @cached_property
    def _traversable(self) -> set[float]:
        """Clearances (m) > 0 that :meth:`check_traversable` has passed (the map is
        immutable)."""
        return set()

    def sample_free_points(self, n: int, rng: np.random.Generator,
                           clearance: float = 0.0) -> np.ndarray:
        """``n`` points (n, 2) uniform in the free space, at least ``clearance`` (m) from every
        obstacle and from the border (rejection sampling in vectorised batches)."""
        n = integer("n", n, "points", low=0, error=MapError)
        _check_rng(rng)
        clearance = real("clearance", clearance, "m", low=0.0, error=MapError)
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
