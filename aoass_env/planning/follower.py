"""Nominal path follower: (speed, heading) commands that track a waypoint list.

The follower is the zero-action behaviour of the environment (docs/interpretations.md): it steers
toward the next waypoint that is not blocked, skipping waypoints inside obstacles and resuming the
path after them (Section 3.3 of the paper). When an obstacle stands between the anchor and its
target, an optional :class:`~aoass_env.planning.detour.DetourPlanner` supplies intermediate points
around it; without a planner the follower steers straight (and relies on a safety layer).

A progress watchdog gets the follower out of traps (a wedge, a pocket, a passage a moving
obstacle blocks, or a safety layer that will not let it through): when its distance to go along
its plan has not shrunk by ``watchdog_progress`` metres for ``watchdog_time`` seconds, it marks
the spot as a keep-out, backs out along its own track, and re-plans around the keep-outs through
the known static map. A target that still cannot be reached after :data:`MAX_RECOVERIES` tries,
or one a stuck follower is already beside, is given up and recorded in ``skipped``, as is a
target with no path from the field and one past its stall timer. When the planner finds no path
because the anchor itself stands where it reaches nothing (its grid cell is shut in a pocket,
e.g. after an escape into a narrow passage), the follower backs out along its track to where the
field is reachable and plans again (one of the target's tries), rather than give up every
remaining waypoint at once. Optionally (``replan_excess``) a re-plan round the keep-outs that
is much longer than the plain way is not taken: a target the follower got stuck on is given up
(``"long re-plan"``), any other target (keep-outs left by an earlier one) takes the plain way.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from aoass_env.config import AOASSConfig
from aoass_env.planning.detour import DetourPlanner
from aoass_env.validators import positive, real

#: Radius (m) around a spot where the follower got stuck that its re-plans avoid, and how long
#: (s) the keep-out lasts (a moving obstacle parked in a passage may leave).
KEEPOUT_RADIUS = 1.5
KEEPOUT_TIME = 60.0
#: Back-outs tried for one target before the follower gives it up.
MAX_RECOVERIES = 2
#: The follower remembers its track as points this far apart (m), up to TRAIL_POINTS of them.
TRAIL_SPACING = 0.5
TRAIL_POINTS = 200
# Relative band around a threshold inside which :func:`_within` asks numpy's hypot; outside it
# the squared distance decides (it is within a few ulps of the true one).
_BAND = 1e-9


def _within(dx: float, dy: float, radius: float) -> bool:
    """``np.hypot(dx, dy) <= radius`` for floats, without numpy unless the squared distance
    lies within a relative 1e-9 of ``radius**2`` (then numpy decides: the same answer)."""
    d2, r2 = dx * dx + dy * dy, radius * radius
    if d2 < r2 * (1.0 - _BAND):
        return True
    if d2 > r2 * (1.0 + _BAND):
        return False
    return bool(np.hypot(dx, dy) <= radius)


#: No keep-out in force (read-only).
_NO_KEEPOUT = np.zeros((0, 2))
_NO_KEEPOUT.flags.writeable = False


def _reaches(dx: float, dy: float, radius: float) -> bool:
    """``np.hypot(dx, dy) >= radius`` for floats, as :func:`_within` decides."""
    d2, r2 = dx * dx + dy * dy, radius * radius
    if d2 > r2 * (1.0 + _BAND):
        return True
    if d2 < r2 * (1.0 - _BAND):
        return False
    return bool(np.hypot(dx, dy) >= radius)


def _pairwise_sum(values: list[float], lo: int, n: int) -> float:
    """NumPy's sum of the float64 ``values[lo:lo + n]`` (its pairwise summation: in order
    below 8 numbers, 8 accumulators up to 128, halves above), the same float."""
    if n < 8:
        total = 0.0
        for i in range(lo, lo + n):
            total += values[i]
        return total
    if n <= 128:
        r0, r1, r2, r3, r4, r5, r6, r7 = values[lo:lo + 8]
        i, stop = lo + 8, lo + n - n % 8
        while i < stop:
            r0 += values[i]
            r1 += values[i + 1]
            r2 += values[i + 2]
            r3 += values[i + 3]
            r4 += values[i + 4]
            r5 += values[i + 5]
            r6 += values[i + 6]
            r7 += values[i + 7]
            i += 8
        total = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        for j in range(i, lo + n):
            total += values[j]
        return total
    half = n // 2
    half -= half % 8
    return _pairwise_sum(values, lo, half) + _pairwise_sum(values, lo + half, n - half)


def _numpy_sums_pairwise() -> bool:
    """Whether :func:`_pairwise_sum` gives ``np.sum``'s floats on this machine (probed at
    import on random lengths; the follower's path lengths use NumPy otherwise)."""
    rng = np.random.default_rng(20)
    for n in (*range(1, 41), 63, 64, 127, 128, 129, 200, 300):
        for _ in range(4):
            x = rng.exponential(1.0, n) * 10.0 ** rng.uniform(-3.0, 3.0, n)
            if _pairwise_sum(x.tolist(), 0, n) != float(x.sum()):
                return False
    return True


#: see :func:`_numpy_sums_pairwise`
PAIRWISE_SUM = _numpy_sums_pairwise()


def _polyline_length(points: list) -> float:
    """``float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())`` for a list of (2,)
    points, in plain floats (the same float: each leg is sqrt(dx*dx + dy*dy), and the legs are
    summed as NumPy sums them, :func:`_pairwise_sum`); NumPy's own code for more than seven
    legs when the import-time probe finds the sums differ."""
    if len(points) <= 8 or PAIRWISE_SUM:
        if len(points) > 4:
            coords = np.array(points, dtype=np.float64).tolist()
        else:
            coords = [(float(x), float(y)) for x, y in points]
        legs = []
        (x0, y0), sqrt = coords[0], math.sqrt
        for x1, y1 in coords[1:]:
            dx, dy = x1 - x0, y1 - y0
            legs.append(sqrt(dx * dx + dy * dy))
            x0, y0 = x1, y1
        return _pairwise_sum(legs, 0, len(legs))
    return float(np.linalg.norm(np.diff(np.array(points), axis=0), axis=1).sum())


@dataclass(frozen=True)
class Skip:
    """A waypoint the follower gave up: its index, the time (s, follower clock) and why:
    ``"no path"`` (the planner finds none), ``"stall timer"`` (not reached in its time),
    ``"stuck"`` (the watchdog fired ``MAX_RECOVERIES`` + 1 times, or beside the target) or
    ``"long re-plan"`` (its re-plan round the keep-outs exceeds ``replan_excess``)."""

    index: int
    time: float
    reason: str


@dataclass
class WaypointFollower:
    """Tracks progress along ``waypoints`` (W, 2) with a ``blocked`` (W,) mask.

    Args:
        waypoints: positions (m).
        blocked: waypoints to skip.
        capture_radius: a waypoint counts as reached within this distance (m).
        cruise_speed: commanded speed on straight stretches (m/s).
        max_accel: the anchor's deceleration limit (m/s^2), used to brake ahead of sharp turns.
        stall_time: a target (spiral or detour point) not reached within this time (s) is
            skipped, so a follower pushed against an obstacle does not wait forever.
        stall_travel: the time allowed for a waypoint also grows by twice the straight
            travel time from the previous one (for sparse waypoints, such as a pruned spiral's,
            whose next one may lie farther than ``stall_time`` allows).
        planner: detour planner used when the straight line to the target is obstructed.
        watchdog_time: seconds without ``watchdog_progress`` metres of progress along the plan
            after which the follower is stuck (inf: no watchdog).
        watchdog_progress: progress (m) that resets the watchdog.
        backout_distance: how far back along its track a stuck follower retreats (m).
        replan_excess: a re-plan round the keep-outs longer than the plain path to the target
            by more than this (m) is not taken: the target is given up when the follower got
            stuck on it, else the plain path is taken (inf: always taken).

    Attributes:
        recoveries: back-outs so far.
        skipped: the free waypoints given up so far (:class:`Skip`).
    """

    waypoints: np.ndarray
    blocked: np.ndarray
    capture_radius: float
    cruise_speed: float
    max_accel: float = math.inf
    stall_time: float = 30.0
    stall_travel: bool = False
    planner: DetourPlanner | None = None
    watchdog_time: float = math.inf
    watchdog_progress: float = 1.0
    backout_distance: float = 3.0
    replan_excess: float = math.inf
    index: int = 0
    recoveries: int = 0
    skipped: list[Skip] = field(default_factory=list)
    _clock: float = 0.0
    _budget: float = 0.0
    _planned: bool = False
    _detour: list[np.ndarray] = field(default_factory=list)
    _way_on: tuple[tuple[float, float, float, float] | None, bool] = (None, True)
    _trail: deque[np.ndarray] = field(default_factory=lambda: deque(maxlen=TRAIL_POINTS))
    _keepout: list[tuple[np.ndarray, float]] = field(default_factory=list)
    _backout: list[np.ndarray] = field(default_factory=list)
    _best: float = math.inf
    _best_time: float = 0.0
    _tries: int = 0

    def __post_init__(self) -> None:
        w = self.waypoints
        if not (isinstance(w, np.ndarray) and w.ndim == 2 and w.shape[1] == 2
                and w.dtype.kind in "iuf" and np.isfinite(w).all()):
            raise ValueError(f"waypoints must be a finite (W, 2) array of numbers (m), got "
                             f"{type(w).__name__} {getattr(w, 'shape', '')}")
        if np.shape(self.blocked) != (len(w),):
            raise ValueError(f"blocked must be a (W,) mask, one flag per waypoint (W={len(w)}), "
                             f"got shape {np.shape(self.blocked)}")
        real("capture_radius", self.capture_radius, "m", low=0.0)
        positive("cruise_speed", self.cruise_speed, "m/s")
        for name, unit in (("max_accel", "m/s^2"), ("stall_time", "s"), ("watchdog_time", "s")):
            value = getattr(self, name)       # inf: no limit
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
                raise ValueError(f"{name}={value!r} must be a number > 0 {unit} (inf: none)")
        for name in ("watchdog_progress", "backout_distance"):
            real(name, getattr(self, name), "m", low=0.0)
        if not self.replan_excess >= 0:
            raise ValueError(f"replan_excess={self.replan_excess!r} must be a number >= 0 m "
                             f"(inf: none)")
        self.index = self._next_free(self.index)
        self._budget = self.stall_time

    @classmethod
    def nominal(cls, config: AOASSConfig, waypoints: np.ndarray, blocked: np.ndarray | None = None,
                planner: DetourPlanner | None = None, start: int = 0,
                recovery: bool = False, stall_time: float = 30.0) -> WaypointFollower:
        """The nominal follower of ``config``: cruise at ``anchor_nominal_speed``, brake within
        ``anchor_max_accel``, and capture a waypoint within the anchor radius or half a control
        period's travel, whichever is larger; ``blocked`` None: no waypoint is skipped; the
        waypoints before ``start`` are skipped; ``recovery``: get out of traps with the config's
        progress watchdog (``watchdog_time``, ``watchdog_progress``, ``backout_distance``,
        ``replan_excess``),
        else rely on the stall timer alone (``stall_time``, s)."""
        wps = np.asarray(waypoints, dtype=np.float64)
        return cls(wps, np.zeros(len(wps), dtype=bool) if blocked is None else blocked,
                   capture_radius=max(config.anchor_radius,
                                      0.5 * config.anchor_nominal_speed * config.dt),
                   cruise_speed=config.anchor_nominal_speed, max_accel=config.anchor_max_accel,
                   stall_time=stall_time, planner=planner,
                   watchdog_time=config.watchdog_time if recovery else math.inf,
                   watchdog_progress=config.watchdog_progress,
                   backout_distance=config.backout_distance,
                   replan_excess=(math.inf if config.replan_excess is None or not recovery
                                  else config.replan_excess), index=start)

    @property
    def done(self) -> bool:
        """True once every waypoint has been reached or skipped."""
        return self.index >= len(self.waypoints)

    @property
    def target(self) -> np.ndarray | None:
        """The waypoint currently steered to, or None when done."""
        return None if self.done else self.waypoints[self.index]

    def progress(self) -> float:
        """Fraction of waypoints reached or skipped, in [0, 1]."""
        return min(self.index, len(self.waypoints)) / len(self.waypoints)

    def _next_free(self, i: int) -> int:
        while i < len(self.waypoints) and self.blocked[i]:
            i += 1
        return i

    def _advance(self) -> None:
        last = self.index
        self.index = self._next_free(self.index + 1)
        self._budget = self._clock + self.stall_time
        if self.stall_travel and not self.done:
            hop = self.waypoints[self.index] - self.waypoints[last]
            self._budget += 2.0 * math.hypot(hop[0], hop[1]) / self.cruise_speed
        self._planned = False
        self._detour.clear()
        self._tries = 0
        self._reset_watchdog()

    def pass_target(self) -> None:
        """Leave the current target unvisited by choice (a coverage-aware sweep's skip) and
        steer to the next free waypoint; not recorded in ``skipped``."""
        if not self.done:
            self._backout.clear()
            self._advance()

    def _give_up(self, reason: str) -> None:
        self.skipped.append(Skip(self.index, self._clock, reason))
        self._advance()

    def command(self, position: np.ndarray, heading: float, dt: float) -> tuple[float, float]:
        """(speed [m/s], heading [rad]) toward the current target after advancing past reached
        waypoints. ``heading`` (rad) is the anchor's current heading: the speed is scaled by the
        cosine of the heading error (zero beyond 90 deg, so sharp turns happen in place);
        ``dt`` (s) is the time since the last call, for stall detection and the watchdog.

        With a planner, an obstructed target gets one detour (intermediate points, then the
        target); the time allowed for the target grows by twice the detour's travel time.
        A stuck follower backs out along its track first (module docstring).
        """
        self._clock += dt
        px, py = float(position[0]), float(position[1])
        if not self._trail or _reaches(float(self._trail[-1][0]) - px,
                                       float(self._trail[-1][1]) - py, TRAIL_SPACING):
            self._trail.append(np.array(position, dtype=np.float64))
        if self._backout:
            if self._backing_out(position):
                return self._steer(position, heading, self._backout[0], None)
        capture = self.capture_radius
        waypoints, count = self.waypoints, len(self.waypoints)
        while self.index < count:
            target = waypoints[self.index]
            tx, ty = target.tolist()
            if _within(tx - px, ty - py, capture):
                self._advance()
                continue
            if self._clock > self._budget:
                self._give_up("stall timer")
                continue
            while self._detour and _within(float(self._detour[0][0]) - px,
                                           float(self._detour[0][1]) - py, capture):
                self._detour.pop(0)
            if self.planner is None or self._planned or self._clear(position, target):
                break
            keepout = self._active_keepouts(position)
            path = self.planner.path(position, target, keepout, KEEPOUT_RADIUS)
            plain = (self._plain_instead(position, target, path)
                     if path is not None and len(keepout) else None)
            if plain is not None:
                if self._tries:     # stuck on this target: give it up
                    self._give_up("long re-plan")
                    continue
                path = plain        # the keep-outs are an earlier target's
            if path is None:
                if self._rejoin(position):  # shut in where the planner reaches nothing
                    return self.command(position, heading, 0.0)
                self._give_up("no path")    # unreachable from the field, as if in an obstacle
                continue
            self._planned = True
            self._detour = list(path[1:-1])
            length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
            self._budget = self._clock + self.stall_time + 2.0 * length / self.cruise_speed
            self._reset_watchdog()
            break
        if self.index >= count:
            return 0.0, 0.0
        if self._detour:
            to_go = self._to_go(position)
        else:   # _to_go's one leg (0.0 + the leg: the same float)
            dx, dy = tx - px, ty - py
            to_go = math.sqrt(dx * dx + dy * dy)
        if self._stalled(to_go):
            self._stuck(position)
            return self.command(position, heading, 0.0)
        aim, after = self._aim_points()
        return self._steer(position, heading, aim, after)

    def _steer(self, position: np.ndarray, heading: float, aim: np.ndarray,
               after: np.ndarray | None) -> tuple[float, float]:
        """Cruise toward ``aim``, slowed by the heading error and braked so that the speed at
        ``aim`` suits the turn toward ``after`` (a stop when that leg is obstructed)."""
        ax, ay = aim.tolist()
        dx, dy = ax - float(position[0]), ay - float(position[1])
        bearing = math.atan2(dy, dx)
        speed = self.cruise_speed * max(0.0, math.cos(bearing - heading))
        if after is not None:
            # brake so that the speed at the aim point suits the turn there
            bx, by = after.tolist()
            ox, oy = bx - ax, by - ay
            turn = math.atan2(oy, ox) - bearing
            corner_speed = self.cruise_speed * max(0.0, math.cos(turn))
            if not self._way_on_open(aim, after, (ax, ay, bx, by)):
                corner_speed = 0.0      # the way on is obstructed: stop there to replan
            room = max(0.0, math.hypot(dx, dy) - self.capture_radius)
            speed = min(speed, math.sqrt(corner_speed**2 + 2.0 * self.max_accel * room))
        return speed, bearing

    # --- watchdog and recovery -----------------------------------------------------------
    def _reset_watchdog(self) -> None:
        self._best, self._best_time = math.inf, self._clock

    def _stalled(self, to_go: float) -> bool:
        """Feed the watchdog the distance to go (m); True when it has not shrunk by
        ``watchdog_progress`` for ``watchdog_time`` seconds."""
        if to_go < self._best - self.watchdog_progress or self._best == math.inf:
            self._best, self._best_time = to_go, self._clock
            return False
        return self._clock - self._best_time > self.watchdog_time

    def _to_go(self, position: np.ndarray) -> float:
        """Distance (m) from ``position`` along the plan (detour points, then the target)."""
        return _polyline_length([position, *self._detour, self.waypoints[self.index]])

    def _stuck(self, position: np.ndarray) -> None:
        """The watchdog fired at ``position``: keep re-plans away from it; give the target up
        when the follower is beside it or has tried ``MAX_RECOVERIES`` times, and back out
        along the track (unless beside the target)."""
        self._keepout.append((np.array(position, dtype=np.float64),
                              self._clock + KEEPOUT_TIME))
        self._tries += 1
        beside = np.hypot(*(self.waypoints[self.index] - position)) <= KEEPOUT_RADIUS
        if beside or self._tries > MAX_RECOVERIES:
            self._give_up("stuck")
        else:
            self._planned = False
            self._detour.clear()
        if not beside:
            self._backout = self._retreat(position)
            self.recoveries += 1
        self._reset_watchdog()

    def _plain_instead(self, position: np.ndarray, target: np.ndarray, path: np.ndarray
                       ) -> np.ndarray | None:
        """The plain path from ``position`` to ``target`` when ``path`` (round the keep-outs)
        is longer than it by more than ``replan_excess`` (m), else None."""
        if self.replan_excess == math.inf:
            return None
        plain = self.planner.path(position, target)
        if plain is None or (_polyline_length(list(path))
                             <= _polyline_length(list(plain)) + self.replan_excess):
            return None
        return plain

    def _rejoin(self, position: np.ndarray) -> bool:
        """No path to the target from ``position``: when the planner sees ``position`` shut
        in a pocket (its grid cell lies outside the largest connected free region, e.g. where an
        escape from a moving obstacle pushed the anchor into a narrow passage), no target can be
        planned from there, so the target is not to blame: back out along the track to the
        newest point from which the field is reachable and ``backout_distance`` on (a back-out
        ends within the capture radius of its last point), as one of the target's tries. False
        (the target is given up) when ``position`` is in the field (the target is unreachable),
        no remembered point is, or the tries are spent."""
        if self._tries >= MAX_RECOVERIES or self.planner.can_start(position, 0.0):
            return False
        back: list[np.ndarray] = []
        field_at = None
        for point in reversed(self._trail):
            back.append(point)
            if field_at is None:
                if self.planner.can_start(point, 0.0):
                    field_at = point
            elif np.hypot(*(point - field_at)) >= self.backout_distance:
                break
        if field_at is None:
            return False
        self._tries += 1
        self.recoveries += 1
        self._backout = back
        self._reset_watchdog()
        return True

    def _retreat(self, position: np.ndarray) -> list[np.ndarray]:
        """The remembered track back from ``position`` (newest first) up to the first point
        ``backout_distance`` (m) away, or the whole track when it is shorter."""
        back: list[np.ndarray] = []
        for point in reversed(self._trail):
            back.append(point)
            if np.hypot(*(point - position)) >= self.backout_distance:
                break
        return back

    def _backing_out(self, position: np.ndarray) -> bool:
        """Advance along the back-out; False (and the back-out ends, the target is planned
        afresh) once it is done or the watchdog fires on it."""
        px, py = float(position[0]), float(position[1])
        while self._backout and _within(float(self._backout[0][0]) - px,
                                        float(self._backout[0][1]) - py, self.capture_radius):
            self._backout.pop(0)
        if self._backout:
            if not self._stalled(_polyline_length([position, *self._backout])):
                return True
        self._backout.clear()
        self._planned = False
        self._detour.clear()
        self._budget = max(self._budget, self._clock + self.stall_time)
        self._reset_watchdog()
        return False

    def _active_keepouts(self, position: np.ndarray) -> np.ndarray:
        """(P, 2) keep-outs still in force, less those ``position`` lies in (a follower cannot
        avoid the spot it stands on)."""
        if not self._keepout:
            return _NO_KEEPOUT
        self._keepout = [(p, until) for p, until in self._keepout if until >= self._clock]
        pts = [p for p, _ in self._keepout if np.hypot(*(p - position)) > KEEPOUT_RADIUS]
        return np.array(pts).reshape(-1, 2)

    def _clear(self, a: np.ndarray, b: np.ndarray) -> bool:
        """Whether the straight move a -> b is free of obstacles (the planner's disc) and of
        the keep-outs in force."""
        if not self.planner.visible(a, b):
            return False
        keepout = self._active_keepouts(a)
        if not len(keepout):
            return True
        ab = b - a
        t = np.clip((keepout - a) @ ab / max(float(ab @ ab), 1e-12), 0.0, 1.0)
        gaps = np.hypot(*(a + t[:, None] * ab - keepout).T)
        return bool(np.all(gaps > KEEPOUT_RADIUS))

    def _way_on_open(self, aim: np.ndarray, after: np.ndarray,
                     key: tuple[float, float, float, float]) -> bool:
        """Whether the leg aim -> after is free; one planner query per leg (``key``: its end
        points' coordinates), not per step."""
        if self.planner is None:
            return True
        if self._way_on[0] != key:
            self._way_on = (key, self.planner.visible(aim, after))
        return self._way_on[1]

    def _aim_points(self) -> tuple[np.ndarray, np.ndarray | None]:
        """The point steered to and the one after it (None at the end of the path)."""
        queue = self._detour + [self.waypoints[self.index]]
        if len(queue) > 1:
            return queue[0], queue[1]
        nxt = self._next_free(self.index + 1)
        return queue[0], (self.waypoints[nxt] if nxt < len(self.waypoints) else None)
