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

import numpy as np

__all__ = ["BrakingEnvelope", "braking_speed", "clearance", "free_travel", "speed_bounds",
           "turn_headings", "unicycle_command"]

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
    u = np.stack([np.cos(headings), np.sin(headings)], axis=1)            # (k, 2)
    p = np.asarray(position, dtype=np.float64)
    r2 = radius * radius
    best = np.full(len(headings), np.inf)
    with np.errstate(invalid="ignore", divide="ignore"):
        # the end points: |w + t u| = radius with w = p - vertex, entered while w . u < 0
        for vertex in (starts, ends):
            w = p - vertex                                                  # (m, 2)
            wu = u @ w.T                                                    # (k, m)
            ww = (w * w).sum(axis=1)
            disc = wu * wu - (ww - r2)
            t = np.where(ww > r2, -wu - np.sqrt(disc), 0.0)
            t = np.where((wu < 0.0) & (disc >= 0.0), t, np.inf)
            best = np.minimum(best, t.min(axis=1))
        # the segments' sides: the disc's centre reaches the line offset by radius
        e = ends - starts
        length = np.hypot(e[:, 0], e[:, 1])
        n = np.stack([-e[:, 1], e[:, 0]], axis=1) / length[:, None]        # (m, 2) unit normals
        side = ((p - starts) * n).sum(axis=1)                              # signed distance
        rate = u @ n.T                                                      # (k, m)
        approach = side[None, :] * rate < -_PARALLEL      # moving toward the side
        t = np.maximum(np.abs(side)[None, :] - radius, 0.0) / np.abs(rate)
        along = ((p - starts) * e).sum(axis=1)[None, :] + t * (u @ e.T)      # (k, m)
        inside = (along >= 0.0) & (along <= length * length)
        t = np.where(approach & inside, t, np.inf)
        best = np.minimum(best, t.min(axis=1))
    return best


def clearance(starts: np.ndarray, ends: np.ndarray, point: np.ndarray) -> float:
    """Distance (m) from ``point`` (2,) to the nearest of the segments ``starts`` -> ``ends``
    ((m, 2) each, m); inf without segments."""
    if len(starts) == 0:
        return math.inf
    e = ends - starts
    w = np.asarray(point, dtype=np.float64) - starts
    s = np.clip((w * e).sum(axis=1) / (e * e).sum(axis=1), 0.0, 1.0)
    gap = w - s[:, None] * e
    return float(np.sqrt((gap * gap).sum(axis=1)).min())


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

    def __call__(self, headings: np.ndarray) -> np.ndarray:
        """(k,) the speed cap on each heading (rad)."""
        radius = min(self.radius, clearance(self.starts, self.ends, self.position) - _HELD)
        travel = free_travel(self.starts, self.ends, self.position, headings, max(radius, 0.0))
        return braking_speed(travel, self.max_accel, self.dt)


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
    vx, vy = float(v_star[0]), float(v_star[1])
    wanted = math.hypot(vx, vy)
    target = math.atan2(vy, vx) if wanted > _STILL else fallback_heading
    arc = turn_headings(heading, target, max_turn, n=8)
    bounds = speed_bounds(points, directions, arc)
    floor = max(speed - max_dv, 0.0)
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
