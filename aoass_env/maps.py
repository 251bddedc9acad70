"""Obstacle maps: the field, its static obstacle polygons and their geometry.

An :class:`ObstacleMap` is a rectangular field ``[0, width] x [0, height]`` (m) with simple
polygons (possibly concave, no holes) as static obstacles. Polygons are stored counter-clockwise
without a repeated closing vertex, as RVO2 and pymunk expect.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import shapely
from pymunk import autogeometry
from shapely.geometry.base import BaseGeometry


class MapError(ValueError):
    """A map cannot be used: bad geometry, disconnected free space or too little room."""


def _as_ccw(vertices: np.ndarray) -> np.ndarray:
    """(k, 2) float64 vertices in counter-clockwise order, closing duplicate removed."""
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 2)
    if len(v) > 1 and np.array_equal(v[0], v[-1]):
        v = v[:-1]
    x, y = v[:, 0], v[:, 1]
    signed_area = 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
    return v[::-1].copy() if signed_area < 0 else v.copy()


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
        """Union of all obstacles clipped to the field."""
        if not self.polygons:
            return shapely.Polygon()
        return shapely.intersection(shapely.union_all(self.shapes), self.field_polygon)

    @cached_property
    def free_space(self) -> BaseGeometry:
        """The field minus the obstacles."""
        return shapely.difference(self.field_polygon, self.union)

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
        """Boolean mask of points (M, 2) lying in an obstacle dilated by ``dilation`` (m)."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if not self.polygons:
            return np.zeros(len(pts), dtype=bool)
        geom = self.union if dilation <= 0 else self.union.buffer(dilation)
        return shapely.intersects_xy(geom, pts[:, 0], pts[:, 1]) if dilation > 0 else \
            shapely.contains_xy(geom, pts[:, 0], pts[:, 1])

    def bounds_contain(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Mask of points (M, 2) inside the field shrunk by ``margin`` (m)."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        return ((pts[:, 0] >= margin) & (pts[:, 0] <= self.width - margin)
                & (pts[:, 1] >= margin) & (pts[:, 1] <= self.height - margin))
