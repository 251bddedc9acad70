"""Conservative clearance of the static obstacles: cheap proofs that a query cannot hit them.

:class:`ClearanceGrid` gives, for any point (x, y) of the field, a lower bound (m) of its distance
to the static obstacles and the field border. The world uses it to skip pymunk's swept-disc and
ray queries that provably return no hit, so results stay exactly what the queries would give.

Construction (about 1-3 ms on a 100 x 100 m field): the field is rasterised into square cells;
a cell is *occupied* when it holds a point sampled along an obstacle edge (spacing at most
``cell / 2``) or when its centre lies inside an obstacle; scipy's Euclidean distance transform
gives each cell's distance to the nearest occupied cell centre. For a point p outside every
obstacle, the nearest obstacle point lies on an edge, within ``spacing / 2`` of a sample, whose
cell centre is within half a cell diagonal of it, and p is within half a diagonal of its own
cell centre; so ``edt - diagonal - spacing / 2`` bounds p's distance from below. A point inside
an obstacle gets a bound of at most half a cell diagonal (its cell centre is inside the obstacle
unless an edge is that close), so bounds up to half a diagonal are reported as 0.
"""

from __future__ import annotations

import math

import numpy as np
import shapely
from scipy import ndimage

from aoass_env.maps import ObstacleMap
from aoass_env.validators import positive

__all__ = ["ClearanceGrid"]

#: Absolute slack (m) for the float round-off of the distance transform and the sampling.
_ROUND_OFF = 1e-6


def _edge_samples(edges: np.ndarray, spacing: float) -> np.ndarray:
    """Points (K, 2) along edges (E, 2, 2), both ends included, at most ``spacing`` (m) apart."""
    a, d = edges[:, 0], edges[:, 1] - edges[:, 0]
    pieces = np.maximum(np.ceil(np.hypot(d[:, 0], d[:, 1]) / spacing), 1).astype(np.int64)
    edge = np.repeat(np.arange(len(edges)), pieces + 1)
    first = np.repeat(np.cumsum(pieces + 1) - (pieces + 1), pieces + 1)
    t = (np.arange(len(edge)) - first) / pieces[edge]
    return a[edge] + t[:, None] * d[edge]


class ClearanceGrid:
    """Lower bounds of the distance (m) from field points to static obstacles and border.

    Args:
        obstacle_map: the field and its static obstacles.
        cell: grid cell side (m); smaller cells give tighter bounds and cost more to build.
    """

    def __init__(self, obstacle_map: ObstacleMap, cell: float = 1.0) -> None:
        cell = positive("cell", cell, "m")
        self.width, self.height, self.cell = obstacle_map.width, obstacle_map.height, cell
        nx = max(1, math.ceil(self.width / cell))
        ny = max(1, math.ceil(self.height / cell))
        self._ny, self._inv = ny, 1.0 / self.cell
        half_diagonal = self.cell / math.sqrt(2.0)
        self._floor = half_diagonal
        xs, ys = (np.arange(nx) + 0.5) * cell, (np.arange(ny) + 0.5) * cell
        gx, gy = np.meshgrid(xs, ys, indexing="ij")
        occupied = shapely.contains_xy(obstacle_map.union, gx, gy)
        spacing = 0.5 * self.cell
        ij = np.floor(_edge_samples(obstacle_map.edges, spacing) / cell).astype(np.int64)
        ij = ij[(ij[:, 0] >= 0) & (ij[:, 0] < nx) & (ij[:, 1] >= 0) & (ij[:, 1] < ny)]
        occupied[ij[:, 0], ij[:, 1]] = True
        if not occupied.any():      # no obstacle in the field: the border alone bounds
            self._bound = [math.inf] * (nx * ny)
            return
        edt = ndimage.distance_transform_edt(~occupied) * self.cell
        bound = edt - 2.0 * half_diagonal - 0.5 * spacing - _ROUND_OFF
        self._bound = bound.ravel().tolist()

    def lower_bound(self, x: float, y: float) -> float:
        """A lower bound (m) of the distance from (x, y) (m) to every static obstacle and the
        field border; 0 when the point may be inside an obstacle or outside the field."""
        border = min(x, self.width - x, y, self.height - y)
        if not border > 0.0:    # outside the field (or NaN)
            return 0.0
        bound = min(self._bound[int(x * self._inv) * self._ny + int(y * self._inv)], border)
        return bound if bound > self._floor else 0.0
