"""Exact tests of segments against a set of edges, on a grid of buckets (compiled with numba).

A segment *crosses* an edge when each properly separates the other's end points; it is *clear*
of a set of edges when it is certainly disjoint from every one of them. Each (segment, edge)
pair is settled by four orientation determinants with Shewchuk's static error bound: a sign the
bound certifies is exact, so a crossing or a disjoint pair found so is exact too. What the bound
cannot certify (a vertex on the segment, collinear overlap, an end point on an edge, a sign too
close to zero) is a *contact*, left by the caller to :func:`meets_interior`, exact in rational
arithmetic (GEOS is not: it rounds the points where a segment crosses an edge, and calls a
segment that passes 1e-17 m inside a vertex a touch).

:class:`EdgeGrid` buckets the edges once on a grid of :data:`GRID_CELL` cells: each edge in
every bucket its bounding box, :data:`GRID_SLACK` wider, overlaps. A segment's candidate edges
are those of the buckets under each grid row's stretch of it, also :data:`GRID_SLACK` wider.
An edge that meets the segment shares a point with it, and that point lies in one of those
buckets, so no edge the segment meets is missed; the other candidates are settled as disjoint
(or, rarely, reported as a contact), so the answer does not depend on which extra edges a
bucket holds. Used by the radio's line of sight (:mod:`aoass_env.radio`) and the detour
planner's straight-line test (:mod:`aoass_env.planning.detour`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from fractions import Fraction

import numpy as np

from aoass_env.jit import njit

__all__ = ["CLEAR", "CONTACT", "CROSSES", "GRID_CELL", "GRID_SLACK", "MAX_BUCKETS", "EdgeGrid",
           "meets_interior", "segment_status", "statuses"]

#: A polygon's rings (exterior, then holes) as closed lists of exact vertices [m].
Rings = Sequence[Sequence[tuple[Fraction, Fraction]]]

_UNIT_ROUNDOFF = np.finfo(np.float64).eps / 2
#: Shewchuk's static error bound for the 2D orientation determinant (ccwerrboundA): when
#: |det| exceeds this times (|detleft| + |detright|), the sign of the float determinant is exact.
_ORIENT_ERRBOUND = (3.0 + 16.0 * _UNIT_ROUNDOFF) * _UNIT_ROUNDOFF

#: Side (m) of the grid's buckets.
GRID_CELL = 4.0
#: The most buckets a grid may have (its counts take 8 bytes each): a 16 km square field.
MAX_BUCKETS = 1 << 24
#: Slack (m) of the grid: an edge is bucketed, and a segment looks, this far past its extent,
#: so that rounding at a bucket's border never hides an edge that meets a segment.
GRID_SLACK = 1e-6

#: What :func:`segment_status` says of a segment: clear of every edge, a proper crossing of
#: one, or a contact only an exact test settles.
CLEAR, CROSSES, CONTACT = 0, 1, 2


@njit
def _orientation(dax: float, day: float, dbx: float, dby: float) -> tuple[bool, bool]:
    """Sign-certain orientation of (a, b, c) from the differences a - c and b - c.

    Returns ``(positive, certain)``: ``det > 0`` and whether that sign (and non-zeroness) is
    exact under Shewchuk's error bound. An exactly zero determinant is never certain.
    """
    left = dax * dby
    right = day * dbx
    det = left - right
    return det > 0, abs(det) > _ORIENT_ERRBOUND * (abs(left) + abs(right))


@njit
def _clamped(v: float, n: int) -> int:
    """floor(v) clamped to [0, n - 1], clamped as a float first: a coordinate beyond 2**63
    buckets (|v| > 3.7e19 m) would wrap around in the integer conversion."""
    return int(min(max(np.floor(v), 0.0), n - 1.0))


@njit
def segment_status(sx: float, sy: float, ex: float, ey: float, px: np.ndarray,
                   py: np.ndarray, qx: np.ndarray, qy: np.ndarray, x0: float, y0: float,
                   cell: float, nx: int, ny: int, first: np.ndarray, members: np.ndarray,
                   seen: np.ndarray, tag: int) -> int:
    """:data:`CLEAR`, :data:`CROSSES` or :data:`CONTACT` of the segment (sx, sy) -> (ex, ey)
    (m) against the edges ``p[e] -> q[e]`` its buckets of the edge grid hold (``nx`` x ``ny``
    buckets of side ``cell`` from ``(x0, y0)``; bucket ``j nx + i`` holds
    ``members[first[k]:first[k + 1]]``) by the orientation test with Shewchuk's error bound
    (:func:`_orientation`). The buckets are those of each grid row's stretch of the segment,
    :data:`GRID_SLACK` wider. With ``tag >= 0`` each edge is tested once (``seen[e] == tag``
    once tested, ``seen`` one mark per edge); with ``tag < 0`` (``seen`` unread) an edge in
    several of the buckets is tested again, to the same answer."""
    ylo, yhi = min(sy, ey), max(sy, ey)
    j0 = _clamped((ylo - GRID_SLACK - y0) / cell, ny)
    j1 = _clamped((yhi + GRID_SLACK - y0) / cell, ny)
    status = CLEAR
    for j in range(j0, j1 + 1):
        lo = max(ylo, y0 + j * cell - GRID_SLACK)
        hi = min(yhi, y0 + (j + 1) * cell + GRID_SLACK)
        if lo > hi:
            continue
        if sy == ey:
            xa, xb = sx, ex
        else:
            xa = sx + (lo - sy) / (ey - sy) * (ex - sx)
            xb = sx + (hi - sy) / (ey - sy) * (ex - sx)
        i0 = _clamped((min(xa, xb) - GRID_SLACK - x0) / cell, nx)
        i1 = _clamped((max(xa, xb) + GRID_SLACK - x0) / cell, nx)
        for i in range(i0, i1 + 1):
            bucket = j * nx + i
            for slot in range(first[bucket], first[bucket + 1]):
                e = members[slot]
                if tag >= 0:
                    if seen[e] == tag:
                        continue
                    seen[e] = tag
                apx, apy, aqx, aqy = sx - px[e], sy - py[e], sx - qx[e], sy - qy[e]
                bpx, bpy, bqx, bqy = ex - px[e], ey - py[e], ex - qx[e], ey - qy[e]
                s1, c1 = _orientation(apx, apy, bpx, bpy)    # p against line a-b
                s2, c2 = _orientation(aqx, aqy, bqx, bqy)    # q against line a-b
                s3, c3 = _orientation(apx, apy, aqx, aqy)    # a against line p-q
                s4, c4 = _orientation(bpx, bpy, bqx, bqy)    # b against line p-q
                if c1 and c2 and c3 and c4 and s1 != s2 and s3 != s4:
                    return CROSSES
                if not ((c1 and c2 and s1 == s2) or (c3 and c4 and s3 == s4)):
                    status = CONTACT
    return status


@njit
def statuses(ax: np.ndarray, ay: np.ndarray, bx: np.ndarray, by: np.ndarray, px: np.ndarray,
           py: np.ndarray, qx: np.ndarray, qy: np.ndarray, x0: float, y0: float, cell: float,
           nx: int, ny: int, first: np.ndarray, members: np.ndarray) -> np.ndarray:
    """(M,) int8 :func:`segment_status` of each segment ``a[m] -> b[m]`` (m)."""
    out = np.empty(len(ax), dtype=np.int8)
    seen = np.full(len(px), -1, dtype=np.int64)
    for k in range(len(ax)):
        out[k] = segment_status(ax[k], ay[k], bx[k], by[k], px, py, qx, qy, x0, y0, cell, nx,
                                ny, first, members, seen, k)
    return out


@njit
def _bucket(i0: np.ndarray, i1: np.ndarray, j0: np.ndarray, j1: np.ndarray,
            nx: int, ny: int) -> tuple[np.ndarray, np.ndarray]:
    """(first, members): edge e in every bucket (i, j) with i0[e] <= i <= i1[e] and
    j0[e] <= j <= j1[e], in CSR form, each bucket's edges in increasing order."""
    count = np.zeros(nx * ny + 1, dtype=np.int64)
    for e in range(len(i0)):
        for j in range(j0[e], j1[e] + 1):
            for i in range(i0[e], i1[e] + 1):
                count[j * nx + i + 1] += 1
    first = np.cumsum(count)
    fill = first[:-1].copy()
    members = np.empty(first[-1], dtype=np.int64)
    for e in range(len(i0)):
        for j in range(j0[e], j1[e] + 1):
            for i in range(i0[e], i1[e] + 1):
                members[fill[j * nx + i]] = e
                fill[j * nx + i] += 1
    return first, members


def _grid(edges: np.ndarray) -> tuple[float, float, float, int, int, np.ndarray, np.ndarray]:
    """(x0, y0, cell, nx, ny, first, members): the edges (E, 2, 2) bucketed by the cells of
    side :data:`GRID_CELL` their bounding box, :data:`GRID_SLACK` wider, overlaps (CSR:
    bucket ``j nx + i`` holds ``members[first[k]:first[k + 1]]``)."""
    cell = GRID_CELL
    if not len(edges):
        return 0.0, 0.0, cell, 1, 1, np.zeros(2, dtype=np.int64), np.zeros(0, dtype=np.int64)
    lo = edges.min(axis=1) - GRID_SLACK               # (E, 2) each edge's box
    hi = edges.max(axis=1) + GRID_SLACK
    x0, y0 = float(lo[:, 0].min()), float(lo[:, 1].min())
    span = (hi.max(axis=0) - (x0, y0)) / cell
    if span[0] * span[1] > MAX_BUCKETS:
        raise ValueError(f"the edges span {span[0] * cell:.3g} x {span[1] * cell:.3g} m: more "
                         f"than MAX_BUCKETS={MAX_BUCKETS} buckets of {cell:g} m")
    nx = int(math.floor((hi[:, 0].max() - x0) / cell)) + 1
    ny = int(math.floor((hi[:, 1].max() - y0) / cell)) + 1
    i0 = np.floor((lo[:, 0] - x0) / cell).astype(np.int64)
    i1 = np.minimum(np.floor((hi[:, 0] - x0) / cell).astype(np.int64), nx - 1)
    j0 = np.floor((lo[:, 1] - y0) / cell).astype(np.int64)
    j1 = np.minimum(np.floor((hi[:, 1] - y0) / cell).astype(np.int64), ny - 1)
    return (x0, y0, cell, nx, ny, *_bucket(i0, i1, j0, j1, nx, ny))


#: ``seen`` of one-segment queries, which test an edge in several buckets again: nothing
#: mutable is shared, so threads may query one grid at once.
_NO_MARKS = np.zeros(0, dtype=np.int64)


class EdgeGrid:
    """Edges bucketed for :func:`segment_status` (module docstring).

    Args:
        edges: (E, 2, 2) float64 (start, end) points (m).

    Attributes:
        args: the edges and the grid as :func:`segment_status` and :func:`statuses` take them
            after the segment: ``(px, py, qx, qy, x0, y0, cell, nx, ny, first, members)``.
    """

    def __init__(self, edges: np.ndarray) -> None:
        edges = np.asarray(edges, dtype=np.float64).reshape(-1, 2, 2)
        self.args = (edges[:, 0, 0].copy(), edges[:, 0, 1].copy(), edges[:, 1, 0].copy(),
                     edges[:, 1, 1].copy(), *_grid(edges))

    def statuses(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """(M,) int8 :func:`segment_status` of the segments ``a[m] -> b[m]`` ((M, 2) each, m)."""
        return statuses(np.ascontiguousarray(a[:, 0]), np.ascontiguousarray(a[:, 1]),
                        np.ascontiguousarray(b[:, 0]), np.ascontiguousarray(b[:, 1]), *self.args)

    def status(self, ax: float, ay: float, bx: float, by: float) -> int:
        """:func:`segment_status` of the one segment (ax, ay) -> (bx, by) (m)."""
        return segment_status(ax, ay, bx, by, *self.args, _NO_MARKS, -1)


def _rational_side(rings: Rings, x: Fraction, y: Fraction) -> int:
    """1 when (x, y) lies strictly inside the polygon of ``rings``, 0 on its boundary, -1
    outside: the even-odd rule on exact rationals (a crossing to the right of the point is
    told by the sign of a cross product, without a division)."""
    inside = False
    for ring in rings:
        for (x1, y1), (x2, y2) in itertools.pairwise(ring):
            cross = (x2 - x1) * (y - y1) - (y2 - y1) * (x - x1)
            if cross == 0 and min(x1, x2) <= x <= max(x1, x2) and min(y1, y2) <= y <= max(y1, y2):
                return 0
            if (y1 > y) != (y2 > y) and (cross > 0) == (y2 > y1):
                inside = not inside
    return 1 if inside else -1


def meets_interior(start: Sequence[float], end: Sequence[float], rings: Rings) -> bool:
    """Whether the open segment ``start -> end`` [m] (a point when they are equal) meets the
    interior of the polygon of ``rings`` (closed vertex lists of Fractions: exterior, then
    holes), exactly: the segment is cut where it meets the boundary (crossings, and the ends of
    collinear overlaps); each piece between two cuts lies wholly inside or outside, so its
    midpoint decides. Slow (Python rationals): for the rare contacts of :func:`statuses`."""
    sx, sy = Fraction(start[0]), Fraction(start[1])
    dx, dy = Fraction(end[0]) - sx, Fraction(end[1]) - sy
    if dx == 0 and dy == 0:
        return _rational_side(rings, sx, sy) == 1
    norm = dx * dx + dy * dy
    cuts = {Fraction(0), Fraction(1)}
    for ring in rings:
        for (px, py), (qx, qy) in itertools.pairwise(ring):
            ex, ey, wx, wy = qx - px, qy - py, px - sx, py - sy
            den = dx * ey - dy * ex
            if den != 0:
                if 0 <= (wx * dy - wy * dx) / den <= 1:   # where along the edge
                    cuts.add((wx * ey - wy * ex) / den)   # where along the segment
            elif wx * dy == wy * dx:                      # collinear: the edge's ends
                cuts.add((wx * dx + wy * dy) / norm)
                cuts.add(((qx - sx) * dx + (qy - sy) * dy) / norm)
    ts = sorted(t for t in cuts if 0 <= t <= 1)
    return any(_rational_side(rings, sx + (t0 + t1) / 2 * dx, sy + (t0 + t1) / 2 * dy) == 1
               for t0, t1 in itertools.pairwise(ts))
