"""The anchor's own coverage map: where, by what it has broadcast so far, Eq. 18 coverage is
still missing.

The anchor never knows where the nodes are. It knows its beacon positions, the radio range R and
the degree of irregularity (DOI) bound, and its static obstacle map. :class:`CoverageMap` rasters
the field into square cells of ``coverage_cell`` metres and treats the centre of every cell
outside the obstacles as a virtual node that hears a beacon when the beacon lies within the
*guaranteed* range and in line of sight:

    r_cell = R (1 - DOI) - cell / sqrt(2),

so that any node of the cell within that range of the centre is within R (1 - DOI) of the
beacon (line of sight is checked from the centre only). A cell whose centre lies inside an
obstacle but which keeps at least ``PARTIAL_CELL_SHARE`` of its area free (a cell along an
obstacle's edge, where nodes lie as densely as anywhere) has its virtual node at a point of its
free part instead; there the range guarantee is approximate (a node of the free part may lie up
to a cell's diagonal from that point). A cell is covered when it meets Eq. 18
the way a node does (at least 3 heard beacons, not collinear: their root-sum-square distance
from the best-fit line is at least ``collinearity_tol``). The bookkeeping is the network's own
(:class:`~aoass_env.network.Network`), on the virtual nodes, with the radio's own receivers
(:class:`~aoass_env.radio.Radio`): one beacon updates only the cells within r_cell of it.

Each cell's **deficit** in [0, 1] says how far it is from coverage: 0 when covered, else
(missing beacons + missing spread) / 4 with missing beacons = max(0, 3 - heard) and missing
spread = 1 - min(1, residual / collinearity_tol); a cell that heard nothing has deficit 1.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable
from typing import TypeVar

import numpy as np
import shapely

from aoass_env.config import AOASSConfig
from aoass_env.jit import njit
from aoass_env.maps import ObstacleMap
from aoass_env.network import Network, lambda_min, residual_after
from aoass_env.radio import Radio, points_within

__all__ = ["PARTIAL_CELL_SHARE", "CoverageMap"]

_T = TypeVar("_T")

#: A cell whose centre lies inside an obstacle is kept when at least this share of its area is
#: free (its virtual node then lies in the free part).
PARTIAL_CELL_SHARE = 0.3


@njit
def _sector_means(turned: np.ndarray, values: np.ndarray, cells: np.ndarray,
                  n_sectors: int) -> np.ndarray:
    """(n_sectors,) mean of ``values[cells]`` by sector ``floor(turned / (2 pi) * n_sectors)`` (at
    most the last) of their bearings ``turned`` in [0, 2 pi], summed in order; 0 where
    empty."""
    total = np.zeros(n_sectors)
    count = np.zeros(n_sectors, dtype=np.int64)
    for k in range(len(turned)):
        sector = min(int(math.floor(turned[k] / (2.0 * math.pi) * n_sectors)), n_sectors - 1)
        total[sector] += values[cells[k]]
        count[sector] += 1
    out = np.zeros(n_sectors)
    for sector in range(n_sectors):
        if count[sector] > 0:
            out[sector] = total[sector] / count[sector]
    return out


def _free_points(obstacle_map: ObstacleMap, index: np.ndarray, cell: float) -> np.ndarray:
    """(K, 2) for the cells ``index`` (K, 2) whose centre lies inside an obstacle: a point (m)
    of each cell's free part where at least :data:`PARTIAL_CELL_SHARE` of it is free, NaN
    elsewhere."""
    out = np.full((len(index), 2), np.nan)
    if not len(index):
        return out
    lo = index * cell
    hi = np.minimum(lo + cell, [obstacle_map.width, obstacle_map.height])
    boxes = shapely.box(lo[:, 0], lo[:, 1], hi[:, 0], hi[:, 1])
    # a cell the obstacles cover has no free part: only the others are cut (the overlays are
    # most of the raster's cost; the prepared union answers the covers test quickly)
    open_cells = np.flatnonzero(~shapely.covers(obstacle_map.union, boxes))
    parts = shapely.difference(boxes[open_cells], obstacle_map.union)
    keep = shapely.area(parts) >= PARTIAL_CELL_SHARE * cell * cell
    if keep.any():
        out[open_cells[keep]] = shapely.get_coordinates(shapely.point_on_surface(parts[keep]))
    return out


def _cells(obstacle_map: ObstacleMap, cell: float, reach: float, line_of_sight: bool
           ) -> tuple[tuple[int, int], np.ndarray, np.ndarray, Radio]:
    """The map's raster: (nx, ny), the kept cells' (i, j) and virtual nodes (read-only), and
    the radio of the virtual nodes (:class:`CoverageMap`); built once per map and settings
    (:meth:`~aoass_env.maps.ObstacleMap.derived`: the radio refers back to the map)."""
    return obstacle_map.derived(("coverage cells", float(cell), float(reach),
                                 bool(line_of_sight)),
                                lambda: _build_cells(obstacle_map, cell, reach, line_of_sight))


def _build_cells(obstacle_map: ObstacleMap, cell: float, reach: float, line_of_sight: bool
                 ) -> tuple[tuple[int, int], np.ndarray, np.ndarray, Radio]:
    """:func:`_cells` built."""
    nx = max(1, math.ceil(obstacle_map.width / cell))
    ny = max(1, math.ceil(obstacle_map.height / cell))
    gi, gj = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    index = np.stack([gi.ravel(), gj.ravel()], axis=1)
    centres = (index + 0.5) * cell
    centres = np.minimum(centres, [obstacle_map.width, obstacle_map.height])
    free = ~obstacle_map.inside_obstacle(centres)
    centres[~free] = _free_points(obstacle_map, index[~free], cell)
    free |= np.isfinite(centres[:, 0])
    index, centres = index[free], centres[free]
    index.flags.writeable = False
    centres.flags.writeable = False
    return ((nx, ny), index, centres,
            Radio(centres, obstacle_map, reach, line_of_sight=line_of_sight))


class CoverageMap:
    """Eq. 18 coverage of the free field as the anchor can know it (module docstring).

    Args:
        obstacle_map: the static obstacles (the anchor's map).
        config: supplies ``coverage_cell`` (m), ``radio_range`` (m), ``doi``,
            ``line_of_sight`` and ``collinearity_tol`` (m).

    Attributes:
        cell: the cell side (m).
        shape: (nx, ny) cells; cell (i, j) has its centre at ((i + 0.5) cell, (j + 0.5) cell).
        centres: (C, 2) the virtual nodes (m) of the free cells, the cells the map keeps: the
            centre of a cell whose centre lies outside every obstacle, else a point of the
            cell's free part when at least ``PARTIAL_CELL_SHARE`` of it is free (module
            docstring); ``index`` (C, 2) their (i, j).
        reach: r_cell (m).
    """

    def __init__(self, obstacle_map: ObstacleMap, config: AOASSConfig) -> None:
        self.cell = config.coverage_cell
        self.reach = config.cell_range
        self._map = obstacle_map
        self.shape, self.index, self.centres, self._radio = _cells(
            obstacle_map, self.cell, self.reach, config.line_of_sight)
        self._network = Network(max(len(self.centres), 1), config)
        self._tol = config.collinearity_tol
        self._deficit: np.ndarray | None = None      # of every free cell, until a beacon
        self._cx, self._cy = self.centres[:, 0].copy(), self.centres[:, 1].copy()
        self._every = np.ones(len(self.centres), dtype=bool)

    def derived(self, key: Hashable, build: Callable[[], _T]) -> _T:
        """A value derived from this raster (its map, cell, reach and line of sight) for the
        hashable settings ``key``, built by ``build()`` once and kept with the map
        (:meth:`~aoass_env.maps.ObstacleMap.derived`; the episodes on one map share it): the
        adaptive sweep's plans, beacon sites and coverable cells."""
        return self._map.derived(("coverage raster", self.cell, self.reach,
                                  self._radio.line_of_sight, key), build)

    def listeners(self) -> tuple[Radio, np.ndarray]:
        """(radio, among) for :func:`~aoass_env.radio.receivers_at`: the cells' radio and the
        cells a beacon is tested for now. Covered cells stay covered: only the others are
        tested (their counts then freeze)."""
        return self._radio, ~self.covered

    def add_beacon(self, position: np.ndarray, cells: np.ndarray | None = None) -> int:
        """Record a beacon broadcast at ``position`` (2,) (m); the number of cells it made
        covered. ``cells``: its receivers among :meth:`listeners` when the caller has them
        (the simulator tests them with the nodes' links), else they are found here."""
        if not len(self.centres):
            return 0
        self._deficit = None
        if cells is None:
            radio, among = self.listeners()
            cells = radio.receivers(position, among)
        return self._network.record_beacon(position, cells)

    # --- what the map says --------------------------------------------------------------------
    @property
    def n_cells(self) -> int:
        """Free cells."""
        return len(self.centres)

    @property
    def covered(self) -> np.ndarray:
        """(C,) bool: the free cells meeting Eq. 18 (read-only)."""
        return self._network.covered[:self.n_cells]

    @property
    def heard(self) -> np.ndarray:
        """(C,) beacons each free cell heard until it was covered (read-only)."""
        return self._network.heard[:self.n_cells]

    @property
    def deficit(self) -> np.ndarray:
        """(C,) how far each free cell is from coverage, in [0, 1] (module docstring);
        read-only, computed once per beacon."""
        if self._deficit is None:
            self._deficit = self.deficit_at(np.arange(self.n_cells))
            self._deficit.flags.writeable = False
        return self._deficit

    @property
    def radio(self) -> Radio:
        """The radio of the virtual nodes (guaranteed range, line of sight), shared by the
        episodes on one map: for planning what beacons would cover."""
        return self._radio

    @property
    def beacons(self) -> int:
        """Beacons recorded so far (:meth:`add_beacon`); the cells' state changes only with
        one."""
        return self._network.beacons_sent

    @property
    def ratio(self) -> float:
        """Covered share of the free cells (the area coverage ratio), in [0, 1]."""
        return self._network.n_covered / self.n_cells if self.n_cells else 1.0

    def near(self, point: np.ndarray, radius: float) -> np.ndarray:
        """Indices of the free cells whose centre lies within ``radius`` (m) of ``point``."""
        if not radius >= 0:
            raise ValueError(f"radius={radius!r} must be a number >= 0 m")
        d = self.centres - np.asarray(point, dtype=np.float64)
        return np.flatnonzero(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] <= radius * radius)

    def deficit_at(self, cells: np.ndarray) -> np.ndarray:
        """The deficit (module docstring) of the free cells ``cells`` (indices)."""
        net = self._network
        missing = np.maximum(0, 3 - net.heard[cells])
        # the line residual of these cells only (Network.line_residual, element by element)
        residual = np.sqrt(lambda_min(net.scatter[cells]))
        spread = 1.0 - np.minimum(1.0, residual / self._tol)
        return np.where(net.covered[cells], 0.0, (missing + spread) / 4.0)

    def residual_after(self, cell: int, points: np.ndarray) -> np.ndarray:
        """(K,) the spread (m) free cell ``cell`` would have, its heard beacons' distance to
        their best line, if one more beacon were sent from each of ``points`` (K, 2) (m) alone
        (:func:`~aoass_env.network.residual_after`)."""
        net = self._network
        return residual_after(int(net.heard[cell]), net.beacon_centroid[cell],
                              net.scatter[cell], points)

    def visible_near(self, point: np.ndarray, radius: float) -> np.ndarray:
        """Indices of the free cells within ``radius`` (m, at most :attr:`reach`) of ``point``
        that a beacon sent there reaches (line of sight)."""
        cells = self._radio.receivers(np.asarray(point, dtype=np.float64))
        d = self.centres[cells] - point
        return cells[d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] <= radius * radius]

    def sector_deficits(self, position: np.ndarray, heading: float, n_sectors: int,
                        radius: float) -> np.ndarray:
        """(n_sectors,) mean deficit of the free cells within ``radius`` (m) of ``position``, by
        bearing sector relative to ``heading`` (rad): sector k spans [k, k + 1) x 2π /
        n_sectors counter-clockwise from straight ahead. An empty sector (all obstacle or
        outside the field) reads 0: nothing to cover there."""
        x, y = (float(v) for v in np.asarray(position, dtype=np.float64))
        # the compiled sums index by sector: a NaN bearing or no sector would write out of
        # bounds, so the scalars are checked here (a few comparisons per step)
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(heading)):
            raise ValueError(f"position={[x, y]} and heading={heading!r} rad must be finite")
        if isinstance(n_sectors, bool) or not isinstance(n_sectors, (int, np.integer)) \
                or n_sectors < 1 or not radius >= 0:
            raise ValueError(f"n_sectors={n_sectors!r} must be an integer >= 1 and "
                             f"radius={radius!r} a number >= 0 m")
        cells = points_within(self._cx, self._cy, self._every, x, y, radius * radius)
        # the bearings by NumPy (its arctan2 and mod), the sectors' sums compiled, in order
        turned = np.mod(np.arctan2(self._cy[cells] - y, self._cx[cells] - x) - heading,
                        2.0 * math.pi)
        return _sector_means(turned, self.deficit, cells, int(n_sectors))

    def raster(self) -> np.ndarray:
        """(nx, ny) deficit per cell, NaN for cells inside obstacles (for drawing)."""
        grid = np.full(self.shape, np.nan)
        grid[self.index[:, 0], self.index[:, 1]] = self.deficit
        return grid
