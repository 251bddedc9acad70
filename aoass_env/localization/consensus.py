"""Visibility consensus: where on the map does a node's heard / unheard record fit best?

The obstacle map is known to the localizer, so every beacon says something about every point of
the field. A beacon heard by node k constrains k to points *in range and in sight* of it
(distance <= R (1 + DOI), no obstacle between); a beacon k did not hear rules out the points in
sight of it within R (1 - DOI), where it would surely have been heard. On a grid of ``cell``-metre
cells, the consensus estimate of k is the mean of the cells with the fewest violations

    violations(c) = #{heard b: |b - c| > R (1 + DOI) or an obstacle blocks b -> c}
                  + #{unheard b: |b - c| <= R (1 - DOI) and nothing blocks b -> c},

cells inside obstacles excluded. Violations are counted, not forbidden: moving obstacles (not in
the map) block some beacons, and cell centres are up to ``cell / sqrt 2`` from the node.

**Neighbour stages.** Every node is then scored again, ``NEIGHBOUR_ROUNDS`` times, with the
*reliable* nodes (best cells spread at most ``RELIABLE_SPREAD``, RMS distance from their mean, at
the stage before) as further transmitters at their estimates of the stage before: its neighbours
(``node_links``) count like heard beacons, the reliable nodes it does not hear like unheard
ones; a reliable node is no transmitter to itself. Node links obey the same range and
line-of-sight rules as beacons (within R (1 + DOI) and in sight; certain within R (1 - DOI)).
The neighbour stages read the beacons' violations of every box cell kept from the first stage
(a neighbour stage's box lies inside the first stage's).

Speed comes from three restrictions (docs/localization.md):

* **Visibility rasters.** Line of sight is decided per beacon for the cells of a square stencil
  around it, from a polar *profile*: the distance from the beacon to the first obstacle edge that
  faces it, in each of ``ANGLE_BINS`` directions (only edges facing the beacon can be entered
  first). A cell is in sight when it is nearer than the profile in its direction. The profile is
  exact on the bin centres; a cell off its bin centre may be judged wrongly within
  ``pi R / ANGLE_BINS`` (8 cm at R = 25 m) of a shadow boundary.
* **Candidate boxes.** Only cells in the bounding box of the intersection of the heard discs
  (radius R (1 + DOI) + cell / sqrt 2, so the node's own cell is in it) are scored.
* **One count per cell for all unheard beacons.** The unheard violations of a cell are the
  beacons in sight within R (1 - DOI) of it (one field-wide raster, ``certain``) minus the
  heard ones among them, so only heard beacons are looked up per node.
"""

from __future__ import annotations

import itertools
import weakref
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import shapely
from scipy.spatial import cKDTree

from aoass_env.localization.episode import Episode
from aoass_env.localization.ragged import pad_rows
from aoass_env.validators import index_array, positive

__all__ = ["ANGLE_BINS", "DEFAULT_CELL", "NEIGHBOUR_ROUNDS", "RELIABLE_SPREAD", "Consensus",
           "VisibilityRaster", "consensus", "node_consensus", "visibility_raster"]

#: Grid cell size [m].
DEFAULT_CELL = 0.5
#: Nodes whose best cells spread at most this [m] are reliable: transmitters in the neighbour
#: stages (and the OLSTM's record).
RELIABLE_SPREAD = 1.0
#: Neighbour stages after the beacons-only stage (chosen on maps/train logs, docs/localization.md:
#: 1 did worse; 3 gains at most 0.05 m at most DOIs but takes the N = 1000 log past 2 s).
NEIGHBOUR_ROUNDS = 2
#: Directions of a beacon's visibility profile.
ANGLE_BINS = 1024
_CHUNK_LOOKUPS = 2_000_000  # (cell, beacon) lookups per chunk of nodes


@dataclass(frozen=True)
class VisibilityRaster:
    """Per transmitter (beacon, or node at its estimate), what each cell of an (S, S) stencil
    around it makes of it.

    ``weight`` is flat: transmitter b at cell (ix, iy) is entry ``key[b] + ix * S + iy`` for the
    cells of b's stencil, which holds every cell within R (1 + DOI) + cell of b along x and y;
    ``key[-1]`` (padding) lands on an all-zero tail for any cell of the field.

    Attributes:
        cell: cell size [m]; cell (i, j) has its centre at ((i + 0.5) cell, (j + 0.5) cell).
        shape: (nx, ny) cells of the field.
        field: (width, height) [m]; the last cells of a field that is not a whole number of
            cells reach beyond it, and an estimate takes the centre of their part on the field.
        size: S, stencil side [cells].
        key: (M + 1,) int64 table offset of each transmitter, and of padding (last).
        weight: flat uint8 table: 2 in sight within R (1 - DOI) (hearing is certain), 1 in sight
            within R (1 + DOI) (hearing is possible), 0 otherwise (not in sight, too far, cell
            inside an obstacle or off the field).
        certain: (nx, ny) number of transmitters in sight within R (1 - DOI) of each cell.
        inside: (nx, ny) bool, cell centre inside an obstacle.
    """

    cell: float
    shape: tuple[int, int]
    field: tuple[float, float]
    size: int
    key: np.ndarray
    weight: np.ndarray
    certain: np.ndarray
    inside: np.ndarray


def _profiles(beacon_xy: np.ndarray, polygons: tuple[np.ndarray, ...], reach: float,
              bins: int) -> np.ndarray:
    """(M, bins) distance [m] from each transmitter to the first obstacle edge facing it along
    the centre direction of each angle bin (``inf``: none within ``reach``)."""
    out = np.full((len(beacon_xy), bins), np.inf)
    if not polygons or not len(beacon_xy):
        return out
    p = np.concatenate(polygons)
    q = np.concatenate([np.roll(v, -1, axis=0) for v in polygons])
    mid, half = (p + q) / 2, np.hypot(*(q - p).T) / 2
    tree = cKDTree(beacon_xy)
    lists = tree.query_ball_point(mid, reach + half)
    counts = np.fromiter((len(x) for x in lists), dtype=np.int64, count=len(lists))
    if counts.sum() == 0:
        return out
    edge = np.repeat(np.arange(len(p)), counts)
    beacon = np.concatenate([np.asarray(x, dtype=np.int64) for x in lists])
    rp, rq = p[edge] - beacon_xy[beacon], q[edge] - beacon_xy[beacon]
    e = q[edge] - p[edge]
    # polygons are counter-clockwise: an edge faces the beacon when the beacon is on its right
    facing = e[:, 0] * rp[:, 1] - e[:, 1] * rp[:, 0] > 0
    beacon, rp, rq, e = beacon[facing], rp[facing], rq[facing], e[facing]
    step = 2 * np.pi / bins
    # seen from the beacon, a facing edge runs clockwise from p to q: sweep q -> p
    a_q = np.arctan2(rq[:, 1], rq[:, 0])
    sweep = (np.arctan2(rp[:, 1], rp[:, 0]) - a_q) % (2 * np.pi)
    first = np.ceil(a_q / step - 0.5).astype(np.int64)
    n_bins = np.floor((a_q + sweep) / step - 0.5).astype(np.int64) - first + 1
    n_bins = np.maximum(n_bins, 0)
    pair = np.repeat(np.arange(len(beacon)), n_bins)
    k = first[pair] + np.arange(len(pair)) - np.repeat(np.cumsum(n_bins) - n_bins, n_bins)
    angle = (k + 0.5) * step
    # ray b + s u meets edge p + t e where s = (rp x e) / (u x e)
    num = rp[pair, 0] * e[pair, 1] - rp[pair, 1] * e[pair, 0]
    den = np.cos(angle) * e[pair, 1] - np.sin(angle) * e[pair, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        dist = np.where(den != 0, num / den, np.inf)
    dist = np.where(dist >= 0, dist, np.inf)
    np.minimum.at(out.reshape(-1), beacon[pair] * bins + k % bins, dist)
    return out


def visibility_raster(episode: Episode, cell: float = DEFAULT_CELL, bins: int = ANGLE_BINS,
                      points: np.ndarray | None = None,
                      band: tuple[np.ndarray, np.ndarray] | None = None) -> VisibilityRaster:
    """The :class:`VisibilityRaster` of ``episode`` on a grid of ``cell`` metres, for the
    transmitters at ``points`` (M, 2) [m] (default: the beacons).

    ``band``: range factors (certain, possible), each (360,) per whole degree of the direction
    transmitter -> cell, in place of the DOI bound (1 - DOI, 1 + DOI); within [1 - DOI, 1 + DOI]
    (the OLSTM's learned reception range, :mod:`~aoass_env.localization.olstm`).

    Raises:
        ValueError: ``cell`` is not a positive number or ``bins`` not a power of two >= 8.
    """
    positive("cell", cell, "m")
    if not (isinstance(bins, int) and bins >= 8 and bins & (bins - 1) == 0):
        raise ValueError(f"bins={bins!r} must be a power of two >= 8")
    geo = _stencil_geometry(episode, cell, bins, points)
    shape, size, origin, pad, xy = geo.shape, geo.size, geo.origin, geo.pad, geo.xy
    r_hi = episode.log.radio_range * (1 + episode.config.doi)
    r_lo = episode.log.radio_range * (1 - episode.config.doi)
    if band is not None:
        # dist <= radius x band[deg]: per degree, the threshold as the largest float32 not
        # above it, so that float32 distances compare as they do with the exact threshold
        radius = episode.log.radio_range
        lo_at, hi_at = (_float32_floor(radius * b) for b in band)
    n, stencil = len(xy), size * size
    tail = shape[0] * size + shape[1]          # all-zero padding lands here
    weight = np.zeros(n * stencil + tail, dtype=np.uint8)
    table = weight[:n * stencil].reshape(n, size, size)
    certain = np.zeros((shape[0] + 2 * pad, shape[1] + 2 * pad), dtype=np.int32)
    for a, z in _chunks(n, stencil):
        dist, sight = geo.dist[a:z], geo.sight[a:z]
        if band is None:
            near = sight & (dist <= r_lo)
            np.add(near, sight & (dist <= r_hi), out=table[a:z], dtype=np.uint8)
        else:
            # whole degrees of the direction (int32: the same values as int64 in [0, 360))
            deg = np.degrees(np.arctan2(geo.dy[a:z], geo.dx[a:z]))
            np.rint(deg, out=deg)
            deg = deg.astype(np.int32)
            deg %= 360
            near = sight & (dist <= lo_at[deg])
            np.add(near, sight & (dist <= hi_at[deg]), out=table[a:z], dtype=np.uint8)
        for (ox, oy), block in zip(origin[a:z] + pad, near, strict=True):
            certain[ox:ox + size, oy:oy + size] += block
    certain = certain[pad:-pad, pad:-pad]
    key = np.r_[np.arange(n) * stencil - origin[:, 0] * size - origin[:, 1], n * stencil]
    return VisibilityRaster(cell=float(cell), shape=shape, field=tuple(map(float, episode.field)),
                            size=size, key=key, weight=weight, certain=certain,
                            inside=geo.inside)


@dataclass(frozen=True)
class _Geometry:
    """What a visibility raster's transmitters see of their stencils, whatever the range
    model: the stencil placement, the (M, S, S) float32 distances of the cell centres from each
    transmitter (offsets ``dx`` (M, S, 1), ``dy`` (M, 1, S)), and which cells are in sight."""

    xy: np.ndarray
    shape: tuple[int, int]
    size: int
    origin: np.ndarray
    pad: int
    dx: np.ndarray
    dy: np.ndarray
    dist: np.ndarray
    sight: np.ndarray
    inside: np.ndarray


#: The last beacon stencil geometry: (weak reference to its episode, cell, bins, geometry). The
#: OLSTM's two consensus passes over one log share it (only the range model differs).
_LAST_GEOMETRY: list[tuple[weakref.ref, float, int, _Geometry]] = []
#: Stencil cells per chunk of transmitters: the temporaries of a chunk are reused by the next
#: instead of each being a fresh whole-raster array.
_CHUNK_CELLS = 1 << 21


def _chunks(n: int, stencil: int) -> list[tuple[int, int]]:
    """[a, z) ranges of ``n`` transmitters of ``stencil`` cells each, about
    :data:`_CHUNK_CELLS` cells per range."""
    step = max(1, _CHUNK_CELLS // max(stencil, 1))
    return [(a, min(a + step, n)) for a in range(0, n, step)]


def _float32_floor(values: np.ndarray) -> np.ndarray:
    """The largest float32 not above each of ``values``: for a float32 d, ``d <= v`` exactly
    when ``d <= _float32_floor(v)``."""
    v = np.asarray(values)
    out = v.astype(np.float32)
    above = out.astype(v.dtype) > v
    out[above] = np.nextafter(out[above], np.float32(-np.inf))
    return out


def _stencil_geometry(episode: Episode, cell: float, bins: int,
                      points: np.ndarray | None) -> _Geometry:
    """The :class:`_Geometry` of ``points`` (default: the beacons; then shared with the last
    call on the same episode, cell and bins)."""
    if points is None and _LAST_GEOMETRY:
        ref, last_cell, last_bins, geo = _LAST_GEOMETRY[0]
        if ref() is episode and last_cell == cell and last_bins == bins:
            return geo
    config = episode.config
    xy = episode.beacon_xy if points is None else np.asarray(points, dtype=np.float64)
    r_hi = episode.log.radio_range * (1 + config.doi)
    w, h = episode.field
    shape = (int(np.ceil(w / cell)), int(np.ceil(h / cell)))
    # the border ring of the stencil lies beyond r_hi, and every cell of a candidate box lies
    # within r_hi + cell / sqrt 2 of each heard beacon along x and y: both fit in this half-width
    half = int(np.ceil(r_hi / cell)) + 2
    size = 2 * half + 1
    origin = np.floor(xy / cell).astype(np.int64) - half
    offs = np.arange(size)
    # (B, S, S) offsets of the stencil's cell centres from the beacon [m]
    cx = ((origin[:, 0, None] + offs + 0.5) * cell - xy[:, 0, None]).astype(np.float32)
    cy = ((origin[:, 1, None] + offs + 0.5) * cell - xy[:, 1, None]).astype(np.float32)
    dx, dy = cx[:, :, None], cy[:, None, :]
    inside = _inside_cells(episode.log.obstacle_map.polygons, shape, cell)
    # cells off the field or inside an obstacle are never in sight; the ring of excluded cells
    # also holds the stencils of points off the field (a log may place a beacon up to 1 % of
    # its side outside: such a stencil ran past the ring, a broadcast or index error)
    beyond = max(0.0, float(-xy.min(initial=0.0)), float((xy - (w, h)).max(initial=0.0)))
    pad = half + 1 + int(np.ceil(beyond / cell))
    excluded = np.ones((shape[0] + 2 * pad, shape[1] + 2 * pad), dtype=bool)
    excluded[pad:-pad, pad:-pad] = inside
    gx, gy = (origin[:, 0, None] + pad + offs)[:, :, None], (origin[:, 1, None] + pad + offs)
    n = len(xy)
    dist = np.empty((n, size, size), dtype=np.float32)
    sight = np.empty((n, size, size), dtype=bool)
    profile = None
    if config.line_of_sight and episode.log.obstacle_map.polygons:
        profile = _profiles(xy, episode.log.obstacle_map.polygons, r_hi, bins)
        profile = profile.astype(np.float32).reshape(-1)
    for a, z in _chunks(n, size * size):
        d = dist[a:z]
        np.add(dx[a:z] * dx[a:z], dy[a:z] * dy[a:z], out=d)
        np.sqrt(d, out=d)
        np.logical_not(excluded[gx[a:z], gy[a:z, None, :]], out=sight[a:z])
        if profile is not None:
            # angle bin, floor of a positive number by truncation, wrapped by a mask (bins =
            # 2^k)
            k = np.arctan2(dy[a:z], dx[a:z])
            k *= np.float32(bins / (2 * np.pi))
            k += np.float32(bins)
            k = k.astype(np.int32)
            k &= bins - 1
            k += (np.arange(a, z, dtype=np.int32) * bins)[:, None, None]
            sight[a:z] &= d < np.take(profile, k)
    geo = _Geometry(xy, shape, size, origin, pad, dx, dy, dist, sight, inside)
    if points is None:
        _LAST_GEOMETRY[:] = [(weakref.ref(episode, _forget), cell, bins, geo)]
    return geo


def _forget(ref: weakref.ref) -> None:
    """Drop the shared geometry once its episode is gone (it is large)."""
    if _LAST_GEOMETRY and _LAST_GEOMETRY[0][0] is ref:
        _LAST_GEOMETRY.clear()


def _inside_cells(polygons: tuple[np.ndarray, ...], shape: tuple[int, int],
                  cell: float) -> np.ndarray:
    """(nx, ny) bool: cell centre strictly inside some obstacle polygon."""
    inside = np.zeros(shape, dtype=bool)
    for poly in polygons:
        lo = np.clip(np.floor(poly.min(axis=0) / cell).astype(np.int64), 0, shape)
        hi = np.clip(np.ceil(poly.max(axis=0) / cell).astype(np.int64), 0, shape)
        if np.any(hi <= lo):
            continue
        gx, gy = np.meshgrid((np.arange(lo[0], hi[0]) + 0.5) * cell,
                             (np.arange(lo[1], hi[1]) + 0.5) * cell, indexing="ij")
        inside[lo[0]:hi[0], lo[1]:hi[1]] |= shapely.contains_xy(shapely.Polygon(poly), gx, gy)
    return inside


@dataclass(frozen=True)
class Consensus:
    """Visibility-consensus result for S nodes.

    Attributes:
        nodes: (S,) node indices.
        estimate: (S, 2) mean of the best cells [m].
        spread: (S,) RMS distance of the best cells from the estimate [m] (0: one cell).
        violations: (S,) the fewest violations (0: a cell fits the whole record).
    """

    nodes: np.ndarray
    estimate: np.ndarray
    spread: np.ndarray
    violations: np.ndarray


class _Part(NamedTuple):
    """Transmitters of one raster as a group of nodes sees them."""

    raster: VisibilityRaster
    points: np.ndarray        # (M, 2) transmitter positions [m]
    heard: np.ndarray         # (S, H) transmitters each node heard, padded with -1
    own: np.ndarray | None    # (S,) each node's own transmitter (-1: none), None: no node is one


def _boxes(parts: list[_Part], reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Grid index ranges [i0, i1] (S, 2) of the bounding boxes of the intersections of the
    discs of radius ``reach`` [m] around every heard transmitter of every part; i1 < i0:
    empty."""
    raster = parts[0].raster
    xy = np.concatenate([np.where((part.heard >= 0)[..., None], part.points[part.heard], np.nan)
                         for part in parts], axis=1)
    top = np.array(raster.shape) - 1
    with np.errstate(invalid="ignore"):
        lo = np.nanmax(xy, axis=1) - reach
        hi = np.nanmin(xy, axis=1) + reach
    i0 = np.clip(np.floor(lo / raster.cell), 0, top).astype(np.int64)
    i1 = np.clip(np.ceil(hi / raster.cell) - 1, -1, top).astype(np.int64)
    return i0, i1


class _Scores(NamedTuple):
    """Violations of the cells of every node's box against the first part (the beacons), kept
    from the beacons-only stage for the neighbour stages (their boxes lie inside it)."""

    i0: np.ndarray      # (S, 2) first cell of each box
    wy: np.ndarray      # (S,) box height [cells]
    start: np.ndarray   # (S,) where each box's cells begin in ``viol`` (x-major)
    viol: np.ndarray    # violations per cell


def _chunk(parts: list[tuple[VisibilityRaster, np.ndarray, np.ndarray | None]], i0: np.ndarray,
           i1: np.ndarray, kept: _Scores | None = None
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """Estimate (S, 2), spread (S,) and fewest violations (S,) of S nodes with non-empty boxes
    [i0, i1], and, unless ``kept`` holds them, the violations against the first part per box
    cell (x-major, nodes in order); ``parts``: (raster, heard transmitters (S, H) padded with
    -1, each node's own transmitter (S,) or -1, or None), rasters on one grid. A node is not
    unheard by its own transmitter: its certain range adds no violation. ``kept``: the first
    part's violations of these S nodes on boxes holding [i0, i1], in place of scoring the first
    part again."""
    grid = parts[0][0]
    wx, wy = i1[:, 0] - i0[:, 0] + 1, i1[:, 1] - i0[:, 1] + 1
    n_cells = wx * wy
    s = len(i0)
    owner = np.repeat(np.arange(s), n_cells)
    local = np.arange(len(owner)) - np.repeat(np.cumsum(n_cells) - n_cells, n_cells)
    ix = i0[owner, 0] + local // wy[owner]
    iy = i0[owner, 1] + local % wy[owner]
    viol = np.zeros(len(owner))
    first = None
    for k, (raster, heard, own) in enumerate(parts):
        if k == 0 and kept is not None:
            at = kept.start[owner] + (ix - kept.i0[owner, 0]) * kept.wy[owner] \
                + iy - kept.i0[owner, 1]
            viol += np.take(kept.viol, at)
            continue
        # #heard - #heard in sight and reach + #in sight within R (1 - DOI) - #heard among
        # those; every box cell lies on every heard transmitter's stencil
        cells = ix * raster.size + iy
        entries = raster.key[heard][owner]
        entries += cells[:, None]
        fit = np.take(raster.weight, entries).sum(axis=1, dtype=np.int32)   # <= 2 per entry
        viol += (heard >= 0).sum(axis=1)[owner] + raster.certain[ix, iy] - fit
        if own is not None:
            # key[-1] (no own transmitter) lands on the all-zero padding
            viol -= np.take(raster.weight, raster.key[own][owner] + cells) == 2
        if k == 0:
            first = viol.astype(np.int32)
    viol[grid.inside[ix, iy]] = np.inf
    best = np.minimum.reduceat(viol, np.cumsum(n_cells) - n_cells)
    win = viol == best[owner]
    owner = owner[win]
    # cell centres; a last cell that reaches beyond the field: the centre of its part on it
    (w, h), c = grid.field, grid.cell
    px = np.minimum((ix[win] + 0.5) * c, 0.5 * (ix[win] * c + w))
    py = np.minimum((iy[win] + 0.5) * c, 0.5 * (iy[win] * c + h))
    n_win = np.bincount(owner, minlength=s)
    est = np.stack([np.bincount(owner, weights=v, minlength=s) for v in (px, py)], axis=1)
    est /= n_win[:, None]
    var = np.bincount(owner, weights=(px - est[owner, 0]) ** 2 + (py - est[owner, 1]) ** 2,
                      minlength=s) / n_win
    return est, np.sqrt(var), best, first


def _solve(parts: list[_Part], reach: float,
           result: tuple[np.ndarray, np.ndarray, np.ndarray], rows: np.ndarray,
           kept: _Scores | None = None) -> _Scores | None:
    """Score the nodes ``rows`` of ``result`` (estimate, spread, violations), in place; the
    heard (and own) arrays of ``parts`` have one row per entry of ``rows``. Nodes with an empty
    box keep their values. ``kept``: the first part's violations from an earlier call on the
    same rows with the first part alone (every box now lies inside that call's); returns, when
    ``kept`` is None, this call's (None otherwise)."""
    i0, i1 = _boxes(parts, reach)
    wy = i1[:, 1] - i0[:, 1] + 1
    n_heard = sum((part.heard >= 0).sum(axis=1) for part in parts)
    ok = np.flatnonzero(np.all(i1 >= i0, axis=1))
    # chunks of nodes with similar heard counts (little padding), bounded lookups per chunk
    ok = ok[np.argsort(n_heard[ok], kind="stable")]
    size = np.prod(i1[ok] - i0[ok] + 1, axis=1)
    start = np.zeros(len(rows), dtype=np.int64)
    start[ok] = np.cumsum(size) - size
    work = np.cumsum(size * n_heard[ok])
    bounds = np.unique(np.r_[np.searchsorted(work, np.arange(0, work[-1], _CHUNK_LOOKUPS)),
                             len(ok)]) if len(ok) else np.zeros(1, np.int64)
    first = []
    for a, b in itertools.pairwise(bounds):
        idx = ok[a:b]
        chunk = []
        for raster, _, heard, own in parts:
            width = max(int((heard[idx] >= 0).sum(axis=1).max()), 1)
            chunk.append((raster, heard[idx, :width], None if own is None else own[idx]))
        part_kept = None if kept is None else _Scores(kept.i0[idx], kept.wy[idx],
                                                      kept.start[idx], kept.viol)
        est, spread, viol, first_viol = _chunk(chunk, i0[idx], i1[idx], part_kept)
        if kept is None:
            first.append(first_viol)
        for out, value in zip(result, (est, spread, viol), strict=True):
            out[rows[idx]] = value
    if kept is not None:
        return None
    return _Scores(i0, wy, start, np.concatenate(first) if first else np.zeros(0, np.int32))


def _lists(rows: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """(n, L) padded lists of ``values`` per row, sorted within a row (pairs with a negative
    row or value dropped)."""
    keep = (rows >= 0) & (values >= 0)
    rows, values = rows[keep], values[keep]
    order = np.lexsort((values, rows))
    return pad_rows(rows[order], values[order], n)[0]


def node_consensus(episode: Episode, nodes: np.ndarray | None = None, *,
                   cell: float = DEFAULT_CELL,
                   band: tuple[np.ndarray, np.ndarray] | None = None) -> Consensus:
    """Visibility-consensus estimates of ``nodes`` (default: the Eq. 18 covered nodes).

    Every node from the beacons; then every node again, ``NEIGHBOUR_ROUNDS`` times, with its
    reliable neighbour nodes (best cells spread at most ``RELIABLE_SPREAD`` at the stage before;
    ``node_links``) as extra heard transmitters at their estimates of the stage before and the
    reliable nodes it does not hear as unheard ones (a reliable node is no transmitter to
    itself). A node whose heard discs (radius R (1 + DOI)) do not intersect on the field, which
    a log of this simulator never holds, keeps the centroid of its heard beacons, with NaN
    spread and violations.

    Args:
        episode: the prepared log.
        nodes: (S,) distinct node indices in [0, N); each must have heard a beacon.
        cell: grid cell size [m].
        band: per-degree range factors (certain, possible) of the beacons in place of the DOI
            bound (see :func:`visibility_raster`); node-to-node links keep the bound.

    Raises:
        ValueError: ``nodes`` are not distinct indices in [0, N), a node heard no beacon, or
            ``cell`` is not a positive number.
    """
    nodes = np.flatnonzero(episode.covered) if nodes is None \
        else index_array("nodes", nodes, episode.log.n_nodes)
    positive("cell", cell, "m")
    if len(nodes) == 0:
        empty = np.zeros(0)
        return Consensus(nodes=nodes, estimate=np.zeros((0, 2)), spread=empty,
                         violations=empty.copy())
    beacon_raster = visibility_raster(episode, cell, band=band)
    seq_of = np.full(episode.log.n_nodes, -1, dtype=np.int64)
    seq_of[nodes] = np.arange(len(nodes))
    rec = episode.log.receptions
    heard = _lists(seq_of[rec[:, 1]], rec[:, 0], len(nodes))
    n_heard = (heard >= 0).sum(axis=1)
    if len(nodes) and n_heard.min() == 0:
        raise ValueError(f"node {nodes[np.argmin(n_heard)]} heard no beacon")
    reach = episode.log.radio_range * (1 + episode.config.doi) + beacon_raster.cell / np.sqrt(2)
    # the fallback of a node whose discs do not overlap: its heard beacons' centroid, on the
    # field (beacons a log places just off it put it off the field too)
    result = Consensus(nodes=nodes, estimate=np.clip(episode.heard_centroid[nodes], 0.0,
                                                     np.asarray(episode.field, dtype=float)),
                       spread=np.full(len(nodes), np.nan), violations=np.full(len(nodes), np.nan))
    fields = (result.estimate, result.spread, result.violations)
    every = np.arange(len(nodes))
    kept = _solve([_Part(beacon_raster, episode.beacon_xy, heard, None)], reach, fields, every)
    links = seq_of[episode.log.node_links]
    links = np.concatenate([links, links[:, ::-1]])
    links = links[np.all(links >= 0, axis=1)]
    for _ in range(NEIGHBOUR_ROUNDS):
        reliable = result.spread <= RELIABLE_SPREAD  # NaN: not reliable
        if not reliable.any():
            return result
        # reliable nodes become transmitters at their estimates of the stage before
        anchor_of = np.full(len(nodes), -1, dtype=np.int64)
        anchor_of[reliable] = np.arange(int(reliable.sum()))
        points = result.estimate[reliable]
        node_raster = visibility_raster(episode, cell, points=points)
        neighbours = _lists(links[:, 0], anchor_of[links[:, 1]], len(nodes))
        _solve([_Part(beacon_raster, episode.beacon_xy, heard, None),
                _Part(node_raster, points, neighbours, anchor_of)], reach, fields, every, kept)
    return result


def consensus(episode: Episode, *, cell: float = DEFAULT_CELL) -> np.ndarray:
    """Visibility-consensus estimates (N, 2) [m]; NaN for nodes not covered under Eq. 18."""
    out = np.full((episode.log.n_nodes, 2), np.nan)
    nodes = np.flatnonzero(episode.covered)
    if len(nodes):
        out[nodes] = node_consensus(episode, nodes, cell=cell).estimate
    return out
