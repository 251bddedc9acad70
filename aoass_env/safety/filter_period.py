"""One period of the fuzzy-ORCA velocity filter's compiled part in one call.

:class:`~aoass_env.wrappers.FuzzyORCASafety` turns the preferred velocity into a command in
four compiled steps, each behind a few lines of Python that check and convert its inputs:
ORCA's lines and velocity (:meth:`OrcaAgent.velocity <aoass_env.safety.orca.OrcaAgent.
velocity>`), the static edges of the braking envelope (:meth:`StaticObstacles.segments_near
<aoass_env.safety.orca.StaticObstacles.segments_near>`), the unicycle's command on the ORCA
lines (:func:`~aoass_env.safety.unicycle.unicycle_command`) and the constraints active at v*
(:func:`~aoass_env.safety.orca.active_constraints`). :func:`filter_period` runs the same
compiled functions on the same floats in one call, for the periods where nothing else decides:

- no moving-obstacle line while the look-ahead is on (otherwise the look-ahead may replace
  v*: the wrapper's own path runs);
- the ORCA lines alone decide the command (``unicycle_command``'s compiled path; otherwise the
  braking envelope's caps are computed from NumPy's products: the wrapper's own path runs).

Elsewhere it returns ``done = False`` and the wrapper takes its own path, which gives the same
floats (tests/safety/test_filter_period.py). It is used only where the compiled
trigonometry, ``atan2`` and ``hypot`` are ``math``'s (:func:`fused`).
"""

from __future__ import annotations

import numpy as np

from aoass_env.jit import njit
from aoass_env.safety.checks import finite
from aoass_env.safety.orca import (
    OrcaAgent,
    OrcaLines,
    StaticObstacles,
    _active,
    _lines_and_velocity,
    _moving,
    _near_compiled,
    _read_only_lines,
)
from aoass_env.safety.unicycle import _compiled_command
from aoass_env.trig import SCALAR_TRIG, compiled_polar, compiled_trig

__all__ = ["PeriodSettings", "filter_period", "fused", "orca_lines_of"]

#: The slack (m/s) within which v* counts as on a constraint (``info["safety"]["active"]``).
ACTIVE_SLACK = 1e-6


def fused() -> bool:
    """Whether :func:`filter_period` gives the wrapper's floats here: the compiled
    trigonometry, ``atan2`` and ``hypot`` are ``math``'s (probed once per process)."""
    return SCALAR_TRIG and compiled_trig() and compiled_polar()


class PeriodSettings:
    """The settings of :func:`filter_period` that stay the same period after period, as one
    read-only float64 array (``values``): the ORCA agent's (radius, speed limit, horizons,
    control period, share), the anchor's turn (rad) and speed change (m/s) in a period, the
    braking envelope's reach (m), its disc radius (m), braking (m/s^2) and period (s).

    Args:
        agent: the anchor's ORCA settings (its radius is the braking envelope's too).
        max_turn: the most the anchor turns in one control period (rad).
        max_dv: the most its speed changes in one control period (m/s).
        reach: how far (m) from the anchor the braking envelope's edges are taken.
        max_accel: the anchor's deceleration limit (m/s^2).
        dt: the control period (s).
    """

    def __init__(self, agent: OrcaAgent, *, max_turn: float, max_dv: float, reach: float,
                 max_accel: float, dt: float) -> None:
        self.values = np.array([agent.radius, agent.max_speed, agent.time_horizon_obst,
                                agent.time_horizon, agent.time_step, agent.responsibility,
                                max_turn, max_dv, reach, max_accel, dt], dtype=np.float64)
        self.values.flags.writeable = False


@njit
def _discs_ok(moving: np.ndarray) -> bool:
    """Are the (k, 5) discs ``moving`` [x, y, vx, vy, radius] finite, with radii >= 0?"""
    if not finite(moving):
        return False
    for i in range(moving.shape[0]):
        if moving[i, 4] < 0.0:
            return False
    return True


@njit
def _period(edges: np.ndarray, links: np.ndarray, bbox: np.ndarray, grid: np.ndarray,
            cells: np.ndarray, point: np.ndarray, nxt: np.ndarray, moving: np.ndarray,
            settings: np.ndarray, px: float, py: float, vx: float, vy: float, ox: float,
            oy: float, heading: float, speed: float, fallback_heading: float,
            look_ahead: bool
            ) -> tuple[bool, np.ndarray, int, float, float, float, float, int, int]:
    """:func:`filter_period` on the static obstacles' tables."""
    radius, max_speed, tau_obst, tau, step, share = (settings[0], settings[1], settings[2],
                                                     settings[3], settings[4], settings[5])
    max_turn, max_dv, reach, max_accel, dt = (settings[6], settings[7], settings[8],
                                              settings[9], settings[10])
    lines, n_static, sx, sy = _lines_and_velocity(edges, links, bbox, grid, cells, px, py, vx,
                                                  vy, radius, max_speed, tau_obst, moving,
                                                  tau, step, share, ox, oy)
    if look_ahead and lines.shape[0] > n_static:
        return False, lines, n_static, sx, sy, 0.0, 0.0, 0, 0
    near = _near_compiled(edges, bbox, grid, cells, px, py, reach)
    starts = np.empty((near.shape[0], 2))
    ends = np.empty((near.shape[0], 2))
    for i in range(near.shape[0]):
        j = near[i]
        starts[i, 0], starts[i, 1] = point[j, 0], point[j, 1]
        ends[i, 0], ends[i, 1] = point[nxt[j], 0], point[nxt[j], 1]
    done, speed_cmd, heading_cmd, _, _, _, _ = _compiled_command(
        sx, sy, heading, speed, max_turn, max_dv, lines[:, :2], lines[:, 2:], fallback_heading,
        starts, ends, px, py, radius, max_accel, dt)
    if not done:
        return False, lines, n_static, sx, sy, 0.0, 0.0, 0, 0
    active, active_static = _active(lines, n_static, sx, sy, ACTIVE_SLACK)
    return True, lines, n_static, sx, sy, speed_cmd, heading_cmd, active, active_static


def filter_period(static: StaticObstacles, moving: np.ndarray | None, settings: PeriodSettings,
                  position: tuple[float, float], velocity: tuple[float, float],
                  preferred: tuple[float, float], heading: float, speed: float,
                  fallback_heading: float, look_ahead: bool
                  ) -> tuple[bool, np.ndarray, int, float, float, float, float, int, int]:
    """(done, lines, static lines, v*x, v*y, speed, heading, active, active static): ORCA's
    lines (n, 4) rows [px, py, dx, dy] (static lines first) and velocity v* (m/s) closest to
    ``preferred`` (m/s) for the anchor at ``position`` (m) moving at ``velocity`` (m/s) among
    ``static`` and the ``moving`` (k, 5) discs [x, y, vx, vy, radius] (m, m/s, m; checked as
    ORCA checks them; None: none), the unicycle's command (m/s, rad) for v* from ``heading``
    (rad) and ``speed`` (m/s) under the braking envelope of the edges within ``settings``'
    reach (``fallback_heading``, rad, for a v* of almost zero), and how many of the lines, and
    of the static ones, are active at v* (within :data:`ACTIVE_SLACK`). Not ``done`` (speed,
    heading and the active counts 0) where the look-ahead (``look_ahead`` on and a moving
    obstacle's line) or the braking envelope's caps decide: the caller runs its own path from
    the lines (:func:`orca_lines_of`) and v*. Only where :func:`fused` holds.

    Raises:
        ValueError: ``moving`` of another shape, not finite, or with a negative radius.
    """
    # the wrapper's (k, 5) float64 tracks pass a compiled check (about 1 us a period, where
    # ORCA's own check costs about 9); anything else, or a bad row, goes to ORCA's check and
    # its messages
    rows = (moving if type(moving) is np.ndarray and moving.dtype == np.float64
            and moving.ndim == 2 and moving.shape[1] == 5 and moving.shape[0] > 0
            and _discs_ok(moving) else _moving(moving))
    cache = static._cache
    return _period(cache.edges, cache.links, cache.bbox, cache.grid, cache.cells, static.point,
                   static.next, rows, settings.values, position[0], position[1],
                   velocity[0], velocity[1], preferred[0], preferred[1], heading, speed,
                   fallback_heading, look_ahead)


def orca_lines_of(rows: np.ndarray, n_static: int) -> OrcaLines:
    """The ORCA lines of :func:`filter_period`'s ``rows`` and ``n_static``, as
    :meth:`OrcaAgent.velocity <aoass_env.safety.orca.OrcaAgent.velocity>` returns them (the
    rows made read-only): for a period handed back."""
    return _read_only_lines(rows, n_static)
