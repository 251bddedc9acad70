"""ORCA's lines in Python floats, as aoass_env/safety/orca.py built them before issue 20's ninth
round compiled them, and its linear programs (Eq. 10) as they ran before the tenth round
compiled them: the oracle of tests/safety/test_orca.py, whose compiled lines and solver must
give these floats bit for bit (Python's ``math.hypot`` is correctly rounded since Python 3.11,
as the compiled ``_hypot`` is).
"""

from __future__ import annotations

import math

import numpy as np

from aoass_env.safety.orca import _EPS, _OVERSHOOT, _PARALLEL, _SLACK, StaticObstacles

_Line = tuple[float, float, float, float]


class ReferenceEdges:
    """What the float code read of a :class:`StaticObstacles`: the edge arrays of the NumPy
    edge query (:meth:`near_array`) and the vertices as Python floats."""

    def __init__(self, static: StaticObstacles) -> None:
        point, nxt = static.point, static.next
        self.ax, self.ay = point[:, 0].copy(), point[:, 1].copy()
        self.bx, self.by = point[nxt, 0], point[nxt, 1]
        self.ex, self.ey = self.bx - self.ax, self.by - self.ay
        self.inv_len2 = 1.0 / (self.ex * self.ex + self.ey * self.ey)
        lo, hi = ((point.min(axis=0), point.max(axis=0)) if len(point)
                  else (np.zeros(2), np.zeros(2)))
        self.bbox = (*lo.tolist(), *hi.tolist())
        self.x, self.y = self.ax.tolist(), self.ay.tolist()
        self.dx, self.dy = static.direction[:, 0].tolist(), static.direction[:, 1].tolist()
        self.next, self.prev = nxt.tolist(), static.prev.tolist()
        self.convex = static.convex.tolist()

    def _projection(self, px: float, py: float) -> tuple[np.ndarray, np.ndarray]:
        rx = px - self.ax
        ry = py - self.ay
        ex, ey = self.ex, self.ey
        s = (rx * ex + ry * ey) * self.inv_len2
        np.clip(s, 0.0, 1.0, out=s)
        rx -= s * ex
        ry -= s * ey
        return s, rx * rx + ry * ry

    def near_array(self, px: float, py: float, reach: float) -> list[int]:
        """The edges closer than ``reach`` (m) to (px, py), nearest first, with NumPy."""
        x0, y0, x1, y1 = self.bbox
        if (len(self.x) == 0 or px < x0 - reach or px > x1 + reach or py < y0 - reach
                or py > y1 + reach):
            return []
        s, dist2 = self._projection(px, py)
        hits = np.flatnonzero(dist2 < reach * reach)
        if len(hits) > 1:
            ends = hits[s[hits] >= 1.0]
            if len(ends):
                qx, qy = px - self.bx[ends], py - self.by[ends]
                dist2[ends] = qx * qx + qy * qy
            hits = hits[np.argsort(dist2[hits], kind="stable")]
        return hits.tolist()

    near = near_array


def reference_lines(static: StaticObstacles | None, moving: np.ndarray, px: float, py: float,
                    vx: float, vy: float, radius: float, max_speed: float, tau_obst: float,
                    tau: float, step: float, share: float) -> tuple[list[_Line], int]:
    """(lines, n_static): the float code's ORCA lines for checked floats."""
    lines: list[_Line] = []
    if static is not None:
        _static_lines(ReferenceEdges(static), px, py, vx, vy, radius, max_speed, tau_obst,
                      lines)
    n_static = len(lines)
    if len(moving):
        _moving_lines(np.asarray(moving, dtype=np.float64).tolist(), px, py, vx, vy, radius,
                      tau, step, share, lines)
    return lines, n_static


def _static_lines(edges: ReferenceEdges, px: float, py: float, vx: float, vy: float,
                  radius: float, max_speed: float, tau: float, lines: list[_Line]) -> None:
    """Append RVO2's obstacle lines for the edges near (px, py) (m) to ``lines``.

    RVO2's ``Agent::computeNewVelocity``, obstacle part: the edges within
    ``tau * max_speed + radius`` (m), nearest first, seen from their free side, go through
    the cases below in RVO2's order. The tests of each case stay here, inline, and only the
    case that applies is called: the loop is the hot path of the safety stack.
    """
    near = edges.near(px, py, tau * max_speed + radius)
    if not near:
        return
    xs, ys, nxt = edges.x, edges.y, edges.next
    inv_tau = 1.0 / tau
    rad2 = radius * radius
    rad_tau = radius * inv_tau  # cut-off radius (m/s)

    for first in near:
        second = nxt[first]
        # positions of the edge's end vertices relative to the anchor (m)
        x1, y1 = xs[first] - px, ys[first] - py
        x2, y2 = xs[second] - px, ys[second] - py
        ex, ey = x2 - x1, y2 - y1
        # back-face culling (RVO2's kd-tree query): the anchor must lie right of the edge
        if x1 * ey - y1 * ex >= 0.0:
            continue
        if lines and _already_covered(lines, x1 * inv_tau, y1 * inv_tau, x2 * inv_tau,
                                      y2 * inv_tau, rad_tau):
            continue

        dist2_1 = x1 * x1 + y1 * y1
        dist2_2 = x2 * x2 + y2 * y2
        # s: where the anchor projects on the edge (0 at the first vertex, 1 at the second)
        s = -(x1 * ex + y1 * ey) / (ex * ex + ey * ey)
        fx, fy = -x1 - s * ex, -y1 - s * ey
        dist2_line = fx * fx + fy * fy

        # the anchor already overlaps the edge: forbid moving deeper
        if s < 0.0 and dist2_1 <= rad2:
            _left_vertex_collision(edges, first, x1, y1, dist2_1, lines)
            continue
        if s >= 1.0 and dist2_2 <= rad2:
            _right_vertex_collision(edges, second, x2, y2, dist2_2, lines)
            continue
        if 0.0 <= s < 1.0 and dist2_line <= rad2:
            _segment_collision(edges, first, lines)
            continue

        # no collision: the velocity obstacle's legs, then the projection on it
        legs = _legs(edges, first, second, x1, y1, x2, y2, s, dist2_1, dist2_2, dist2_line,
                     radius, rad2)
        if legs is not None:
            _cutoff_projection(edges, *_foreign_legs(edges, *legs), px, py, vx, vy, inv_tau,
                               rad_tau, lines)


def _already_covered(lines: list[_Line], c1x: float, c1y: float, c2x: float, c2y: float,
                     rad_tau: float) -> bool:
    """RVO2's "already covered" test: do earlier lines forbid both cut-off discs (centres
    (c1x, c1y), (c2x, c2y), radius ``rad_tau``, m/s) of the edge entirely?"""
    for lx, ly, ldx, ldy in lines:
        if ((c1x - lx) * ldy - (c1y - ly) * ldx - rad_tau >= -_EPS
                and (c2x - lx) * ldy - (c2y - ly) * ldx - rad_tau >= -_EPS):
            return True
    return False


def _left_vertex_collision(edges: ReferenceEdges, first: int, x1: float, y1: float,
                           dist2_1: float, lines: list[_Line]) -> None:
    """RVO2's "collision with left vertex": the anchor overlaps the edge's first vertex (at
    (x1, y1) m from it, squared distance ``dist2_1``); a line through the origin forbids moving
    toward the vertex, unless it is non-convex (then it adds nothing)."""
    if edges.convex[first]:
        norm = math.sqrt(dist2_1)
        lines.append((0.0, 0.0, -y1 / norm, x1 / norm))


def _right_vertex_collision(edges: ReferenceEdges, second: int, x2: float, y2: float,
                            dist2_2: float, lines: list[_Line]) -> None:
    """RVO2's "collision with right vertex": the anchor overlaps the edge's second vertex (at
    (x2, y2) m); as the left-vertex case, but a non-convex vertex, or one the next edge handles,
    adds nothing."""
    if edges.convex[second] and x2 * edges.dy[second] - y2 * edges.dx[second] >= 0.0:
        norm = math.sqrt(dist2_2)
        lines.append((0.0, 0.0, -y2 / norm, x2 / norm))


def _segment_collision(edges: ReferenceEdges, first: int, lines: list[_Line]) -> None:
    """RVO2's "collision with obstacle segment": the anchor overlaps the edge's interior; a line
    through the origin along the reversed edge forbids moving toward it."""
    lines.append((0.0, 0.0, -edges.dx[first], -edges.dy[first]))


def _left_leg(x: float, y: float, dist2: float, radius: float,
              rad2: float) -> tuple[float, float]:
    """Unit direction of the left leg: from the anchor, tangent on the left to the disc of
    ``radius`` (m) around the vertex at (x, y) m (squared distance ``dist2``)."""
    leg = math.sqrt(max(dist2 - rad2, 0.0))
    return (x * leg - y * radius) / dist2, (x * radius + y * leg) / dist2


def _right_leg(x: float, y: float, dist2: float, radius: float,
               rad2: float) -> tuple[float, float]:
    """Unit direction of the right leg, tangent on the right (as :func:`_left_leg`)."""
    leg = math.sqrt(max(dist2 - rad2, 0.0))
    return (x * leg + y * radius) / dist2, (y * leg - x * radius) / dist2


def _legs(edges: ReferenceEdges, first: int, second: int, x1: float, y1: float, x2: float,
          y2: float, s: float, dist2_1: float, dist2_2: float, dist2_line: float, radius: float,
          rad2: float) -> tuple[int, int, float, float, float, float] | None:
    """RVO2's legs computation: (left vertex, right vertex, left leg, right leg) of the
    velocity obstacle, or None when the edge adds no line.

    "Obstacle viewed obliquely": when the anchor is within ``radius`` of the edge's line but
    projects beyond one end, that vertex alone defines the velocity obstacle (both legs are its
    tangents; a non-convex one gives None). "Usual situation": the left leg comes from the first
    vertex, the right leg from the second; at a non-convex vertex the leg continues the cut-off
    line (the edge's direction).
    """
    convex = edges.convex
    if s < 0.0 and dist2_line <= rad2:
        if not convex[first]:
            return None
        return (first, first, *_left_leg(x1, y1, dist2_1, radius, rad2),
                *_right_leg(x1, y1, dist2_1, radius, rad2))
    if s > 1.0 and dist2_line <= rad2:
        if not convex[second]:
            return None
        return (second, second, *_left_leg(x2, y2, dist2_2, radius, rad2),
                *_right_leg(x2, y2, dist2_2, radius, rad2))
    if convex[first]:
        llx, lly = _left_leg(x1, y1, dist2_1, radius, rad2)
    else:
        llx, lly = -edges.dx[first], -edges.dy[first]
    if convex[second]:
        rlx, rly = _right_leg(x2, y2, dist2_2, radius, rad2)
    else:
        rlx, rly = edges.dx[first], edges.dy[first]
    return first, second, llx, lly, rlx, rly


def _foreign_legs(edges: ReferenceEdges, left: int, right: int, llx: float, lly: float, rlx: float,
                  rly: float) -> tuple[int, int, float, float, float, float, bool, bool]:
    """RVO2's foreign-leg checks: a leg at a convex vertex may not point into the neighbouring
    edge; that edge's direction replaces it ("foreign" leg; projecting on it adds no line).

    Returns (left, right, left leg, right leg, left_foreign, right_foreign).
    """
    convex, dxs, dys = edges.convex, edges.dx, edges.dy
    left_foreign = right_foreign = False
    before = edges.prev[left]
    if convex[left] and llx * -dys[before] - lly * -dxs[before] >= 0.0:
        llx, lly = -dxs[before], -dys[before]
        left_foreign = True
    if convex[right] and rlx * dys[right] - rly * dxs[right] <= 0.0:
        rlx, rly = dxs[right], dys[right]
        right_foreign = True
    return left, right, llx, lly, rlx, rly, left_foreign, right_foreign


def _cutoff_projection(edges: ReferenceEdges, left: int, right: int, llx: float, lly: float,
                       rlx: float, rly: float, left_foreign: bool, right_foreign: bool,
                       px: float, py: float, vx: float, vy: float, inv_tau: float,
                       rad_tau: float, lines: list[_Line]) -> None:
    """RVO2's projection of the current velocity (vx, vy) (m/s) on the velocity obstacle.

    The cut-off centres are the left and right vertices over ``tau`` (m/s), with radius
    ``rad_tau``. The velocity projects on a cut-off circle when it lies behind the cut-off
    segment and behind the legs. Otherwise it projects on the nearest of the cut-off line, the
    left leg and the right leg; a foreign leg adds no line.
    """
    xs, ys = edges.x, edges.y
    # cut-off centres (m/s) and the cut-off segment between them
    lcx, lcy = (xs[left] - px) * inv_tau, (ys[left] - py) * inv_tau
    rcx, rcy = (xs[right] - px) * inv_tau, (ys[right] - py) * inv_tau
    cx, cy = rcx - lcx, rcy - lcy
    single = left == right
    wlx, wly = vx - lcx, vy - lcy
    t = 0.5 if single else (wlx * cx + wly * cy) / (cx * cx + cy * cy)
    t_left = wlx * llx + wly * lly
    wrx, wry = vx - rcx, vy - rcy
    t_right = wrx * rlx + wry * rly

    # project the current velocity on the velocity obstacle's boundary
    if (t < 0.0 and t_left < 0.0) or (single and t_left < 0.0 and t_right < 0.0):
        lines.append(_on_circle(wlx, wly, lcx, lcy, rad_tau))
        return
    if t > 1.0 and t_right < 0.0:
        lines.append(_on_circle(wrx, wry, rcx, rcy, rad_tau))
        return

    inf = math.inf
    if t < 0.0 or t > 1.0 or single:
        d2_cut = inf
    else:
        qx, qy = wlx - t * cx, wly - t * cy
        d2_cut = qx * qx + qy * qy
    if t_left < 0.0:
        d2_left = inf
    else:
        qx, qy = wlx - t_left * llx, wly - t_left * lly
        d2_left = qx * qx + qy * qy
    if t_right < 0.0:
        d2_right = inf
    else:
        qx, qy = wrx - t_right * rlx, wry - t_right * rly
        d2_right = qx * qx + qy * qy

    if d2_cut <= d2_left and d2_cut <= d2_right:
        # the cut-off line, shifted by the cut-off radius toward the anchor
        dx, dy = -edges.dx[left], -edges.dy[left]
        lines.append((lcx - rad_tau * dy, lcy + rad_tau * dx, dx, dy))
    elif d2_left <= d2_right:
        if not left_foreign:
            lines.append((lcx - rad_tau * lly, lcy + rad_tau * llx, llx, lly))
    elif not right_foreign:
        dx, dy = -rlx, -rly
        lines.append((rcx - rad_tau * dy, rcy + rad_tau * dx, dx, dy))


def _on_circle(wx: float, wy: float, cx: float, cy: float, rad: float) -> _Line:
    """Line tangent to the cut-off circle (centre (cx, cy), radius ``rad``, m/s) at the point
    nearest the velocity (cx + wx, cy + wy)."""
    norm = math.hypot(wx, wy)
    if norm > 0.0:
        ux, uy = wx / norm, wy / norm
    else:
        # velocity exactly at the centre (RVO2 divides by zero): the side facing the origin
        norm = math.hypot(cx, cy)
        ux, uy = (-cx / norm, -cy / norm) if norm > 0.0 else (-1.0, 0.0)
    return (cx + rad * ux, cy + rad * uy, uy, -ux)


def _moving_lines(rows: list[list[float]], px: float, py: float, vx: float, vy: float,
                  radius: float, tau: float, time_step: float, share: float,
                  lines: list[_Line]) -> None:
    """Append RVO2's agent lines for moving discs (nearest first) to ``lines``."""
    inv_tau = 1.0 / tau
    entries = []
    for ox, oy, ovx, ovy, orad in rows:
        rx, ry = ox - px, oy - py
        entries.append((rx * rx + ry * ry, rx, ry, vx - ovx, vy - ovy, radius + orad))
    entries.sort(key=lambda entry: entry[0])
    for dist2, rx, ry, wvx, wvy, rad in entries:
        rad2 = rad * rad
        if dist2 > rad2:
            # w: from the cut-off centre to the relative velocity
            wx, wy = wvx - rx * inv_tau, wvy - ry * inv_tau
            w2 = wx * wx + wy * wy
            dot = wx * rx + wy * ry
            if dot < 0.0 and dot * dot > rad2 * w2:
                # nearest boundary point on the cut-off circle
                w_len = math.sqrt(w2)
                ux, uy = wx / w_len, wy / w_len
                dx, dy = uy, -ux
                grow = rad * inv_tau - w_len
                ux, uy = grow * ux, grow * uy
            else:
                # nearest boundary point on a leg
                leg = math.sqrt(dist2 - rad2)
                if rx * wy - ry * wx > 0.0:
                    dx, dy = (rx * leg - ry * rad) / dist2, (rx * rad + ry * leg) / dist2
                else:
                    dx, dy = -(rx * leg + ry * rad) / dist2, (rx * rad - ry * leg) / dist2
                along = wvx * dx + wvy * dy
                ux, uy = along * dx - wvx, along * dy - wvy
        else:
            # overlapping: leave the cut-off circle of time time_step
            inv_step = 1.0 / time_step
            wx, wy = wvx - rx * inv_step, wvy - ry * inv_step
            w_len = math.hypot(wx, wy)
            if w_len > 0.0:
                ux, uy = wx / w_len, wy / w_len
            else:
                # relative velocity exactly at the centre: push straight away from the disc
                norm = math.hypot(rx, ry)
                ux, uy = (-rx / norm, -ry / norm) if norm > 0.0 else (-1.0, 0.0)
            dx, dy = uy, -ux
            grow = rad * inv_step - w_len
            ux, uy = grow * ux, grow * uy
        lines.append((vx + share * ux, vy + share * uy, dx, dy))


# --- the linear programs (Eq. 10) ---------------------------------------------------------
def _lp1(lines: list[_Line], k: int, speed: float, ox: float, oy: float,
         along_direction: bool) -> tuple[float, float] | None:
    """Best point on line k inside the speed disc and lines 0..k-1 (None if there is none):
    the extreme along (ox, oy) when ``along_direction``, else the nearest to (ox, oy)."""
    px, py, dx, dy = lines[k]
    mid = px * dx + py * dy
    disc = mid * mid + speed * speed - (px * px + py * py)
    if disc < 0.0:
        return None  # the speed disc misses the line
    half = math.sqrt(disc)
    lo, hi = -mid - half, -mid + half
    for i in range(k):
        qx, qy, ex, ey = lines[i]
        cross = dx * ey - dy * ex           # det(d_k, d_i)
        gap = ex * (py - qy) - ey * (px - qx)  # det(d_i, p_k - p_i)
        if -_PARALLEL <= cross <= _PARALLEL:
            if gap < -_SLACK:
                return None  # parallel, and line k lies entirely in line i's forbidden side
            continue
        cut = gap / cross
        if cross > 0.0:
            if cut < hi:
                hi = cut
        elif cut > lo:
            lo = cut
    if lo > hi:
        # empty interval; accept its middle when that is only round-off (a feasible set that
        # shrank to a point, e.g. lines through the origin), else there is no solution
        t = 0.5 * (lo + hi)
        x, y = px + t * dx, py + t * dy
        for i in range(k):
            qx, qy, ex, ey = lines[i]
            if ex * (qy - y) - ey * (qx - x) > _SLACK:
                return None
        return x, y
    if along_direction:
        t = hi if ox * dx + oy * dy > 0.0 else lo
    else:
        t = dx * (ox - px) + dy * (oy - py)
        t = lo if t < lo else hi if t > hi else t
    return px + t * dx, py + t * dy


def _lp2(lines: list[_Line], speed: float, ox: float, oy: float,
         along_direction: bool) -> tuple[int, float, float]:
    """RVO2's linearProgram2: (index of the first line that cannot be met, or len(lines); x, y).
    On failure (x, y) is the optimum of the lines before that index."""
    if along_direction:
        rx, ry = ox * speed, oy * speed
    elif ox * ox + oy * oy > speed * speed:
        scale = speed / math.hypot(ox, oy)
        rx, ry = ox * scale, oy * scale
    else:
        rx, ry = ox, oy
    for k in range(len(lines)):
        px, py, dx, dy = lines[k]
        if dx * (py - ry) - dy * (px - rx) > 0.0:
            better = _lp1(lines, k, speed, ox, oy, along_direction)
            if better is None:
                return k, rx, ry
            rx, ry = better
    return len(lines), rx, ry


def _lp3(lines: list[_Line], n_static: int, begin: int, speed: float, rx: float,
         ry: float) -> tuple[float, float]:
    """RVO2's linearProgram3: keep lines[:n_static] hard and minimise the largest violation of
    the others, starting from line ``begin`` with the partial result (rx, ry)."""
    depth = 0.0
    hard = lines[:n_static]
    for i in range(begin, len(lines)):
        px, py, dx, dy = lines[i]
        if dx * (py - ry) - dy * (px - rx) <= depth:
            continue
        # lines of equal violation of line i and each earlier relaxed line j
        projected = list(hard)
        for j in range(n_static, i):
            qx, qy, ex, ey = lines[j]
            cross = dx * ey - dy * ex
            if -_EPS <= cross <= _EPS:
                if dx * ex + dy * ey > 0.0:
                    continue  # same direction: line j adds nothing
                mx, my = 0.5 * (px + qx), 0.5 * (py + qy)
            else:
                along = (ex * (py - qy) - ey * (px - qx)) / cross
                mx, my = px + along * dx, py + along * dy
            nx, ny = ex - dx, ey - dy
            norm = math.hypot(nx, ny)
            projected.append((mx, my, nx / norm, ny / norm))
        fail, sx, sy = _lp2(projected, speed, -dy, dx, True)
        if fail == len(projected):
            rx, ry = sx, sy
        # else: round-off; keep the current result (as RVO2)
        depth = dx * (py - ry) - dy * (px - rx)
    return rx, ry


def reference_solve(lines: list[_Line], n_static: int, px: float, py: float,
                    max_speed: float) -> tuple[float, float]:
    """Eq. 10 in Python floats: linearProgram2, then 3 when it fails; a result beyond the speed
    disc by more than round-off (``_OVERSHOOT``, relative) is scaled back onto its circle."""
    fail, x, y = _lp2(lines, max_speed, px, py, False)
    if fail < len(lines):
        x, y = _lp3(lines, n_static, fail, max_speed, x, y)
    norm = math.hypot(x, y)
    if norm > max_speed * (1.0 + _OVERSHOOT):
        x, y = x * (max_speed / norm), y * (max_speed / norm)
    return x, y
