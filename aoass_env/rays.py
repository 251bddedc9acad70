"""The range sensor's rays, cast in one compiled call with Chipmunk2D's own arithmetic.

A ray reads the distance (m) to the first static part, wall or moving disc along a segment of
``sensing_range`` from the anchor's centre: pymunk's ``cpSpaceSegmentQueryFirst`` with radius
0, one C call per ray. :func:`cast_rays` replays that query's arithmetic for all the rays at
once, on the shapes Chipmunk holds (the polygons' vertices read back from Chipmunk, in its
order, after its convex hull), operation for operation, as Munk2D 2.0 (pymunk 7) computes it:

* a shape whose point query finds the ray's start on or inside it is hit at ``alpha = 0``
  (``cpShapeSegmentQuery``);
* a polygon is hit at the ``t`` of the last of its planes that the segment enters within the
  plane's edge (``cpPolyShapeSegmentQuery``; its planes' normals are ``cpvnormalize`` of the
  edges' right perpendiculars, ``SetVerts``);
* a disc is hit at the smaller root of its quadratic (``CircleSegmentQuery``);
* a polygon is tested only when the segment meets its bounding box (``cpBBSegmentQuery``), as
  Chipmunk's tree visits only those (unless the polygon is the only static shape: the tree's
  root is then its leaf, visited untested), and the ray reads the least ``alpha`` below 1 of
  all the shapes it hits (``SegmentQueryFirst``), times its reach, or its reach where none is.

The one place the two could part: Chipmunk's tree also skips a box that starts farther along
the ray than the best hit so far, so where two shapes are hit within a few units in the last
place of one another, at a point where their boundaries meet, the box's float ``t`` could hide
the nearer one. Such rays read the same distance to within those units.

Whether the compiled floats are the installed Chipmunk's (the C library's compiler may contract
or reorder them, and other versions compute otherwise) is checked once per process by
:func:`compiled_rays` on a probe scene, and the world casts its rays this way only when they
are, bit for bit (:class:`~aoass_env.world.World`).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable

import numpy as np
import pymunk

from aoass_env.jit import njit
from aoass_env.trig import compiled_trig

__all__ = ["StaticShapes", "cast_rays", "chipmunk_rays", "compiled_rays"]

#: Chipmunk's CPFLOAT_MIN (DBL_MIN), the guard of its ``cpvnormalize``.
_DBL_MIN = np.finfo(np.float64).tiny


class StaticShapes:
    """Chipmunk's convex polygons as flat arrays for :func:`cast_rays`.

    Args:
        polygons: each polygon's vertices (m) as Chipmunk holds them (``Poly.get_vertices()``
            of a shape on the static body: its convex hull, in Chipmunk's order).

    Attributes:
        vertices: (V, 2) all vertices (m); polygon i's are rows ``first[i]:first[i + 1]``.
        normals: (V, 2) the unit normal of the plane at each vertex, as ``SetVerts`` computes
            it: of the edge from the previous vertex to this one.
        first: (P + 1,) the polygons' row ranges.
        boxes: (P, 4) each polygon's bounding box (left, bottom, right, top; m).
    """

    def __init__(self, polygons: Iterable[np.ndarray]) -> None:
        polygons = [np.asarray(p, dtype=np.float64).reshape(-1, 2) for p in polygons]
        sizes = np.array([len(p) for p in polygons], dtype=np.int64)
        if not sizes.all():
            raise ValueError("every polygon needs at least one vertex")
        self.first = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        self.vertices = np.concatenate(polygons) if polygons else np.zeros((0, 2))
        self.normals = _plane_normals(self.vertices, self.first)
        self.boxes = np.zeros((len(polygons), 4))
        if polygons:
            self.boxes[:, :2] = np.minimum.reduceat(self.vertices, self.first[:-1])
            self.boxes[:, 2:] = np.maximum.reduceat(self.vertices, self.first[:-1])

    @classmethod
    def of(cls, shapes: Iterable[pymunk.Poly]) -> StaticShapes:
        """The shapes (pymunk polygons on a static body at the origin, unrotated, radius 0)."""
        return cls([np.array([tuple(v) for v in shape.get_vertices()]) for shape in shapes])


@njit(error_model="numpy")
def _plane_normals(vertices: np.ndarray, first: np.ndarray) -> np.ndarray:
    """Each plane's normal as ``SetVerts`` computes it: ``cpvnormalize(cpvrperp(b - a))`` for
    the edge a -> b ending at the plane's vertex (``cpvnormalize(v) = v (1 / (|v| +
    DBL_MIN))``)."""
    out = np.empty_like(vertices)
    for p in range(len(first) - 1):
        lo, hi = first[p], first[p + 1]
        count = hi - lo
        for i in range(count):
            a = lo + (i - 1 + count) % count
            b = lo + i
            vx = vertices[b, 1] - vertices[a, 1]           # cpvrperp(cpvsub(b, a))
            vy = -(vertices[b, 0] - vertices[a, 0])
            s = 1.0 / (math.sqrt(vx * vx + vy * vy) + _DBL_MIN)
            out[b, 0] = vx * s
            out[b, 1] = vy * s
    return out


@njit(inline="always", error_model="numpy")
def _fmin(a: float, b: float) -> float:
    return a if a < b else b               # cpfmin


@njit(inline="always", error_model="numpy")
def _fmax(a: float, b: float) -> float:
    return a if a > b else b               # cpfmax


@njit(inline="always", error_model="numpy")
def _slab(lo: float, hi: float, a: float, d: float, tmin: float,
          tmax: float) -> tuple[bool, float, float]:
    """One axis of ``cpBBSegmentQuery``: the box's slab [lo, hi] against the segment's start
    coordinate ``a`` and extent ``d``; (missed, tmin, tmax)."""
    if d == 0.0:
        return a < lo or hi < a, tmin, tmax
    t1 = (lo - a) / d
    t2 = (hi - a) / d
    return False, _fmax(tmin, _fmin(t1, t2)), _fmin(tmax, _fmax(t1, t2))


@njit(error_model="numpy")
def _box_t(left: float, bottom: float, right: float, top: float, ax: float, ay: float,
           bx: float, by: float) -> float:
    """``cpBBSegmentQuery``: where (0 to 1) the segment a -> b enters the box, inf if never."""
    missed, tmin, tmax = _slab(left, right, ax, bx - ax, -math.inf, math.inf)
    if missed:
        return math.inf
    missed, tmin, tmax = _slab(bottom, top, ay, by - ay, tmin, tmax)
    if missed:
        return math.inf
    if tmin <= tmax and 0.0 <= tmax and tmin <= 1.0:
        return _fmax(tmin, 0.0)
    return math.inf


@njit(error_model="numpy")
def _polygon_holds(px: float, py: float, vertices: np.ndarray, normals: np.ndarray, lo: int,
                   hi: int) -> bool:
    """``cpPolyShapePointQuery``'s distance <= 0 (radius 0): (px, py) inside or on the
    polygon."""
    count = hi - lo
    v0x, v0y = vertices[hi - 1, 0], vertices[hi - 1, 1]
    min_dist = math.inf
    outside = False
    for i in range(lo, lo + count):
        v1x, v1y = vertices[i, 0], vertices[i, 1]
        outside = outside or (normals[i, 0] * (px - v1x) + normals[i, 1] * (py - v1y) > 0.0)
        # cpClosetPointOnSegment(p, v0, v1)
        dx, dy = v0x - v1x, v0y - v1y
        t = (dx * (px - v1x) + dy * (py - v1y)) / (dx * dx + dy * dy)
        t = _fmax(0.0, _fmin(t, 1.0))                  # cpfclamp01
        cx, cy = v1x + dx * t, v1y + dy * t
        ex, ey = px - cx, py - cy
        dist = math.sqrt(ex * ex + ey * ey)
        if dist < min_dist:
            min_dist = dist
        v0x, v0y = v1x, v1y
    dist = min_dist if outside else -min_dist
    return dist - 0.0 <= 0.0


@njit(error_model="numpy")
def _polygon_alpha(ax: float, ay: float, bx: float, by: float, vertices: np.ndarray,
                   normals: np.ndarray, lo: int, hi: int) -> float:
    """``cpPolyShapeSegmentQuery`` (radius 0): the ``t`` of the last plane the segment a -> b
    enters within its edge, or 2.0 when none."""
    count = hi - lo
    alpha = 2.0
    for i in range(count):
        k = lo + i
        nx, ny = normals[k, 0], normals[k, 1]
        an = ax * nx + ay * ny
        d = an - (vertices[k, 0] * nx + vertices[k, 1] * ny) - 0.0
        if d < 0.0:
            continue
        bn = bx * nx + by * ny
        if an - bn < 10e-6 and an - bn > -10e-6:
            continue
        t = d / (an - bn)
        if t < 0.0 or 1.0 < t:
            continue
        u = 1.0 - t
        px, py = ax * u + bx * t, ay * u + by * t      # cpvlerp(a, b, t)
        dt = nx * py - ny * px
        j = lo + (i - 1 + count) % count
        dt_min = nx * vertices[j, 1] - ny * vertices[j, 0]
        dt_max = nx * vertices[k, 1] - ny * vertices[k, 0]
        if dt_min <= dt and dt <= dt_max:
            alpha = t
    return alpha


@njit(error_model="numpy")
def _disc_alpha(ax: float, ay: float, bx: float, by: float, cx: float, cy: float,
                r: float) -> float:
    """``cpShapeSegmentQuery`` of a circle (radius 0): 0 when a is on or inside it, else
    ``CircleSegmentQuery``'s ``t``; 2.0 when there is no hit."""
    dax, day = ax - cx, ay - cy
    if math.sqrt(dax * dax + day * day) - r <= 0.0:
        return 0.0
    dbx, dby = bx - cx, by - cy
    rsum = r + 0.0
    aa = dax * dax + day * day
    ab = dax * dbx + day * dby
    qa = aa - 2.0 * ab + (dbx * dbx + dby * dby)
    qb = ab - aa
    det = qb * qb - qa * (aa - rsum * rsum)
    if det >= 0.0:
        t = (-qb - math.sqrt(det)) / qa
        if 0.0 <= t and t <= 1.0:
            return t
    return 2.0


@njit(error_model="numpy")
def cast_rays(x: float, y: float, heading: float, offsets: np.ndarray, reach: float,
              vertices: np.ndarray, normals: np.ndarray, first: np.ndarray, boxes: np.ndarray,
              discs: np.ndarray, disc_radius: float) -> np.ndarray:
    """(n,) the distances (m) the rays from (x, y) (m) read, as ``cpSpaceSegmentQueryFirst``
    (module docstring): ray i runs to ``(x + reach cos(a), y + reach sin(a))``, ``a = heading
    + offsets[i]`` (rad), among the polygons of ``vertices`` / ``normals`` / ``first`` /
    ``boxes`` (:class:`StaticShapes`) and the discs of radius ``disc_radius`` (m) centred at
    the rows of ``discs`` (D, 2); ``reach`` where a ray hits nothing."""
    # the polygons whose box comes within reach of (x, y): the only ones a ray can meet
    near = np.empty(len(boxes), dtype=np.int64)
    count = 0
    slack = reach + 1e-6
    for p in range(len(boxes)):
        if (boxes[p, 0] <= x + slack and boxes[p, 2] >= x - slack
                and boxes[p, 1] <= y + slack and boxes[p, 3] >= y - slack):
            near[count] = p
            count += 1
    # the tree tests a leaf's box before visiting it, unless the leaf is its root (one shape)
    tested = len(boxes) > 1
    holds = np.empty(count, dtype=np.bool_)       # the point query at the rays' start
    for q in range(count):
        p = near[q]
        holds[q] = _polygon_holds(x, y, vertices, normals, first[p], first[p + 1])
    out = np.empty(len(offsets))
    for i in range(len(offsets)):
        a = heading + offsets[i]
        ex = x + reach * math.cos(a)
        ey = y + reach * math.sin(a)
        best = 1.0
        for q in range(count):
            p = near[q]
            if tested and not _box_t(boxes[p, 0], boxes[p, 1], boxes[p, 2], boxes[p, 3], x,
                                     y, ex, ey) < 1.0:
                continue
            alpha = 0.0 if holds[q] else _polygon_alpha(x, y, ex, ey, vertices, normals,
                                                         first[p], first[p + 1])
            if alpha < best:
                best = alpha
        for d in range(len(discs)):
            alpha = _disc_alpha(x, y, ex, ey, discs[d, 0], discs[d, 1], disc_radius)
            if alpha < best:
                best = alpha
        out[i] = best * reach if best < 1.0 else reach
    return out


def _probe_space(rng: np.random.Generator) -> tuple[pymunk.Space, StaticShapes, np.ndarray,
                                                    float]:
    """A probe scene: random convex polygons (some touching, some sharing vertices), a box
    room, and discs on kinematic bodies; its shapes as :func:`cast_rays` reads them."""
    space = pymunk.Space()
    polygons = []
    for _ in range(40):
        centre = rng.uniform(2.0, 38.0, 2)
        k = int(rng.integers(3, 9))
        points = centre + rng.uniform(0.3, 3.0, (k, 1)) * np.column_stack(
            [np.cos(angles := rng.uniform(0.0, 2.0 * math.pi, k)), np.sin(angles)])
        polygons.append(np.round(points, 3) if rng.random() < 0.5 else points)
    polygons += [np.array([(-40.0, -40.0), (80.0, -40.0), (80.0, 0.0), (-40.0, 0.0)]),
                 np.array([(0.0, 40.0), (40.0, 40.0), (40.0, 80.0), (0.0, 80.0)])]
    shapes = []
    for points in polygons:
        shape = pymunk.Poly(space.static_body, [tuple(v) for v in points.tolist()])
        space.add(shape)
        shapes.append(shape)
    discs = rng.uniform(3.0, 37.0, (3, 2))
    radius = 0.5
    for cx, cy in discs.tolist():
        body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        body.position = (cx, cy)
        space.add(body, pymunk.Circle(body, radius))
    space.step(0.01)            # the kinematic discs' shapes cache their centres (velocity 0)
    return space, StaticShapes.of(shapes), discs, radius


@functools.cache
def compiled_rays() -> bool:
    """Whether :func:`cast_rays` gives the installed Chipmunk's distances bit for bit on a
    probe scene (:func:`_probe_space`: 4 000 random rays and rays through every vertex; rays
    from inside shapes), with compiled trigonometry that is ``math``'s (:func:`~aoass_env.trig.
    compiled_trig`); once per process."""
    if not compiled_trig():
        return False
    rng = np.random.default_rng(2026)
    space, shapes, discs, radius = _probe_space(rng)
    starts = np.concatenate([rng.uniform(-1.0, 41.0, (250, 2)), shapes.vertices])
    headings = rng.uniform(-math.pi, math.pi, len(starts))
    offsets = 2.0 * math.pi * np.arange(16) / 16
    for reach, (x, y), heading in zip(rng.uniform(0.5, 12.0, len(starts)), starts.tolist(),
                                      headings.tolist(), strict=True):
        got = cast_rays(x, y, heading, offsets, reach, shapes.vertices, shapes.normals,
                        shapes.first, shapes.boxes, discs, radius)
        if not np.array_equal(got, chipmunk_rays(space, x, y, heading, offsets, reach)):
            return False
    return True


def chipmunk_rays(space: pymunk.Space, x: float, y: float, heading: float,
                  offsets: np.ndarray, reach: float,
                  shape_filter: pymunk.ShapeFilter | None = None) -> np.ndarray:
    """The reference: each ray of :func:`cast_rays` through ``space.segment_query_first``
    (every shape, or those ``shape_filter`` passes)."""
    shape_filter = pymunk.ShapeFilter() if shape_filter is None else shape_filter
    out = []
    for offset in offsets.tolist():
        a = heading + offset
        end = (x + reach * math.cos(a), y + reach * math.sin(a))
        hit = space.segment_query_first((x, y), end, 0.0, shape_filter)
        out.append(hit.alpha * reach if hit is not None else reach)
    return np.array(out)
