"""Look-ahead avoidance of moving obstacles: the tracks' prediction and uncertainty, rolled out
over a horizon sized to the anchor's braking and turning limits.

ORCA (:mod:`aoass_env.safety.orca`) sees a moving obstacle as a disc that keeps its current
velocity, and picks the velocity nearest the preferred one that is collision-free for its
horizon. Near walls that is not enough: fleeing along an obstacle's path into a pocket is
locally optimal and leaves the anchor pinned when the obstacle follows it there; an obstacle
that turns toward the anchor at close range breaks the constant-velocity assumption. This
module scores candidate commands by rolling the anchor's unicycle out against the static edges
and the predicted obstacles:

* **Obstacles** move on their Kalman estimate (constant velocity); each one's disc grows with
  time by ``sigma`` standard deviations of its predicted position (the track covariance
  propagated by the CV model, :func:`position_std`) and by ``maneuver`` times its speed times
  the time (room for a turn toward the anchor; 1 would be its whole reachable disc),
  :func:`obstacle_radii`.
* **The anchor** (:func:`rollout`) turns toward each candidate heading at its turn-rate limit
  and ramps its speed at its acceleration limit; a step that would bring its disc closer than
  its radius to a static edge is not taken (it stops there: pinned against the wall).
* **Score** (:func:`violation`): the summed shortfall of the clearance to every obstacle below a
  required ``clearance`` over the horizon; 0 means safe.

:func:`escape_velocity` keeps the velocity it is given unless its rollout's shortfall is
*imminent* (within a reaction time, by default one period and a full stop, or a contact with a
bare disc anywhere in the horizon; the wrapper keeps escaping until the given velocity is clear
over the whole horizon). Otherwise the given velocity and the candidates compete: the
shortfall first (with a ``tolerance``, only the candidates within it of the least take part),
then a price on ending pressed against a wall, on leaving the preferred velocity, on turning,
and on losing the sweep's headway along the preferred direction (without a tolerance all of
it is one cost, and these prices can buy shortfall). The anchor escapes toward free space
instead of braking in place, and backs out of a narrow passage while it still can.
:class:`EscapeBudget` bounds how long escapes may hold the anchor off the sweep: past it the
look-ahead yields (no room for turns, headway priced higher) until half of it is back. The
horizon (:func:`look_ahead_horizon`) is one control period, a full stop from top speed and a
half turn: 4.5 s with the defaults.

All functions are pure (NumPy in, NumPy out); lengths in m, times in s, angles in rad. The
public ones (``__all__``) check their input; the steps of a rollout (``candidate_commands``,
``predict_obstacles``, ``position_std``, ``segment_distances``, ``violation``) read what
:func:`escape_velocity` and :func:`rollout` have checked, and are not part of the API.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from aoass_env.jit import njit
from aoass_env.pairwise import pairwise_sum
from aoass_env.safety.checks import all_finite
from aoass_env.trig import SCALAR_TRIG, compiled_trig
from aoass_env.validators import integer, positive, real, vec2

__all__ = ["Escape", "EscapeBudget", "bounce_reach", "escape_velocity", "look_ahead_horizon",
           "obstacle_radii", "rollout", "rollout_reach"]


#: Weight of a predicted contact with an obstacle's bare disc (m x steps of overlap) against a
#: shortfall from the clearance to its grown disc.
CONTACT_WEIGHT = 10.0
#: Clearance (m, centre to the nearest static edge) at the end of a rollout below which the
#: end counts as pressed against a wall, and the price (steps) of each metre short of it.
OPEN_SPACE = 2.0
OPEN_SPACE_WEIGHT = 10.0
#: Price (m x steps) of a candidate as far from the preferred velocity as the top speed.
PREFERENCE_WEIGHT = 1.0
#: Price (m x steps) of a candidate heading opposite the current one.
TURN_WEIGHT = 1.0


def look_ahead_horizon(max_speed: float, max_accel: float, max_turn_rate: float,
                       dt: float) -> float:
    """Seconds (s) the anchor needs to react to a threat and get away from it: one control
    period ``dt`` (s), a full stop from ``max_speed`` (m/s) at ``max_accel`` (m/s^2) and a half
    turn at ``max_turn_rate`` (rad/s): 0.5 + 2 + 2 = 4.5 s with the env's defaults."""
    max_speed = real("max_speed", max_speed, "m/s", low=0.0)
    max_accel = positive("max_accel", max_accel, "m/s^2")
    max_turn_rate = positive("max_turn_rate", max_turn_rate, "rad/s")
    dt = positive("dt", dt, "s")
    return dt + max_speed / max_accel + math.pi / max_turn_rate


#: Slack (m) added to the edge reaches below, for the rounding of the rollouts' sums.
_REACH_SLACK = 1e-6


def _rollout_steps(horizon: float, step: float) -> int:
    """The rollouts' steps: ceil(``horizon`` / ``step``), at least 1 (their last time is
    ``step`` x that)."""
    return max(int(math.ceil(horizon / step - 1e-9)), 1)


def rollout_reach(max_speed: float, horizon: float, step: float, radius: float) -> float:
    """How far (m) from the anchor a static edge may lie and still matter to
    :func:`escape_velocity`'s rollouts (its ``starts`` and ``ends``): ``max_speed`` (m/s) x the
    rollouts' last time (ceil(``horizon`` / ``step``) steps of ``step``, s), plus the larger of
    the anchor's ``radius`` (m, an edge it stops at) and :data:`OPEN_SPACE` (a wall that prices
    a rollout's end)."""
    return (max_speed * (step * _rollout_steps(horizon, step)) + max(radius, OPEN_SPACE)
            + _REACH_SLACK)


def bounce_reach(obstacles: np.ndarray, horizon: float, step: float,
                 obstacle_radius: float) -> np.ndarray:
    """(m,) how far (m) from each of ``obstacles`` (m, >= 4): x, y (m), vx, vy (m/s) a static
    edge may lie and still turn its predicted path (:func:`predict_obstacles`) within
    :func:`escape_velocity`'s rollouts: its speed x the rollouts' last time (ceil(``horizon``
    / ``step``) steps of ``step``, s) plus ``obstacle_radius`` (m). The edges within it are
    ``escape_velocity``'s ``bounce_starts`` and ``bounce_ends``."""
    obstacles = np.asarray(obstacles, dtype=np.float64)
    speed = np.hypot(obstacles[:, 2], obstacles[:, 3])
    return speed * (step * _rollout_steps(horizon, step)) + obstacle_radius + _REACH_SLACK


def position_std(covariances: np.ndarray, times: np.ndarray) -> np.ndarray:
    """(m, S) standard deviation (m) along the worst axis of each track's position predicted
    ``times`` (S,) (s) ahead under the constant-velocity model: the square root of the largest
    eigenvalue of the position block of F(t) P F(t)', F(t) = [[I, t I], [0, I]], for each
    (4, 4) covariance ``P`` of ``covariances`` (m, 4, 4) (m^2, m^2/s, m^2/s^2)."""
    p = np.asarray(covariances, dtype=np.float64).reshape(-1, 4, 4)
    return _position_std(p, np.asarray(times, dtype=np.float64).reshape(-1))


@njit
def _position_std(p: np.ndarray, times: np.ndarray) -> np.ndarray:
    """:func:`position_std`, compiled element by element with the array form's operations
    (with P_pv + P_vp' = pv): a = P_xx + t pv_xx + t^2 P_vxvx, c likewise in y, b = P_xy +
    0.5 t (pv_xy + pv_yx) + t^2 P_vxvy, and the largest eigenvalue 0.5 (a + c) + sqrt(0.25
    (a - c)^2 + b^2), floored at 0."""
    out = np.empty((p.shape[0], len(times)))
    for i in range(p.shape[0]):
        q = p[i]
        pv00, pv11 = q[0, 2] + q[2, 0], q[1, 3] + q[3, 1]
        pv01, pv10 = q[0, 3] + q[3, 0], q[1, 2] + q[2, 1]
        for j in range(len(times)):
            t = times[j]
            a = q[0, 0] + t * pv00 + t * t * q[2, 2]
            c = q[1, 1] + t * pv11 + t * t * q[3, 3]
            b = q[0, 1] + 0.5 * t * (pv01 + pv10) + t * t * q[2, 3]
            d = a - c
            largest = 0.5 * (a + c) + math.sqrt(0.25 * (d * d) + b * b)
            out[i, j] = math.sqrt(largest if largest > 0.0 else 0.0)
    return out


def obstacle_radii(radii: np.ndarray, speeds: np.ndarray, std: np.ndarray,
                   times: np.ndarray, sigma: float, maneuver: float) -> np.ndarray:
    """(m, S) the radius (m) each obstacle's disc is given ``times`` (S,) (s) ahead: its radius
    ``radii`` (m,) (m, the anchor's included when distances are between centres) plus ``sigma``
    times its position std ``std`` (m, S) (m) plus ``maneuver`` times its speed ``speeds`` (m,)
    (m/s) times the time."""
    t = np.asarray(times, dtype=np.float64)[None, :]
    return (np.asarray(radii, dtype=np.float64)[:, None] + sigma * np.asarray(std)
            + maneuver * np.asarray(speeds, dtype=np.float64)[:, None] * t)


def segment_distances(points: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """(k,) distance (m) from each of ``points`` (k, 2) to the nearest of the segments
    ``starts`` -> ``ends`` ((e, 2) each, m); inf without segments."""
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 2:
        raise ValueError(f"points must be a (k, 2) array (m), got shape {points.shape}")
    if len(starts) == 0:
        return np.full(len(points), np.inf)
    return _Segments(starts, ends).distances(points)


#: Slack (m) of a clearance certificate: a point within ``d`` of a point whose exact distance to
#: the segments is ``g`` is at least ``g - d`` from them; a test is skipped only when that bound
#: clears its threshold by this much (far above the rounding of either distance).
CERTIFICATE_SLACK = 1e-9


class _Segments:
    """Segments ``starts`` -> ``ends`` prepared for distance queries of batches of points
    (:meth:`distances`, what :func:`segment_distances` computes) and of single points, with the
    same floats as :meth:`distances` and :func:`_nearest_on_segments` (per point they are the
    same elementwise operations and an exact min). The queries run compiled
    (:func:`_nearest_compiled`)."""

    __slots__ = ("ee", "ex", "ey", "sx", "sy")

    def __init__(self, starts: np.ndarray, ends: np.ndarray) -> None:
        starts = np.asarray(starts, dtype=np.float64)
        ends = np.asarray(ends, dtype=np.float64)
        if starts.shape != ends.shape or starts.ndim != 2 or starts.shape[1] != 2:
            raise ValueError(f"starts and ends must be (e, 2) arrays of the same segments (m), "
                             f"got shapes {starts.shape} and {ends.shape}")
        self.sx, self.sy, self.ex, self.ey, self.ee = _segment_tables(starts, ends)

    def distances(self, points: np.ndarray) -> np.ndarray:
        """(k,) distance (m) from each of ``points`` (k, 2) (m) to the nearest segment."""
        return _distances_compiled(self.sx, self.sy, self.ex, self.ey, self.ee,
                                   np.asarray(points, dtype=np.float64))

    def distance(self, x: float, y: float) -> float:
        """Distance (m) from (x, y) to the nearest segment: ``segment_distances``'s value."""
        return math.sqrt(_nearest_compiled(self.sx, self.sy, self.ex, self.ey, self.ee, x, y)[0])

    def nearest(self, x: float, y: float) -> tuple[float, float, float]:
        """(distance, dx, dy) of (x, y) from the nearest segment's nearest point:
        ``_nearest_on_segments``'s values."""
        d2, gx, gy = _nearest_compiled(self.sx, self.sy, self.ex, self.ey, self.ee, x, y)
        return math.sqrt(d2), gx, gy


@njit
def _segment_tables(starts: np.ndarray, ends: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(sx, sy, ex, ey, ee) of the segments: the starts' coordinates, e = end - start and
    max(|e|^2, 1e-300), as the array code ``e = ends - starts; np.maximum((e * e).sum(axis=1),
    1e-300)`` computes them (a NaN kept, as np.maximum keeps it)."""
    n = starts.shape[0]
    sx, sy, ex, ey, ee = np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    for j in range(n):
        sx[j], sy[j] = starts[j, 0], starts[j, 1]
        dx, dy = ends[j, 0] - sx[j], ends[j, 1] - sy[j]
        ex[j], ey[j] = dx, dy
        e2 = dx * dx + dy * dy
        ee[j] = e2 if (e2 >= 1e-300 or e2 != e2) else 1e-300
    return sx, sy, ex, ey, ee


@njit
def _nearest_compiled(sx: np.ndarray, sy: np.ndarray, ex: np.ndarray, ey: np.ndarray,
                      ee: np.ndarray, x: float, y: float) -> tuple[float, float, float]:
    """(squared distance, dx, dy) of (x, y) from the nearest of the segments (the first of
    equals): per segment the array code's operations, the projection clipped to [0, 1] (a
    zero's sign aside, which no distance sees: (w - 0.0)^2 == (w + 0.0)^2)."""
    best, bx, by = math.inf, 0.0, 0.0
    for j in range(len(sx)):
        wx, wy = x - sx[j], y - sy[j]
        s = min(max((wx * ex[j] + wy * ey[j]) / ee[j], 0.0), 1.0)
        gx, gy = wx - s * ex[j], wy - s * ey[j]
        d2 = gx * gx + gy * gy
        if d2 < best:
            best, bx, by = d2, gx, gy
    return best, bx, by


@njit
def _distances_compiled(sx: np.ndarray, sy: np.ndarray, ex: np.ndarray, ey: np.ndarray,
                        ee: np.ndarray, points: np.ndarray) -> np.ndarray:
    """:meth:`_Segments.distances` of each point."""
    out = np.empty(points.shape[0])
    for i in range(points.shape[0]):
        out[i] = math.sqrt(_nearest_compiled(sx, sy, ex, ey, ee, points[i, 0], points[i, 1])[0])
    return out


def _nearest_on_segments(points: np.ndarray, starts: np.ndarray, ends: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
    """(k,) distance (m) from each point (k, 2) to the nearest segment and (k, 2) the offset
    from that segment's nearest point to the point."""
    e = ends - starts
    ee = np.maximum((e * e).sum(axis=1), 1e-300)
    wx = points[:, 0, None] - starts[None, :, 0]
    wy = points[:, 1, None] - starts[None, :, 1]
    s = np.clip((wx * e[:, 0] + wy * e[:, 1]) / ee, 0.0, 1.0)
    gx, gy = wx - s * e[:, 0], wy - s * e[:, 1]
    d2 = gx * gx + gy * gy
    j = d2.argmin(axis=1)
    rows = np.arange(len(points))
    return np.sqrt(d2[rows, j]), np.stack([gx[rows, j], gy[rows, j]], axis=1)


def predict_obstacles(states: np.ndarray, step: float, n_steps: int, starts: np.ndarray,
                      ends: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """(m, n_steps, 2) centres (m) of the obstacles ``states`` (m, 4) (x, y m, vx, vy m/s)
    after each of ``n_steps`` steps of ``step`` (s) at constant velocity, reflected off the
    static segments (``starts`` -> ``ends``, (e, 2) each) as the env's obstacles are: a disc
    of radius ``radii`` (m,) (m) that would come closer than its radius to a segment while
    moving toward it mirrors its velocity about the segment's normal (at the end of the step,
    a first-order model of the bounce)."""
    states = np.asarray(states, dtype=np.float64).reshape(-1, 4)
    radii = np.asarray(radii, dtype=np.float64)
    if radii.shape != (len(states),):
        radii = np.broadcast_to(radii, (len(states),))
    if SCALAR_TRIG:     # the float path (no trigonometry), compiled
        segments = _Segments(starts, ends)
        return _predict_all(states, np.ascontiguousarray(radii), float(step), n_steps,
                            segments.sx, segments.sy, segments.ex, segments.ey, segments.ee)
    xy, v = states[:, :2].copy(), states[:, 2:].copy()
    # straight on: the same additions, step by step, as the loop below makes (cumsum adds in
    # order); an obstacle that cannot come within its radius of an edge over the horizon
    # (its travel is shorter than its gap) keeps them
    steps = np.broadcast_to((step * v)[:, None, :], (len(states), n_steps, 2))
    out = np.cumsum(np.concatenate([xy[:, None, :], steps], axis=1), axis=1)[:, 1:]
    if not (len(starts) and len(states)):
        return out
    travel = np.hypot(v[:, 0], v[:, 1]) * (step * n_steps)
    segments = _Segments(starts, ends)
    gaps = segments.distances(xy)
    near = np.flatnonzero(gaps - travel <= radii + 1e-9)
    if len(near) == 0:
        return out
    xy, v, radii = xy[near], v[near], radii[near]
    for i in range(n_steps):
        moved = xy + step * v
        gap, offset = _nearest_on_segments(moved, starts, ends)
        normal = offset / np.maximum(gap, 1e-12)[:, None]
        along = (v * normal).sum(axis=1)
        hit = (gap < radii) & (along < 0.0)
        v = np.where(hit[:, None], v - 2.0 * along[:, None] * normal, v)
        moved = np.where(hit[:, None], xy + step * v, moved)
        xy = moved
        out[near, i] = xy
    return out


@njit
def _predict_all(states: np.ndarray, radii: np.ndarray, step: float, n_steps: int,
                 sx: np.ndarray, sy: np.ndarray, ex: np.ndarray, ey: np.ndarray,
                 ee: np.ndarray) -> np.ndarray:
    """:func:`predict_obstacles`, compiled with the array code's operations: straight on, the
    same additions step by step as NumPy's cumsum, unless the obstacle's travel over the
    horizon can bring it within its radius of an edge (``np.hypot`` is the C library's, as
    numba's); then :func:`_predict_one`."""
    m = states.shape[0]
    out = np.empty((m, n_steps, 2))
    for j in range(m):
        x, y, vx, vy = states[j, 0], states[j, 1], states[j, 2], states[j, 3]
        if len(sx):
            gap = math.sqrt(_nearest_compiled(sx, sy, ex, ey, ee, x, y)[0])
            if gap - math.hypot(vx, vy) * (step * n_steps) <= radii[j] + 1e-9:
                _predict_one(x, y, vx, vy, radii[j], gap, step, n_steps, sx, sy, ex, ey, ee,
                             out[j])
                continue
        dx, dy = step * vx, step * vy
        for i in range(n_steps):
            x, y = x + dx, y + dy
            out[j, i, 0] = x
            out[j, i, 1] = y
    return out


@njit
def _predict_one(x: float, y: float, vx: float, vy: float, radius: float, gap: float,
                 step: float, n_steps: int, sx: np.ndarray, sy: np.ndarray, ex: np.ndarray,
                 ey: np.ndarray, ee: np.ndarray, out: np.ndarray) -> None:
    """Into ``out`` (n_steps, 2): one obstacle of :func:`predict_obstacles`'s step loop,
    compiled (the same operations in the same order), starting at (x, y) whose distance to the
    segments (a :class:`_Segments`' arrays) is ``gap``. The edge test of a step is skipped when
    a clearance certificate (the exact distance of an earlier point, less the way from there)
    shows the disc clear of every edge: then it cannot bounce."""
    cx, cy, cg = x, y, gap                      # certificate: point and its exact distance
    limit = radius + CERTIFICATE_SLACK
    for i in range(n_steps):
        mx, my = x + step * vx, y + step * vy
        dx, dy = mx - cx, my - cy
        if cg - math.sqrt(dx * dx + dy * dy) < limit:
            d2, ox, oy = _nearest_compiled(sx, sy, ex, ey, ee, mx, my)
            g = math.sqrt(d2)
            cx, cy, cg = mx, my, g
            if g < radius:
                g = max(g, 1e-12)
                nx, ny = ox / g, oy / g
                along = vx * nx + vy * ny
                if along < 0.0:
                    vx, vy = vx - 2.0 * along * nx, vy - 2.0 * along * ny
                    mx, my = x + step * vx, y + step * vy
        x, y = mx, my
        out[i, 0] = x
        out[i, 1] = y


@njit
def _rollout_one(x: float, y: float, heading: float, speed: float, target_heading: float,
                 target_speed: float, max_dh: float, max_dv: float, step: float,
                 n_steps: int, walls: bool, sx: np.ndarray, sy: np.ndarray, ex: np.ndarray,
                 ey: np.ndarray, ee: np.ndarray, radius: float, gap: float,
                 out: np.ndarray) -> None:
    """One candidate of :func:`rollout` into ``out`` (n_steps, 2), compiled: the same
    operations in the same order (``np.clip`` as a min/max, ``np.remainder`` as Python's ``%``,
    which rounds alike). ``walls`` False: no edge test (the rollout cannot reach an edge); else
    against the segments of a :class:`_Segments`' arrays. The edge test of a step is skipped
    when a clearance certificate shows the new point ``radius`` clear of every edge (it is
    taken then); the distance of the current point, which a refused step compares with, is
    computed when needed."""
    two_pi = 2.0 * math.pi
    theta, v = heading, speed
    cx, cy, cg = x, y, gap                      # certificate: point and its exact distance
    here, known = gap, True                     # exact distance of (x, y), if known
    limit = radius + CERTIFICATE_SLACK
    for i in range(n_steps):
        turn = (target_heading - theta + math.pi) % two_pi - math.pi
        theta = theta + (-max_dh if turn < -max_dh else max_dh if turn > max_dh else turn)
        dv = target_speed - v
        v = v + (-max_dv if dv < -max_dv else max_dv if dv > max_dv else dv)
        mx = x + (v * step) * math.cos(theta)
        my = y + (v * step) * math.sin(theta)
        if walls:
            dx, dy = mx - cx, my - cy
            if cg - math.sqrt(dx * dx + dy * dy) >= limit:
                x, y, known = mx, my, False
            else:
                new_gap = math.sqrt(_nearest_compiled(sx, sy, ex, ey, ee, mx, my)[0])
                cx, cy, cg = mx, my, new_gap
                if not known:
                    here = math.sqrt(_nearest_compiled(sx, sy, ex, ey, ee, x, y)[0])
                    known = True
                if new_gap >= radius or new_gap >= here:
                    x, y, here = mx, my, new_gap
                else:
                    v = 0.0
        else:
            x, y = mx, my
        out[i, 0] = x
        out[i, 1] = y


@njit
def _rollout_many(x: float, y: float, heading: float, speed: float, headings: np.ndarray,
                  speeds: np.ndarray, max_dh: float, max_dv: float, step: float, n_steps: int,
                  walls: bool, sx: np.ndarray, sy: np.ndarray, ex: np.ndarray, ey: np.ndarray,
                  ee: np.ndarray, radius: float, gap: float) -> np.ndarray:
    """(k, n_steps, 2): :func:`_rollout_one` of each candidate (target heading, speed)."""
    out = np.empty((len(headings), n_steps, 2))
    for c in range(len(headings)):
        _rollout_one(x, y, heading, speed, headings[c], speeds[c], max_dh, max_dv, step,
                     n_steps, walls, sx, sy, ex, ey, ee, radius, gap, out[c])
    return out


def _check_motion(heading: float, speed: float, max_turn_rate: float, max_accel: float,
                  step: float, starts: np.ndarray, ends: np.ndarray, radius: float,
                  **limits: float) -> None:
    """The anchor's state and limits and the static edges of :func:`rollout` and
    :func:`escape_velocity` (``limits``: their other positive limits, by name): finite, the
    speed and the radius >= 0, the limits > 0; else a ValueError naming the first that is
    not."""
    real("heading", heading, "rad")
    real("speed", speed, "m/s", low=0.0)
    real("radius", radius, "m", low=0.0)
    for name, value in (("max_turn_rate", max_turn_rate), ("max_accel", max_accel),
                        ("step", step), *limits.items()):
        positive(name, value)
    if not all_finite(np.asarray(starts, dtype=np.float64), np.asarray(ends, dtype=np.float64)):
        raise ValueError("starts and ends (the static edges, m) must be finite")


def rollout(position: np.ndarray, heading: float, speed: float, headings: np.ndarray,
            speeds: np.ndarray, max_turn_rate: float, max_accel: float, step: float,
            n_steps: int, starts: np.ndarray, ends: np.ndarray, radius: float) -> np.ndarray:
    """(k, n_steps, 2) the anchor's centre (m) after each of ``n_steps`` steps of ``step`` (s)
    for each of k candidate commands (target heading ``headings`` (k,) rad, target speed
    ``speeds`` (k,) m/s), from ``position`` (2,) m, ``heading`` (rad) and ``speed`` (m/s).

    Each step the heading turns toward its target by at most ``max_turn_rate`` * step (the
    shorter way round), the speed moves toward its target by at most ``max_accel`` * step, and
    the centre advances along the new heading. A step that would leave the centre closer than
    ``radius`` (m) to a static segment (``starts`` -> ``ends``, (e, 2) each) and closer than it
    was is not taken, and the speed drops to 0: the anchor is held against the wall.
    """
    headings = np.asarray(headings, dtype=np.float64)
    target_speed = np.asarray(speeds, dtype=np.float64)
    if headings.ndim != 1 or target_speed.shape != headings.shape:
        raise ValueError(f"headings and speeds must be (k,) arrays of one candidate each, got "
                         f"shapes {headings.shape} and {target_speed.shape}")
    if not all_finite(headings, target_speed):
        raise ValueError("headings (rad) and speeds (m/s) must be finite")
    vec2("position", position, "m")
    _check_motion(heading, speed, max_turn_rate, max_accel, step, starts, ends, radius)
    if type(n_steps) is not int or n_steps < 1:
        n_steps = integer("n_steps", n_steps, "steps", low=1)
    k = len(headings)
    max_dh, max_dv = max_turn_rate * step, max_accel * step
    if SCALAR_TRIG and compiled_trig():
        # compiled, candidate by candidate: each row of the array code below is one
        # candidate's own loop; with the edge tests decided for all at once
        px, py = np.asarray(position, dtype=np.float64).tolist()
        segments = _Segments(starts, ends)
        gap0 = segments.distance(px, py) if len(starts) else math.inf
        travel = max(abs(float(speed)), float(np.abs(target_speed).max(initial=0.0))) \
            * step * n_steps
        return _rollout_many(px, py, float(heading), float(speed), headings, target_speed,
                             max_dh, max_dv, float(step), n_steps,
                             bool(len(starts)) and gap0 - travel < radius + 1e-9, segments.sx,
                             segments.sy, segments.ex, segments.ey, segments.ee,
                             float(radius), gap0)
    xy = np.tile(np.asarray(position, dtype=np.float64), (k, 1))
    theta = np.full(k, float(heading))
    v = np.full(k, float(speed))
    gap = np.full(k, float(segment_distances(xy[:1], starts, ends)[0]))
    # the speed stays between the current one and the targets: when even that travel for the
    # whole horizon cannot bring the centre within ``radius`` of an edge, every step is taken
    # and the edge test is skipped (the same positions)
    travel = max(abs(float(speed)), float(np.abs(target_speed).max(initial=0.0))) * step * n_steps
    walls = bool(k) and gap[0] - travel < radius + 1e-9
    segments = _Segments(starts, ends) if walls else None
    out = np.empty((k, n_steps, 2))
    for i in range(n_steps):
        turn = np.remainder(headings - theta + math.pi, 2.0 * math.pi) - math.pi
        # np.clip's values without its wrappers: the bounds are not zero, so a tie with one
        # cannot differ in the sign of a zero (the only difference of the two)
        theta = theta + np.minimum(np.maximum(turn, -max_dh), max_dh)
        v = v + np.minimum(np.maximum(target_speed - v, -max_dv), max_dv)
        moved = xy + (v * step)[:, None] * np.stack([np.cos(theta), np.sin(theta)], axis=1)
        if segments is not None:
            new_gap = segments.distances(moved)
            ok = (new_gap >= radius) | (new_gap >= gap)
            xy = np.where(ok[:, None], moved, xy)
            gap = np.where(ok, new_gap, gap)
            v = np.where(ok, v, 0.0)
        else:
            xy = moved
        out[:, i] = xy
    return out


def violation(paths: np.ndarray, centres: np.ndarray, radii: np.ndarray,
              clearance: float) -> np.ndarray:
    """(k,) summed shortfall (m x steps) of each path's clearance to the obstacles below
    ``clearance`` (m): sum over the steps of max(0, clearance - min over obstacles of
    (|path - centre| - radius)). ``paths`` (k, S, 2), ``centres`` (m, S, 2), ``radii`` (m, S),
    all m; 0 for every path without obstacles."""
    paths = np.asarray(paths, dtype=np.float64)
    centres = np.asarray(centres, dtype=np.float64)
    radii = np.asarray(radii, dtype=np.float64)
    if paths.ndim != 3 or paths.shape[2] != 2:
        raise ValueError(f"paths must be a (k, S, 2) array (m), got shape {paths.shape}")
    if len(centres) == 0:
        return np.zeros(len(paths))
    steps = paths.shape[1]
    if centres.shape != (len(centres), steps, 2) or radii.shape != centres.shape[:2]:
        raise ValueError(f"centres must be (m, {steps}, 2) and radii (m, {steps}) for paths of "
                         f"{steps} steps, got shapes {centres.shape} and {radii.shape}")
    return _shortfalls(paths, centres, radii, float(clearance), steps)


@njit
def _shortfalls(paths: np.ndarray, centres: np.ndarray, radii: np.ndarray, clearance: float,
                steps: int) -> np.ndarray:
    """(k,) :func:`violation` over the first ``steps`` steps, compiled with the array code's
    operations: per step the distance sqrt(dx^2 + dy^2) to each centre less its radius, the
    least over the obstacles, max(clearance - it, 0); the steps summed in NumPy's order
    (:func:`~aoass_env.pairwise.pairwise_sum`)."""
    k, m = paths.shape[0], centres.shape[0]
    out = np.empty(k)
    row = np.empty(steps)
    for c in range(k):
        for t in range(steps):
            px, py = paths[c, t, 0], paths[c, t, 1]
            least = math.inf
            for i in range(m):
                dx, dy = px - centres[i, t, 0], py - centres[i, t, 1]
                gap = math.sqrt(dx * dx + dy * dy) - radii[i, t]
                if gap < least:
                    least = gap
            short = clearance - least
            row[t] = short if short > 0.0 else 0.0
        out[c] = pairwise_sum(row, 0, steps)
    return out


def candidate_commands(heading: float, max_speed: float, n_headings: int = 16,
                       extra_headings: tuple[float, ...] = ()) -> tuple[np.ndarray, np.ndarray]:
    """(headings [rad], speeds [m/s]) of the candidate commands: ``n_headings`` headings evenly
    spaced from ``heading`` plus ``extra_headings``, each at a quarter, a half and all of
    ``max_speed``, and one stop on the current heading."""
    base = heading + 2.0 * math.pi * np.arange(n_headings) / n_headings
    h = np.concatenate([base, np.asarray(extra_headings, dtype=np.float64)])
    fractions = np.array([0.25, 0.5, 1.0])
    headings = np.concatenate([np.repeat(h, len(fractions)), [heading]])
    speeds = np.concatenate([np.tile(fractions * max_speed, len(h)), [0.0]])
    return headings, speeds


@dataclass(frozen=True)
class Escape:
    """What :func:`escape_velocity` decided.

    Attributes:
        velocity: (2,) the velocity to steer for (m/s).
        escaping: whether the given velocity's rollout fell short of the clearance and another
            candidate was taken.
        shortfall: the given velocity's summed clearance shortfall (m x steps, 0: safe).
        chosen_shortfall: the returned velocity's (equal to ``shortfall`` when not escaping).
    """

    velocity: np.ndarray
    escaping: bool
    shortfall: float
    chosen_shortfall: float


@njit
def _reach(radius: float | np.ndarray, speed: float | np.ndarray, worst_std: float | np.ndarray,
           clearance: float, max_speed: float, maneuver: float, last: float,
           sigma: float) -> float | np.ndarray:
    """How far (m) an obstacle's centre may be from the anchor and still come within its grown
    radius plus ``clearance`` of the anchor's rollout by ``last`` (s), the rollout's last time:
    each closes at most at its top speed, the obstacle grows by ``maneuver`` x its ``speed``
    per second and by ``sigma`` x its position std, at most ``worst_std`` (m) over the rollout
    (no fewer than 3 std, the reach the look-ahead always had). Farther obstacles add nothing
    to any shortfall, and are left out."""
    return (radius + clearance + (max_speed + speed * (1.0 + maneuver)) * last
            + sigma * np.maximum(worst_std, 3.0))


def _base_arrays(own: float, wanted: float, position: np.ndarray, heading: float, speed: float,
                 obstacles: np.ndarray, covariances: np.ndarray, max_speed: float,
                 max_accel: float, max_turn_rate: float, horizon: float, step: float,
                 n_steps: int, times: np.ndarray, starts: np.ndarray, ends: np.ndarray,
                 radius: float, sigma: float, maneuver: float, clearance: float,
                 obstacle_radius: float | None, soon: int, bounce_starts: np.ndarray,
                 bounce_ends: np.ndarray
                 ) -> tuple[bool, np.ndarray, np.ndarray, np.ndarray, np.ndarray, float, bool]:
    """What :func:`escape_velocity` reads before a contest of candidates: (whether an obstacle
    is near; the near obstacles' predicted centres (m, S, 2), grown radii and bare radii
    (m, S); the given velocity's path (1, S, 2) (heading ``own``, speed ``wanted``); its
    moving-obstacle cost, a contact counting CONTACT_WEIGHT times a shortfall; whether it falls
    short within the first ``soon`` steps or meets a bare disc), on NumPy's arrays (compiled:
    :func:`_base_compiled`)."""
    # only the obstacles that could come within reach of the anchor within the rollout
    # (:func:`_reach`)
    rel = obstacles[:, :2] - position
    obstacle_speed = np.hypot(obstacles[:, 2], obstacles[:, 3])
    std_all = position_std(covariances, times)
    reach = _reach(obstacles[:, 4], obstacle_speed, std_all.max(axis=1, initial=0.0),
                   clearance, max_speed, maneuver, max(horizon, float(times[-1])), sigma)
    near = np.hypot(rel[:, 0], rel[:, 1]) <= reach
    empty = np.zeros((0, n_steps))
    if not near.any():
        return False, np.zeros((0, n_steps, 2)), empty, empty, np.zeros((0, n_steps, 2)), 0.0, \
            False
    obs = obstacles[near]
    if obstacle_radius is None:
        centres = obs[:, None, :2] + times[None, :, None] * obs[:, None, 2:4]
    else:
        centres = predict_obstacles(obs[:, :4], step, n_steps, bounce_starts, bounce_ends,
                                    np.full(len(obs), obstacle_radius))
    radii = obstacle_radii(obs[:, 4], obstacle_speed[near], std_all[near], times, sigma,
                           maneuver)
    bare = np.repeat(obs[:, 4:5] + 0.0, n_steps, axis=1)       # (m, S): each radius + 0.0
    paths = rollout(position, heading, speed, np.array([own]), np.array([wanted]),
                    max_turn_rate, max_accel, step, n_steps, starts, ends, radius)
    contact = _shortfalls(paths, centres, bare, 0.0, n_steps)
    base = float((CONTACT_WEIGHT * contact + _shortfalls(paths, centres, radii, clearance,
                                                          n_steps))[0])
    imminent = bool(soon) and (_shortfalls(paths, centres, radii, clearance, soon)[0] > 0.0
                               or contact[0] > 0.0)
    return True, centres, radii, bare, paths, base, imminent


@njit
def _base_compiled(own: float, wanted: float, px: float, py: float, heading: float,
                   speed: float, obstacles: np.ndarray, covariances: np.ndarray,
                   max_speed: float, max_accel: float, max_turn_rate: float, horizon: float,
                   step: float, n_steps: int, times: np.ndarray, sx: np.ndarray,
                   sy: np.ndarray, ex: np.ndarray, ey: np.ndarray, ee: np.ndarray,
                   radius: float, sigma: float, maneuver: float, clearance: float,
                   obstacle_radius: float, soon: int, bsx: np.ndarray, bsy: np.ndarray,
                   bex: np.ndarray, bey: np.ndarray, bee: np.ndarray
                   ) -> tuple[bool, np.ndarray, np.ndarray, np.ndarray, np.ndarray, float, bool]:
    """:func:`_base_arrays`, compiled with its operations in its order (``obstacle_radius`` < 0:
    straight through the edges; the obstacles bounce off the ``b*`` segment tables; ``np.hypot``
    is the C library's, as numba's; the rollout's cos and sin must be compiled_trig's)."""
    m_all = obstacles.shape[0]
    near = np.empty(m_all, np.bool_)
    speeds = np.empty(m_all)
    std_all = _position_std(covariances, times)
    last = times[-1] if times[-1] > horizon else horizon
    count = 0
    for i in range(m_all):
        speeds[i] = np.hypot(obstacles[i, 2], obstacles[i, 3])
        worst = 0.0
        for j in range(len(times)):
            worst = max(worst, std_all[i, j])
        reach = _reach(obstacles[i, 4], speeds[i], worst, clearance, max_speed, maneuver, last,
                       sigma)
        near[i] = np.hypot(obstacles[i, 0] - px, obstacles[i, 1] - py) <= reach
        count += near[i]
    states = np.empty((count, 4))
    own_radii = np.empty(count)
    own_speeds = np.empty(count)
    std = np.empty((count, len(times)))
    k = 0
    for i in range(m_all):          # element by element: a row assignment would make numba
        if near[i]:                 # compile its shape-error formatting (seconds)
            for c in range(4):
                states[k, c] = obstacles[i, c]
            for j in range(len(times)):
                std[k, j] = std_all[i, j]
            own_radii[k] = obstacles[i, 4]
            own_speeds[k] = speeds[i]
            k += 1
    paths = np.empty((1, n_steps, 2))
    radii = np.empty((count, n_steps))
    bare = np.empty((count, n_steps))
    if count == 0:
        return False, np.empty((0, n_steps, 2)), radii, bare, paths, 0.0, False
    if obstacle_radius < 0.0:
        centres = np.empty((count, n_steps, 2))
        for i in range(count):
            for j in range(n_steps):
                centres[i, j, 0] = states[i, 0] + times[j] * states[i, 2]
                centres[i, j, 1] = states[i, 1] + times[j] * states[i, 3]
    else:
        centres = _predict_all(states, np.full(count, obstacle_radius), step, n_steps, bsx,
                               bsy, bex, bey, bee)
    for i in range(count):
        grow = maneuver * own_speeds[i]
        for j in range(n_steps):
            radii[i, j] = own_radii[i] + sigma * std[i, j] + grow * times[j]
            bare[i, j] = own_radii[i] + 0.0
    # the given velocity's rollout (rollout()'s arguments)
    gap = math.sqrt(_nearest_compiled(sx, sy, ex, ey, ee, px, py)[0]) if len(sx) else math.inf
    fastest = abs(wanted) if abs(wanted) > abs(speed) else abs(speed)
    travel = fastest * step * n_steps
    _rollout_one(px, py, heading, speed, own, wanted, max_turn_rate * step, max_accel * step,
                 step, n_steps, len(sx) > 0 and gap - travel < radius + 1e-9, sx, sy, ex, ey,
                 ee, radius, gap, paths[0])
    contact = _shortfalls(paths, centres, bare, 0.0, n_steps)[0]
    base = CONTACT_WEIGHT * contact + _shortfalls(paths, centres, radii, clearance, n_steps)[0]
    imminent = soon > 0 and (_shortfalls(paths, centres, radii, clearance, soon)[0] > 0.0
                             or contact > 0.0)
    return True, centres, radii, bare, paths, base, imminent


@functools.lru_cache(maxsize=8)
def _times(step: float, n_steps: int) -> np.ndarray:
    """(n_steps,) the look-ahead's times ``step * [1, 2, ..., n_steps]`` (s), read only."""
    times = step * np.arange(1, n_steps + 1)
    times.flags.writeable = False
    return times


def escape_velocity(velocity: np.ndarray, preferred: np.ndarray, position: np.ndarray,
                    heading: float, speed: float, obstacles: np.ndarray,
                    covariances: np.ndarray, *, max_speed: float, max_accel: float,
                    max_turn_rate: float, horizon: float, step: float, starts: np.ndarray,
                    ends: np.ndarray, radius: float, sigma: float, maneuver: float,
                    clearance: float, obstacle_radius: float | None = None,
                    n_headings: int = 16, react: float | None = None,
                    progress_weight: float = 0.0,
                    tolerance: float | None = None, bounce_starts: np.ndarray | None = None,
                    bounce_ends: np.ndarray | None = None) -> Escape:
    """The velocity (m/s) to steer for among moving obstacles (see the module docstring).

    Args:
        velocity: (2,) the velocity the anchor is about to take (ORCA's v*, m/s).
        preferred: (2,) the velocity it would like (m/s); among safe candidates, the nearest
            to it is taken.
        position, heading, speed: the anchor's centre (m), heading (rad) and speed (m/s).
        obstacles: (m, 5) tracked obstacles x, y (m), vx, vy (m/s), radius (m; the anchor's
            radius included, distances are between centres).
        covariances: (m, 4, 4) their state covariances (m^2, m^2/s, m^2/s^2).
        max_speed, max_accel, max_turn_rate: the anchor's limits (m/s, m/s^2, rad/s).
        horizon, step: the look-ahead (s) and the rollout's step (s).
        starts, ends: (e, 2) the static edges the anchor's rollouts may meet (m): every edge
            within ``max_speed`` x the rollout's time plus ``max(radius, OPEN_SPACE)`` of
            ``position`` (the walls its ends are priced by included).
        radius: the anchor's radius plus its static margin (m), for the edges.
        sigma: position standard deviations added to an obstacle's radius.
        maneuver: fraction of an obstacle's speed by which its radius grows per second.
        clearance: gap (m) to keep between the anchor's centre and the grown discs.
        obstacle_radius: the obstacles' own radius (m) for their bounces off the static
            edges; None predicts them straight through the edges.
        bounce_starts, bounce_ends: (b, 2) the static edges the obstacles bounce off (m):
            every edge within each obstacle's speed x the rollout's time plus
            ``obstacle_radius`` of it (:func:`bounce_reach`); None: ``starts`` and ``ends``
            (an obstacle farther out than the anchor's reach then passes through walls).
        n_headings: evenly spaced candidate headings.
        react: seconds (s) within which a shortfall of ``velocity``'s rollout from the grown
            discs makes an escape (a predicted contact with a bare disc does at any time of
            the horizon); None: the whole horizon (any shortfall).
        progress_weight: price (m x steps) of a rollout that makes no headway along
            ``preferred`` against one that runs at ``max_speed`` straight along it for the
            whole horizon (the sweep's progress; 0: no price).
        tolerance: the prices (walls, headway, preference, turn) choose only among the
            candidates whose shortfall is within this (m x steps) of the least; None: they
            compete with the shortfall on one cost.
    """
    velocity = np.asarray(velocity, dtype=np.float64)
    preferred = np.asarray(preferred, dtype=np.float64)
    obstacles = np.asarray(obstacles, dtype=np.float64).reshape(-1, 5)
    covariances = np.asarray(covariances, dtype=np.float64).reshape(-1, 4, 4)
    if len(covariances) != len(obstacles):
        raise ValueError(f"covariances must be (m, 4, 4) for the m = {len(obstacles)} "
                         f"obstacles, got {len(covariances)} of them")
    # a NaN obstacle or anchor state reads as "nothing in the way" (no escape) and an infinite
    # limit as any escape: refused, as a library call must not pass them on silently
    vec2("velocity", velocity, "m/s")
    vec2("preferred", preferred, "m/s")
    vec2("position", position, "m")
    if not all_finite(obstacles, covariances):
        raise ValueError("obstacles and covariances (the tracks) must be finite")
    _check_motion(heading, speed, max_turn_rate, max_accel, step, starts, ends, radius,
                  max_speed=max_speed, horizon=horizon)
    if (bounce_starts is None) != (bounce_ends is None):
        raise ValueError("bounce_starts and bounce_ends must be given together (or neither)")
    if bounce_starts is None:
        bounce_starts, bounce_ends = starts, ends
    elif not all_finite(np.asarray(bounce_starts, dtype=np.float64),
                        np.asarray(bounce_ends, dtype=np.float64)):
        raise ValueError("bounce_starts and bounce_ends (the static edges, m) must be finite")
    for name, value, unit in (("sigma", sigma, ""), ("maneuver", maneuver, "per s"),
                              ("clearance", clearance, "m"), ("progress_weight", progress_weight,
                                                              ""),
                              ("obstacle_radius", obstacle_radius, "m"), ("react", react, "s"),
                              ("tolerance", tolerance, "")):
        if value is not None:            # the last three: None is a setting
            real(name, value, unit, low=0.0)
    if type(n_headings) is not int or n_headings < 1:
        integer("n_headings", n_headings, "headings", low=1)
    position = np.asarray(position, dtype=np.float64)
    n_steps = _rollout_steps(horizon, step)
    times = _times(float(step), n_steps)
    vx, vy = velocity.tolist()
    wanted = float(np.hypot(vx, vy))        # NumPy's hypot of the floats, as np.hypot(*velocity)
    own = math.atan2(vy, vx) if wanted > 1e-9 else heading
    # imminent only (react): a shortfall from the grown discs within ``react`` seconds, or a
    # contact with a bare disc at any time of the horizon (a contact on the tracks' estimates;
    # a trigger on the discs grown by the covariance alone escaped more and completed fewer
    # zero-action sweeps on the tuning seeds, for about the same contacts under random actions)
    soon = 0 if react is None else min(max(int(math.ceil(react / step - 1e-9)), 1), n_steps)
    if SCALAR_TRIG and compiled_trig():
        segments = _Segments(starts, ends)
        bounces = (segments if bounce_starts is starts and bounce_ends is ends
                   else _Segments(bounce_starts, bounce_ends))
        px, py = position.tolist()
        found, centres, radii, bare, base_paths, base, imminent = _base_compiled(
            own, wanted, px, py, float(heading), float(speed), obstacles, covariances,
            float(max_speed), float(max_accel), float(max_turn_rate), float(horizon),
            float(step), n_steps, times, segments.sx, segments.sy, segments.ex, segments.ey,
            segments.ee, float(radius), float(sigma), float(maneuver), float(clearance),
            -1.0 if obstacle_radius is None else float(obstacle_radius), soon, bounces.sx,
            bounces.sy, bounces.ex, bounces.ey, bounces.ee)
    else:
        found, centres, radii, bare, base_paths, base, imminent = _base_arrays(
            own, wanted, position, heading, speed, obstacles, covariances, max_speed,
            max_accel, max_turn_rate, horizon, step, n_steps, times, starts, ends, radius,
            sigma, maneuver, clearance, obstacle_radius, soon, bounce_starts, bounce_ends)
    if not found or base <= 0.0:
        return Escape(velocity, False, 0.0, 0.0)
    if soon and not imminent:
        return Escape(velocity, False, base, base)

    def score(headings: np.ndarray, speeds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(moving-obstacle cost (k,), paths) of the candidates (:func:`_base_arrays`'s)."""
        paths = rollout(position, heading, speed, headings, speeds, max_turn_rate, max_accel,
                        step, n_steps, starts, ends, radius)
        moving = CONTACT_WEIGHT * _shortfalls(paths, centres, bare, 0.0, n_steps) + \
            _shortfalls(paths, centres, radii, clearance, n_steps)
        return moving, paths

    def open_space(paths: np.ndarray) -> np.ndarray:
        """(k,) the price of the paths' ends: pressed against a wall (no way on), less the
        sweep's headway along the preferred direction; only a contest of candidates reads it."""
        walls = OPEN_SPACE_WEIGHT * np.maximum(
            OPEN_SPACE - segment_distances(paths[:, -1], starts, ends), 0.0)
        headway = headway_price * ((paths[:, -1] - position) @ along)
        return walls - headway

    # a contest of candidates: what open_space() reads
    pref_speed = float(np.hypot(*preferred))
    along = preferred / pref_speed if pref_speed > 1e-9 else np.zeros(2)
    # headway is priced per metre against running the whole horizon at top speed
    headway_price = progress_weight / (max_speed * n_steps * step)
    extra = [own]
    if np.hypot(*preferred) > 1e-9:
        extra.append(math.atan2(preferred[1], preferred[0]))
    headings, speeds = candidate_commands(heading, max_speed, n_headings, tuple(extra))
    # the given velocity is candidate 0, so that it competes on the same terms: choosing
    # between it and an escape with different rules made the anchor alternate between them
    headings = np.concatenate([[own], headings])
    speeds = np.concatenate([[wanted], speeds])
    moving, paths = score(headings[1:], speeds[1:])
    shortfall = np.concatenate([[base], moving])
    walls = np.concatenate([open_space(base_paths), open_space(paths)])
    candidates = speeds[:, None] * np.stack([np.cos(headings), np.sin(headings)], axis=1)
    candidates[0] = velocity
    # the least shortfall, then (priced well below any real shortfall) the nearest to the
    # preferred velocity and the least turn from the current heading: a safe candidate near
    # what was asked for, and no jumps between near ties from one period to the next (at low
    # speed the heading is the only memory of the direction taken)
    distance = np.hypot(*(candidates - preferred).T) / max_speed
    turn = np.abs(np.remainder(headings - heading + math.pi, 2.0 * math.pi) - math.pi) / math.pi
    cost = shortfall + walls + PREFERENCE_WEIGHT * distance + TURN_WEIGHT * turn
    if tolerance is not None:
        cost = np.where(shortfall <= shortfall.min() + tolerance, cost, np.inf)
    pick = int(np.argmin(cost))
    if pick == 0:
        return Escape(velocity, False, base, base)
    return Escape(candidates[pick], True, base, float(shortfall[pick]))


@dataclass
class EscapeBudget:
    """How long the look-ahead may hold the anchor off the sweep: escaping spends the budget
    (1 s per s), a period without an escape refills it at ``refill`` s per s. Once ``spent``
    reaches ``budget`` (s) the anchor *yields* to the sweep until half the budget has come
    back (hysteresis): the look-ahead then escapes only from predicted contacts with the
    obstacles' discs grown by their track covariance alone (no room for a turn), and prices
    the sweep's headway higher (the wrapper also takes ``SafetyConfig.
    yield_shortfall_tolerance`` as the contest's tolerance then); ORCA's lines, the static
    lines and the braking envelope are unchanged, so the anchor still does not drive into
    anything. An obstacle bouncing in a pocket beside the spiral can no longer hold the
    anchor off its way for the rest of the episode.
    """

    budget: float
    refill: float = 0.5
    spent: float = 0.0
    yielding: bool = False

    def __post_init__(self) -> None:
        positive("budget", self.budget, "s")
        real("refill", self.refill, "s per s", low=0.0)

    def reset(self) -> None:
        self.spent, self.yielding = 0.0, False

    def update(self, escaping: bool, dt: float) -> None:
        """Account one period of ``dt`` (s) in which the look-ahead did (not) escape."""
        if not (type(dt) is float and 0.0 <= dt < math.inf):   # a NaN spent it for good
            dt = real("dt", dt, "s", low=0.0)
        if escaping:
            self.spent += dt
        else:
            self.spent = max(self.spent - self.refill * dt, 0.0)
        if self.spent >= self.budget:
            self.yielding = True
        elif self.spent <= 0.5 * self.budget:
            self.yielding = False
