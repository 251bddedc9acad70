"""Executing a holonomic ORCA velocity on the anchor's unicycle.

ORCA (:mod:`aoass_env.safety.orca`) returns a velocity ``v*`` as if the anchor could take any
velocity at once. The anchor cannot: it moves along its heading, turns at most
``max_turn`` (rad) per control period and changes speed at a bounded rate. The anchor is
commanded ``v*``'s heading, and a speed no larger than the largest speed that keeps *every
heading it passes through while turning* inside the ORCA half-planes that zero velocity
satisfies, and that does not deepen a half-plane zero velocity violates (an obstacle closing in
on a standing anchor): the anchor slows down, or turns in place, while it faces the wrong way.
It also cannot stop at once (its deceleration is bounded), so it turns toward ``v*`` only as
far as the headings stay safe at the speed it still has.

ORCA's static half-planes assume the velocity changes at once; the anchor's lags behind, and
passing an obstacle's corner turns its sideways speed into speed toward the corner faster than
it can brake. A :class:`BrakingEnvelope` closes that gap: on each heading the speed is also
capped so that the anchor, moving one control period at it and then braking at its
deceleration limit, stops before its disc (radius plus a margin) reaches a static edge
(:func:`free_travel` along the heading, :func:`braking_speed`).

Convention (RVO2's): a velocity ``v`` satisfies the line (point ``p``, unit direction ``d``)
when ``det(d, p - v) <= 0``, i.e. ``v`` lies to the left of the directed line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from aoass_env.jit import njit
from aoass_env.safety.checks import all_finite, finite
from aoass_env.trig import SCALAR_TRIG, compiled_polar, compiled_trig, hypot
from aoass_env.validators import finite_array, positive, real, vec2

# the steps of a command (braking_speed, clearance, free_travel, speed_bounds, turn_headings)
# read what unicycle_command and BrakingEnvelope have checked: not part of the API
__all__ = ["BrakingEnvelope", "unicycle_command"]

#: Below this speed (m/s) ORCA's velocity has no usable direction.
_STILL = 1e-9
#: How far (m/s) a velocity may lie past a satisfied ORCA line: half the 2-D LP's round-off
#: slack (1e-9 m/s, :mod:`aoass_env.safety.orca`), within which ORCA's v* lies on its lines.
_LINE_SLACK = 5e-10
#: A heading whose approach rate to a segment's side is below this (m per m) runs parallel.
_PARALLEL = 1e-12
#: An anchor inside the envelope's radius keeps its clearance less this much (m): the slack
#: lets a heading within a hair of parallel to the nearest edge (ORCA's slide along it) move on.
_HELD = 1e-3
#: A target heading within this (rad) of the opposite of the current one is ambiguous: the
#: drive and :func:`turn_headings` may round it to opposite turns.
_OPPOSITE = 1e-3


def turn_headings(heading: float, target: float, max_turn: float, n: int = 4) -> np.ndarray:
    """(n + 1,) headings (rad) the anchor passes through when it turns from ``heading`` toward
    ``target`` the shorter way round by at most ``max_turn`` (rad), evenly spaced."""
    turn = math.remainder(target - heading, 2.0 * math.pi)
    turn = min(max(turn, -max_turn), max_turn)
    return heading + turn * np.linspace(0.0, 1.0, n + 1)


def speed_bounds(points: np.ndarray, directions: np.ndarray,
                 headings: np.ndarray) -> np.ndarray:
    """(k,) for each heading h (rad) the largest speed s >= 0 (m/s; inf when unbounded) such
    that s (cos h, sin h) satisfies every line that zero velocity satisfies (to within half the
    LP's round-off slack, 5e-10 m/s) and deepens no line that zero velocity violates.

    Args:
        points, directions: (n, 2) the ORCA lines (velocity space, m/s; unit directions).
        headings: (k,) headings (rad).
    """
    headings = np.asarray(headings, dtype=np.float64)
    if len(points) == 0:
        return np.full(len(headings), np.inf)
    # c = det(d, p): zero velocity satisfies the line when c <= 0; moving at speed s along h
    # changes det(d, p - v) by -s det(d, h)
    c = directions[:, 0] * points[:, 1] - directions[:, 1] * points[:, 0]
    h = np.stack([np.cos(headings), np.sin(headings)], axis=1)                     # (k, 2)
    along = (directions[:, 0][:, None] * h[None, :, 1]
             - directions[:, 1][:, None] * h[None, :, 0])                          # det(d, h)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        # a satisfied line may be met within ORCA's own round-off slack (v* lies on a line
        # through the origin to within it): a heading along such a line is not held to 0
        bound = np.where(along < 0.0,
                         np.where(c[:, None] <= 0.0, (c[:, None] - _LINE_SLACK) / along, 0.0),
                         np.inf)
    return np.maximum(bound.min(axis=0), 0.0)


def free_travel(starts: np.ndarray, ends: np.ndarray, position: np.ndarray,
                headings: np.ndarray, radius: float) -> np.ndarray:
    """(k,) for each heading h (rad) how far (m) a disc of ``radius`` (m) at ``position`` (2,)
    moves along h before it touches one of the segments ``starts`` -> ``ends`` ((m, 2) each,
    m); inf when it touches none. A disc that touches a segment already gets 0 on the headings
    that take it closer, and is free on the others."""
    headings = np.asarray(headings, dtype=np.float64)
    if len(starts) == 0:
        return np.full(len(headings), np.inf)
    return _travel_compiled(*_products(starts, ends, position, headings), radius * radius,
                            radius)


def _products(starts: np.ndarray, ends: np.ndarray, position: np.ndarray,
              headings: np.ndarray) -> tuple[np.ndarray, ...]:
    """:func:`free_travel`'s arrays and its matrix products, in NumPy: BLAS computes the
    products with fused multiply-adds, in an order that depends on the shapes and the CPU,
    which compiled loops cannot reproduce; the rest is element by element
    (:func:`_travel_compiled`)."""
    u = np.stack([np.cos(headings), np.sin(headings)], axis=1)            # (k, 2)
    p = np.asarray(position, dtype=np.float64)
    w_start, w_end = p - starts, p - ends                                  # (m, 2)
    e = ends - starts
    length = np.hypot(e[:, 0], e[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):   # a zero-length edge: no normal
        n = np.stack([-e[:, 1], e[:, 0]], axis=1) / length[:, None]        # (m, 2) unit normals
    return (w_start, u @ w_start.T, w_end, u @ w_end.T, e, length, n, u @ n.T, u @ e.T)


@njit(error_model="numpy")
def _travel_compiled(w_start: np.ndarray, wu_start: np.ndarray, w_end: np.ndarray,
                     wu_end: np.ndarray, e: np.ndarray, length: np.ndarray, n: np.ndarray,
                     rate: np.ndarray, ue: np.ndarray, r2: float, radius: float) -> np.ndarray:
    """:func:`free_travel` from its arrays and products (:func:`_products`, ``r2`` = radius
    squared), element by element with the array code's operations in its order (the array
    code is the tests' oracle)."""
    k, m = wu_start.shape
    best = np.full(k, math.inf)
    for i in range(k):
        b = math.inf
        for j in range(m):
            # the end points: |w + t u| = radius with w = p - vertex, entered while w . u < 0
            for end in range(2):
                w = w_start if end == 0 else w_end
                wu = wu_start[i, j] if end == 0 else wu_end[i, j]
                ww = w[j, 0] * w[j, 0] + w[j, 1] * w[j, 1]
                disc = wu * wu - (ww - r2)
                if wu < 0.0 and disc >= 0.0:
                    t = (-wu) - math.sqrt(disc) if ww > r2 else 0.0
                    if t < b:
                        b = t
            # the segment's side: the disc's centre reaches the line offset by radius
            side = w_start[j, 0] * n[j, 0] + w_start[j, 1] * n[j, 1]      # signed distance
            if side * rate[i, j] < -_PARALLEL:                           # moving toward it
                gap = abs(side) - radius
                t = (gap if gap >= 0.0 else 0.0) / abs(rate[i, j])
                along = (w_start[j, 0] * e[j, 0] + w_start[j, 1] * e[j, 1]) + t * ue[i, j]
                if along >= 0.0 and along <= length[j] * length[j] and t < b:
                    b = t
        best[i] = b
    return best


@njit(error_model="numpy")
def _braking_compiled(travel: np.ndarray, max_accel: float, dt: float) -> np.ndarray:
    """:func:`braking_speed` of a (k,) array, element by element (its operations)."""
    out = np.empty(travel.shape[0])
    for i in range(travel.shape[0]):
        d = travel[i] if travel[i] >= 0.0 else 0.0
        if math.isinf(d):
            out[i] = math.inf
        else:
            out[i] = max_accel * (math.sqrt(dt * dt + 2.0 * d / max_accel) - dt)
    return out


def clearance(starts: np.ndarray, ends: np.ndarray, point: np.ndarray) -> float:
    """Distance (m) from ``point`` (2,) to the nearest of the segments ``starts`` -> ``ends``
    ((m, 2) each, m); inf without segments."""
    starts = np.asarray(starts, dtype=np.float64)
    ends = np.asarray(ends, dtype=np.float64)
    if starts.shape != ends.shape or starts.shape[1:] != (2,):
        raise ValueError(f"starts and ends must be (m, 2) arrays of the same segments, got "
                         f"shapes {starts.shape} and {ends.shape}")
    x, y = np.asarray(point, dtype=np.float64).tolist()
    return _clearance_compiled(starts, ends, x, y)


def braking_speed(distance: np.ndarray, max_accel: float, dt: float) -> np.ndarray:
    """The largest speed s (m/s) from which the anchor, moving ``dt`` (s) at s and then braking
    at ``max_accel`` (m/s^2), stops within ``distance`` (m): s dt + s^2 / (2 max_accel) =
    distance (0 for distance <= 0, inf for inf)."""
    d = np.maximum(np.asarray(distance, dtype=np.float64), 0.0)
    with np.errstate(invalid="ignore"):
        s = max_accel * (np.sqrt(dt * dt + 2.0 * d / max_accel) - dt)
    return np.where(np.isinf(d), np.inf, s)


@dataclass(frozen=True)
class BrakingEnvelope:
    """Speed caps (m/s) by heading from the static edges near the anchor (see the module
    docstring). An anchor already closer to an edge than ``radius`` (ORCA lets it slide along
    the edges of its inflated radius) is held to the clearance it has: it may move along or
    away, never closer.

    Attributes:
        starts, ends: (m, 2) the edges' end points (m).
        position: (2,) the anchor's centre (m).
        radius: the anchor's radius plus a margin (m).
        max_accel: its deceleration limit (m/s^2).
        dt: the control period (s).
    """

    starts: np.ndarray
    ends: np.ndarray
    position: np.ndarray
    radius: float
    max_accel: float
    dt: float

    def __post_init__(self) -> None:
        # an infinite or NaN edge, position or limit would cap no speed (or every one) silently
        starts, ends, position = self.starts, self.ends, self.position
        if not (all(type(a) is np.ndarray and a.dtype == np.float64 for a in (starts, ends,
                                                                               position))
                and starts.ndim == ends.ndim == 2 and starts.shape[1] == ends.shape[1] == 2
                and position.shape == (2,) and all_finite(starts, ends) and finite(position)):
            for name, array, shape in (("starts", starts, (None, 2)), ("ends", ends, (None, 2)),
                                       ("position", position, (2,))):
                finite_array(name, array, "m", shape)
                if not (type(array) is np.ndarray and array.dtype == np.float64):
                    raise ValueError(f"{name} must be a float64 array (m), got "
                                     f"{type(array).__name__}")
        real("radius", self.radius, "m", low=0.0)
        positive("max_accel", self.max_accel, "m/s^2")
        positive("dt", self.dt, "s")

    def __call__(self, headings: np.ndarray) -> np.ndarray:
        """(k,) the speed cap on each heading (rad)."""
        return self._caps(headings, clearance(self.starts, self.ends, self.position))

    def _caps(self, headings: np.ndarray, gap: float) -> np.ndarray:
        """(k,) the speed cap on each heading (rad), the anchor's clearance being ``gap`` (m)."""
        radius = min(self.radius, gap - _HELD)
        travel = free_travel(self.starts, self.ends, self.position, headings, max(radius, 0.0))
        return _braking_compiled(travel, self.max_accel, self.dt)


def unicycle_command(v_star: np.ndarray, heading: float, speed: float, max_turn: float,
                     max_dv: float, points: np.ndarray, directions: np.ndarray,
                     fallback_heading: float, envelope: BrakingEnvelope | None = None
                     ) -> tuple[float, float]:
    """(speed [m/s], heading [rad]) that execute ORCA's ``v_star`` on a unicycle.

    The anchor turns toward ``v_star`` only as far as every heading on the way stays safe at
    the speed it cannot shed within the period (``speed - max_dv``), and is commanded the
    largest safe speed up to ``|v_star|`` on the headings it passes through. When even its
    current heading is unsafe at that speed, it brakes fully and turns toward the safest
    heading within reach; with an ``envelope``, only toward headings on which it can still stop
    before a static edge (the freest one when there is none).

    Args:
        v_star: (2,) ORCA's velocity (m/s).
        heading: the anchor's current heading (rad).
        speed: the anchor's current speed (m/s).
        max_turn: the most the anchor turns in one control period (rad).
        max_dv: the most its speed changes in one control period (m/s).
        points, directions: (n, 2) the ORCA lines ``v_star`` was solved against.
        fallback_heading: heading (rad) to turn toward when ``v_star`` is (almost) zero.
        envelope: further speed caps by heading (the static edges' braking envelope).
    """
    if points.shape != directions.shape or points.shape[1:] != (2,):
        raise ValueError(f"points and directions must be (n, 2) arrays of the same ORCA lines, "
                         f"got shapes {points.shape} and {directions.shape}")
    if envelope is not None and envelope.starts.shape != envelope.ends.shape:
        raise ValueError(f"the envelope's starts and ends must be (m, 2) arrays of the same "
                         f"edges, got shapes {envelope.starts.shape} and {envelope.ends.shape}")
    # a NaN, an infinity or a negative limit would command nonsense silently
    vx, vy = vec2("v_star", v_star, "m/s")
    heading, fallback_heading = real("heading", heading, "rad"), real(
        "fallback_heading", fallback_heading, "rad")
    speed = real("speed", speed, "m/s", low=0.0)
    max_turn = real("max_turn", max_turn, "rad", low=0.0)
    max_dv = real("max_dv", max_dv, "m/s", low=0.0)
    if not all_finite(points, directions):
        raise ValueError("points and directions (the ORCA lines) must be finite")
    if SCALAR_TRIG and compiled_trig() and compiled_polar():
        if envelope is None:
            edges: tuple[Any, ...] = (_NO_EDGES, _NO_EDGES, 0.0, 0.0, 0.0, 1.0, 1.0)
        else:
            px, py = envelope.position.tolist()
            edges = (envelope.starts, envelope.ends, px, py, float(envelope.radius),
                     float(envelope.max_accel), float(envelope.dt))
        done, speed_cmd, heading_cmd, wanted, target, floor, gap = _compiled_command(
            vx, vy, float(heading), float(speed), float(max_turn), float(max_dv), points,
            directions, float(fallback_heading), *edges)
        if done:
            return speed_cmd, heading_cmd
        return _command_with_caps(wanted, target, heading, max_turn, floor, points, directions,
                                  envelope, gap)
    wanted = math.hypot(vx, vy)
    target = math.atan2(vy, vx) if wanted > _STILL else fallback_heading
    floor = max(speed - max_dv, 0.0)
    if not SCALAR_TRIG:
        return _command_on_arrays(wanted, target, heading, max_turn, floor, points, directions,
                                  envelope)
    gap = math.inf
    if envelope is not None and len(envelope.starts):
        gap = _clearance_compiled(envelope.starts, envelope.ends,
                                  float(envelope.position[0]), float(envelope.position[1]))
    return _command_with_caps(wanted, target, heading, max_turn, floor, points, directions,
                              envelope, gap)


# --- the same command in Python floats and compiled ---------------------------------------
# `unicycle_command` computes on float lists, or compiled on the lines' arrays element by
# element (`_reach_on_lines`), what `_command_on_arrays` computes on arrays: the same
# operations in the same order (tests/safety/test_unicycle.py checks them equal bit for bit
# against the array code). Three shortcuts keep the answer:
#
# - The safe speed is non-increasing along the arc (a running minimum), so the headings past
#   the first one whose safe speed falls short of the floor are never looked at: the command
#   stops at the heading before it.
# - The braking envelope caps every heading at no less than `_envelope_floor`: the disc moves at
#   least (clearance - its radius) before it touches an edge (triangle inequality), less
#   `_CERTIFICATE_SLACK` for round-off. When that floor is at least both |v*| and the speed
#   floor, a cap changes neither which branch is taken, nor the heading (every cap clears the
#   floor), nor the speed (min(|v*|, cap) = |v*|), so it is not computed. Otherwise, and when
#   the anchor must brake (the braking branch reads the caps themselves), the caps are computed
#   (`_command_with_caps`), unless the sharper certificate below rules them out.
# - Per heading: a cap changes nothing on a heading where it exceeds the lines' bound b (the
#   minimum there is b) or reaches max(|v*|, floor) (where it binds instead of b, the running
#   minimum that decides the branch and the heading still clears the floor, and the speed is
#   min(|v*|, .) = |v*|). So when, on every heading up to the one commanded, a lower bound of
#   the computed cap passes either test, the ORCA lines' command stands (`_reach_on_lines`).
#   The bound (`_travel_floor`) takes BLAS's products anywhere within `_DOT_SLACK` of their
#   terms (9 units of roundoff, 2^-53; any order, fused or not, errs by 2), keeps every
#   candidate such a product could make valid, and bounds each time from below; the braking
#   speed's rounded operations never decrease with the travel. Tested against free_travel on
#   the headings where its decisions turn on round-off. Of 6 000 recorded calls, 869 computed
#   the caps before, 12 now.
#
# Where the caps are computed, `free_travel` keeps NumPy's matrix products (`_products`), which
# BLAS computes with fused multiply-adds (an order that depends on the shapes and the CPU) that
# compiled loops cannot reproduce, and computes the rest compiled (`_travel_compiled`,
# `_braking_compiled`); the lines' bounds on the arc are compiled too (`_arc_bounds`).

#: How far (m) the computed free travel may fall short of (clearance - radius) by round-off.
#: The worst case is a disc of radius 0 heading straight at an end point W metres away, where
#: the square root of a discriminant near 0 turns its rounding into about 3e-8 W: 3e-7 m at
#: 10 m, 3e-5 m at 1 km (the envelope's edges lie within a few metres of the anchor).
_CERTIFICATE_SLACK = 1e-4
#: An envelope floor must be positive to skip the caps (no signed zeros to account for).
_TINY = 1e-300
#: The arc's fractions: `np.linspace(0, 1, 9)`, exactly i / 8.
_FRACTIONS = tuple(np.linspace(0.0, 1.0, 9).tolist())


@njit
def _clearance_compiled(starts: np.ndarray, ends: np.ndarray, px: float, py: float) -> float:
    """:func:`clearance` of the point (px, py) (m), edge by edge; inf without edges."""
    best = math.inf
    for i in range(starts.shape[0]):
        ax, ay = starts[i, 0], starts[i, 1]
        ex, ey = ends[i, 0] - ax, ends[i, 1] - ay
        wx, wy = px - ax, py - ay
        s = (wx * ex + wy * ey) / (ex * ex + ey * ey)
        s = min(max(s, 0.0), 1.0)
        gx, gy = wx - s * ex, wy - s * ey
        d2 = gx * gx + gy * gy
        if d2 < best:
            best = d2
    return math.sqrt(best)     # the square root is monotone: sqrt of the min = min of sqrts


@njit
def _held_radius(radius: float, gap: float) -> float:
    """The disc's radius (m) the caps use, the anchor's clearance being ``gap`` (m):
    ``max(min(radius, gap - _HELD), 0.0)`` as Python's min and max pick."""
    held = gap - _HELD
    if held < radius:
        radius = held
    return 0.0 if 0.0 > radius else radius


@njit
def _envelope_floor(radius: float, max_accel: float, dt: float, gap: float) -> float:
    """A speed (m/s) no cap of a braking envelope (disc ``radius``, m, braking at ``max_accel``,
    m/s^2, after ``dt``, s) falls below on any heading (notes above), the anchor's clearance
    being ``gap`` (m)."""
    if math.isinf(gap):
        return math.inf
    travel = gap - _held_radius(radius, gap) - _CERTIFICATE_SLACK
    if not travel > 0.0:
        return 0.0
    return max_accel * (math.sqrt(dt * dt + 2.0 * travel / max_accel) - dt)


def _lines(points: np.ndarray, directions: np.ndarray) -> list[tuple[float, float, float]]:
    """(det(d, p), d_x, d_y) of each ORCA line, as :func:`speed_bounds` computes det(d, p)."""
    return [(dx * py - dy * px, dx, dy) for (px, py), (dx, dy) in
            zip(points.tolist(), directions.tolist(), strict=True)]


def _bound(lines: list[tuple[float, float, float]], ch: float, sh: float) -> float:
    """:func:`speed_bounds` on the heading (cos, sin) = (ch, sh), in floats."""
    bound = math.inf
    for c, dx, dy in lines:
        along = dx * sh - dy * ch
        if along < 0.0:
            b = (c - _LINE_SLACK) / along if c <= 0.0 else 0.0
            if b < bound:
                bound = b
    return bound          # never negative: np.maximum(bound, 0.0) keeps it


def _accumulate(values: list[float]) -> list[float]:
    """``np.minimum.accumulate`` of non-NaN floats (np.minimum(a, b) is ``a if a < b else
    b``)."""
    out = []
    for v in values:
        if out and out[-1] < v:
            v = out[-1]
        out.append(v)
    return out


def _argmax(values: list[float]) -> int:
    """``np.argmax`` of non-NaN floats: the first of the largest."""
    best = 0
    for i, v in enumerate(values):
        if v > values[best]:
            best = i
    return best


@njit
def _heading_bound(ch: float, sh: float, points: np.ndarray, directions: np.ndarray) -> float:
    """:func:`_bound` on the heading (cos, sin) = (ch, sh), compiled (its ``math.cos``/``sin``
    must be compiled_trig's)."""
    bound = math.inf
    for j in range(points.shape[0]):
        px, py = points[j, 0], points[j, 1]
        dx, dy = directions[j, 0], directions[j, 1]
        c = dx * py - dy * px
        along = dx * sh - dy * ch
        if along < 0.0:
            b = (c - _LINE_SLACK) / along if c <= 0.0 else 0.0
            if b < bound:
                bound = b
    return bound


@njit
def _arc_bounds(heading: float, turn: float, points: np.ndarray,
                directions: np.ndarray) -> np.ndarray:
    """(9,) :func:`_bound` on each heading of the arc ``heading + turn * i / 8`` (i = 0..8),
    compiled."""
    out = np.empty(9)
    for i in range(9):
        h = heading + turn * (i / 8.0)
        out[i] = _heading_bound(math.cos(h), math.sin(h), points, directions)
    return out


#: Relative slack of the certificate's bounds on BLAS's 2-term products (about 9 units of
#: roundoff, 2^-53, of the terms' magnitudes; any order of the products, fused or not, errs by
#: at most 2) and on the floats it recomputes (the edges' normals, the sides).
_DOT_SLACK = 1e-15


@njit
def _travel_floor(ux: float, uy: float, starts: np.ndarray, ends: np.ndarray, px: float,
                  py: float, radius: float) -> float:
    """A lower bound (m) of :func:`free_travel` on the heading u = (cos, sin) = (ux, uy) as
    NumPy and BLAS compute it (:func:`_products`, :func:`_travel_compiled`): the same
    candidates with each matrix product (u . w, u . n, u . e) taken anywhere within
    ``_DOT_SLACK`` of its terms' magnitudes, every decision that such a product could flip
    counted as taken (a candidate that might be valid is kept), and each time bounded from
    below, its own rounding included. u is compiled_trig's cos and sin, NumPy's (the slack
    would also absorb a unit in the last place)."""
    r2 = radius * radius
    best = math.inf
    for j in range(starts.shape[0]):
        ax, ay, bx, by = starts[j, 0], starts[j, 1], ends[j, 0], ends[j, 1]
        # the end points: |w + t u| = radius, entered while w . u < 0
        for end in range(2):
            wx, wy = (px - ax, py - ay) if end == 0 else (px - bx, py - by)
            wu = ux * wx + uy * wy
            slack = _DOT_SLACK * (abs(ux * wx) + abs(uy * wy)) + 1e-300
            if wu - slack >= 0.0:
                continue                              # moving away: never entered
            ww = wx * wx + wy * wy
            if not ww > r2:
                return 0.0                            # inside the disc already
            most = abs(wu) + slack                    # |w . u| at most
            d = ww - r2
            disc = most * most * (1.0 + 4.0 * _DOT_SLACK) - d
            if disc < 0.0:
                continue                              # the disc's path misses the end point
            root = math.sqrt(disc) * (1.0 + _DOT_SLACK)
            t = (abs(wu) - slack) - root - _DOT_SLACK * (abs(wu) + root)
            if t < best:
                best = t
        # the side: the disc's centre reaches the line offset by radius
        ex, ey = bx - ax, by - ay
        length = math.hypot(ex, ey)
        if not length > 0.0:
            continue                                  # no normal: NumPy's NaN, never taken
        nx, ny = -ey / length, ex / length
        wx, wy = px - ax, py - ay
        side = wx * nx + wy * ny
        side_slack = 10.0 * _DOT_SLACK * (abs(wx * nx) + abs(wy * ny) + abs(side)) + 1e-300
        rate = ux * nx + uy * ny
        rate_slack = 2.0 * _DOT_SLACK * (abs(ux * nx) + abs(uy * ny)) + 1e-300
        lowest = (side * rate - (abs(side) + side_slack) * rate_slack - abs(rate) * side_slack
                  - _DOT_SLACK * abs(side * rate))
        if not lowest < -0.999 * _PARALLEL:          # (the product's own rounding included)
            continue                                  # not moving toward it
        gap_lo = max(abs(side) - side_slack - radius, 0.0) * (1.0 - 4.0 * _DOT_SLACK)
        gap_hi = max(abs(side) + side_slack - radius, 0.0) * (1.0 + 4.0 * _DOT_SLACK)
        t_lo = gap_lo / (abs(rate) + rate_slack) * (1.0 - 4.0 * _DOT_SLACK)
        if t_lo >= best:
            continue                                  # cannot lower the bound
        slow = abs(rate) - rate_slack
        t_hi = gap_hi / slow * (1.0 + 4.0 * _DOT_SLACK) if slow > 0.0 else math.inf
        inside = True
        if t_hi < math.inf:
            # where along the edge the centre is then: surely off the edge, or possibly on it
            ue = ux * ex + uy * ey
            ue_slack = _DOT_SLACK * (abs(ux * ex) + abs(uy * ey)) + 1e-300
            pe = wx * ex + wy * ey
            lo_ue, hi_ue = ue - ue_slack, ue + ue_slack
            a1, a2, a3, a4 = t_lo * lo_ue, t_lo * hi_ue, t_hi * lo_ue, t_hi * hi_ue
            lo = min(min(a1, a2), min(a3, a4))
            hi = max(max(a1, a2), max(a3, a4))
            pad = 4.0 * _DOT_SLACK * (abs(pe) + max(abs(lo), abs(hi))) + 1e-300
            l2 = length * length * (1.0 + 4.0 * _DOT_SLACK)
            inside = not (pe + hi + pad < 0.0 or pe + lo - pad > l2)
        if inside:
            best = t_lo
    return best


@njit
def _reach_on_lines(heading: float, turn: float, floor: float, points: np.ndarray,
                    directions: np.ndarray, need: float, starts: np.ndarray, ends: np.ndarray,
                    px: float, py: float, radius: float, max_accel: float,
                    dt: float) -> tuple[int, float, bool]:
    """(k, safe speed, certified) of :func:`_compiled_command`: the last heading of the arc
    ``heading + turn * i / 8`` (i = 0..8) reached before the running minimum of :func:`_bound`
    falls short of ``floor`` (-1: the first does), and that minimum there (m/s). Compiled, with
    the float code's operations in its order (``math.cos``/``sin`` must be compiled_trig's).

    ``certified``: whether the braking envelope's caps (edges ``starts`` -> ``ends`` around the
    anchor at (px, py), disc ``radius``, braking ``max_accel`` over ``dt``; none when there are
    no edges) provably change nothing: on each heading up to k a lower bound of its cap
    (:func:`_travel_floor` through the braking speed's operations, which never decrease with
    the travel) exceeds the lines' bound there, or reaches ``need`` (|v*|, the speed floor and
    a tiny positive speed; notes above)."""
    reach = math.inf
    last = 0.0
    k = -1
    for i in range(9):
        h = heading + turn * (i / 8.0)
        ch, sh = math.cos(h), math.sin(h)
        bound = _heading_bound(ch, sh, points, directions)
        if not reach < bound:
            reach = bound
        if reach + 1e-9 < floor:
            break
        if starts.shape[0]:
            travel = _travel_floor(ch, sh, starts, ends, px, py, radius)
            if not math.isinf(travel):
                d = travel if travel >= 0.0 else 0.0
                cap = max_accel * (math.sqrt(dt * dt + 2.0 * d / max_accel) - dt)
                if not (cap > bound or cap >= need):
                    return k, last, False
        k += 1
        last = reach
    return k, last, True


#: No edges (no braking envelope): :func:`_compiled_command` has no clearance to measure and
#: no cap to bound (read only, as the edge arrays of ``StaticObstacles.segments_near``: one
#: compiled version serves both).
_NO_EDGES = np.zeros((0, 2))
_NO_EDGES.flags.writeable = False


@njit
def _remainder(x: float) -> float:
    """``math.remainder(x, 2 pi)`` of a finite x (rad), compiled: x less the nearest multiple
    of 2 pi (the even one at a tie), exact; a zero takes the sign of x. ``%`` of two positive
    floats is their exact ``fmod``."""
    period = 2.0 * math.pi
    size = abs(x)
    m = size % period
    c = period - m
    if m < c:
        r = m
    elif m > c:
        r = -c
    else:                   # half way: the even multiple
        r = m - 2.0 * ((0.5 * (size - m)) % period)
    return math.copysign(1.0, x) * r


@njit
def _compiled_command(vx: float, vy: float, heading: float, speed: float, max_turn: float,
                      max_dv: float, points: np.ndarray, directions: np.ndarray,
                      fallback_heading: float, starts: np.ndarray, ends: np.ndarray,
                      px: float, py: float, radius: float, max_accel: float,
                      dt: float) -> tuple[bool, float, float, float, float, float, float]:
    """(done, speed, heading, wanted, target, floor, gap) of :func:`unicycle_command` for ORCA's
    v* = (vx, vy) (m/s) on the ORCA lines alone (:func:`_reach_on_lines`), compiled, looking
    only at the headings up to the first that falls short (notes above); ``math.hypot`` and
    ``math.atan2`` must be compiled_polar's. The braking envelope's edges ``starts`` ->
    ``ends`` (none: no envelope) around the anchor at (px, py) (m), its disc ``radius`` (m)
    and braking ``max_accel`` (m/s^2) over ``dt`` (s). Not ``done`` when the anchor must brake
    or when the envelope's caps might change the command: the caller decides on all headings
    (:func:`_command_with_caps`) from |v*| (``wanted``, m/s), its heading (``target``, rad),
    the speed floor (m/s) and the anchor's clearance (``gap``, m)."""
    wanted = hypot(vx, vy)
    target = math.atan2(vy, vx) if wanted > _STILL else fallback_heading
    floor = speed - max_dv
    if 0.0 > floor:
        floor = 0.0
    gap = _clearance_compiled(starts, ends, px, py) if starts.shape[0] else math.inf
    turn = _remainder(target - heading)
    clipped = -max_turn if -max_turn > turn else turn          # as _arc
    if max_turn < clipped:
        clipped = max_turn
    need = wanted                                              # max(wanted, floor, _TINY)
    if floor > need:
        need = floor
    if _TINY > need:
        need = _TINY
    if _envelope_floor(radius, max_accel, dt, gap) >= need:
        # no cap can bind, or none can change the command: the ORCA lines alone decide
        k, last, certified = _reach_on_lines(heading, clipped, floor, points, directions, 0.0,
                                             starts[:0], ends[:0], 0.0, 0.0, 0.0, 1.0, 1.0)
    else:
        k, last, certified = _reach_on_lines(heading, clipped, floor, points, directions, need,
                                             starts, ends, px, py, _held_radius(radius, gap),
                                             max_accel, dt)
    if k < 0 or not certified:
        return False, 0.0, 0.0, wanted, target, floor, gap
    command = target if k == 8 else heading + clipped * (k / 8.0)     # _FRACTIONS[k]
    if abs(turn) > math.pi - _OPPOSITE:
        command = heading + clipped * (k / 8.0)                      # see _command_on_arrays
    return True, last if last < wanted else wanted, command, wanted, target, floor, gap


def _command_with_caps(wanted: float, target: float, heading: float, max_turn: float,
                       floor: float, points: np.ndarray, directions: np.ndarray,
                       envelope: BrakingEnvelope | None, gap: float) -> tuple[float, float]:
    """:func:`_command_on_arrays` with the ORCA lines' bounds and the decisions in floats; the
    envelope's caps from its arrays (``gap``: the anchor's clearance to its edges, m)."""
    turn = math.remainder(target - heading, 2.0 * math.pi)
    clipped = min(max(turn, -max_turn), max_turn)            # as _arc
    arc = [heading + clipped * f for f in _FRACTIONS]
    if compiled_trig():
        bounds = _arc_bounds(heading, clipped, points, directions).tolist()
    else:
        lines = _lines(points, directions)
        bounds = [_bound(lines, math.cos(h), math.sin(h)) for h in arc]
    if envelope is not None:
        caps = envelope._caps(np.array(arc), gap).tolist()
        bounds = [b if b < c else c for b, c in zip(bounds, caps, strict=True)]
    reach = _accumulate(bounds)
    if reach[0] + 1e-9 < floor:
        if envelope is None:
            return 0.0, float(arc[_argmax(bounds)])
        # the braking of _command_on_arrays
        stop = _accumulate(caps)
        stoppable = [c + 1e-9 >= floor for c in stop]
        if not any(stoppable):
            return 0.0, float(arc[_argmax(stop)])
        return 0.0, float(arc[_argmax([b if ok else -math.inf
                                       for b, ok in zip(bounds, stoppable, strict=True)])])
    k = max(i for i, r in enumerate(reach) if r + 1e-9 >= floor)
    command = target if k == len(arc) - 1 else float(arc[k])
    if abs(turn) > math.pi - _OPPOSITE:
        command = float(arc[k])      # see _command_on_arrays
    return float(min(wanted, reach[k])), command


def _command_on_arrays(wanted: float, target: float, heading: float, max_turn: float,
                       floor: float, points: np.ndarray, directions: np.ndarray,
                       envelope: BrakingEnvelope | None) -> tuple[float, float]:
    """:func:`unicycle_command` on NumPy arrays (the reference the float path reproduces)."""
    arc = turn_headings(heading, target, max_turn, n=8)
    bounds = speed_bounds(points, directions, arc)
    if envelope is not None:
        caps = envelope(arc)
        bounds = np.minimum(bounds, caps)
    reach = np.minimum.accumulate(bounds)          # safe speed over the arc up to each heading
    if reach[0] + 1e-9 < floor:
        if envelope is None:
            return 0.0, float(arc[int(np.argmax(bounds))])
        # braking: never turn, at the speed still to shed, toward a static edge it cannot stop
        # for (static contact is hard, ORCA's moving lines may give); else the freest heading
        stoppable = np.minimum.accumulate(caps) + 1e-9 >= floor
        if not stoppable.any():
            return 0.0, float(arc[int(np.argmax(np.minimum.accumulate(caps)))])
        return 0.0, float(arc[int(np.argmax(np.where(stoppable, bounds, -np.inf)))])
    k = int(np.flatnonzero(reach + 1e-9 >= floor)[-1])
    command = target if k == len(arc) - 1 else float(arc[k])
    if abs(math.remainder(target - heading, 2.0 * math.pi)) > math.pi - _OPPOSITE:
        # a target (almost) opposite the heading: the drive's shorter-way-round turn may go
        # the other way than the arc that was checked (the look-ahead's candidates include
        # heading + pi exactly); command the arc's heading, which the drive turns to the same
        # way (a turn into a wall, issue 24)
        command = float(arc[k])
    return float(min(wanted, reach[k])), command
