"""The observation of AOASS-v0: layout, bounds and how it is read off the simulation.

The observation is one float32 vector; :func:`observation_layout` maps each part's name to its
slice (``env.unwrapped.obs_layout``). Every entry is normalised into [-1, 1] or [0, 1]:

=====================  ======  ==========================================================
name                   size    content (scale)
=====================  ======  ==========================================================
``position``           2       anchor x, y / field size                      [0, 1]
``speed``              1       anchor speed / ``anchor_max_speed``            [0, 1]
``d_obs``              1       gap to the nearest obstacle / ``sensing_range`` [0, 1]
``heading_error``      1       follower's heading - anchor heading, / pi      [-1, 1]
``heading``            2       cos, sin of the anchor heading                 [-1, 1]
``waypoints``          2K      next K free spiral waypoints - anchor, / (K x waypoint step),
                               clipped; the last one repeated near the end    [-1, 1]
``rays``               n_rays  range-sensor distances / ``sensing_range``     [0, 1]
``moving_obstacles``   5M      per slot: dx, dy / ``sensing_range``; vx, vy / speed scale;
                               present (1/0); nearest first, empty slots 0    [-1, 1]
``coverage``           1       Eq. 18 coverage ratio                          [0, 1]
``progress``           1       fraction of spiral waypoints reached or skipped [0, 1]
``time``               1       elapsed steps / episode step limit             [0, 1]
``coverage_sectors``   S       mean coverage deficit of the anchor's coverage map within 2 R,
                               by bearing sector from the heading (S =
                               ``obs_coverage_sectors``; absent when 0)       [0, 1]
``area_coverage``      1       the coverage map's covered share of the free field (with
                               the sectors)                                   [0, 1]
=====================  ======  ==========================================================

The first five entries are Eq. 6's state s = [x, y, v, d_obs, dtheta]. Moving obstacles are seen
when their centre is within ``sensing_range`` of the anchor; their relative position and velocity
carry Gaussian noise (``obs_position_noise`` m, ``obs_velocity_noise`` m/s) so that a tracker
(the Kalman wrapper) has something to filter. The speed scale is the larger of the obstacles'
and the anchor's maximum speed.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np
from gymnasium import spaces

from aoass_env.config import AOASSConfig
from aoass_env.jit import njit
from aoass_env.planning import CoverageMap
from aoass_env.world import World

__all__ = ["MOVING_FIELDS", "Observer", "clip_like_numpy", "observation_layout",
           "observation_space", "velocity_scale"]

#: Fields of one moving-obstacle slot.
MOVING_FIELDS = ("dx", "dy", "vx", "vy", "present")


def _sizes(config: AOASSConfig) -> list[tuple[str, int, float]]:
    """(name, size, lower bound) of each part, in order; upper bounds are all 1."""
    return [("position", 2, 0.0), ("speed", 1, 0.0), ("d_obs", 1, 0.0),
            ("heading_error", 1, -1.0), ("heading", 2, -1.0),
            ("waypoints", 2 * config.obs_waypoints, -1.0), ("rays", config.n_rays, 0.0),
            ("moving_obstacles", len(MOVING_FIELDS) * config.obs_moving_obstacles, -1.0),
            ("coverage", 1, 0.0), ("progress", 1, 0.0), ("time", 1, 0.0)] + (
        [("coverage_sectors", config.obs_coverage_sectors, 0.0), ("area_coverage", 1, 0.0)]
        if config.obs_coverage_sectors else [])


def velocity_scale(config: AOASSConfig) -> float:
    """Velocities in the observation are divided by this (m/s): the larger of the moving
    obstacles' and the anchor's maximum speed."""
    return max(config.moving_obstacle_speed[1], config.anchor_max_speed)


def observation_layout(config: AOASSConfig) -> dict[str, slice]:
    """Name -> slice of each part of the observation vector."""
    layout, start = {}, 0
    for name, size, _ in _sizes(config):
        layout[name] = slice(start, start + size)
        start += size
    return layout


def observation_space(config: AOASSConfig) -> spaces.Box:
    """The bounded float32 Box of the observation."""
    low = np.concatenate([np.full(size, lo, np.float32) for _, size, lo in _sizes(config)])
    return spaces.Box(low, np.ones_like(low), dtype=np.float32)


@njit(inline="always")
def clip_like_numpy(x: float, low: float, high: float) -> float:
    """``np.minimum(np.maximum(x, low), high)`` of one element, as NumPy's array functions give
    it: a NaN is kept, and a tie of +0.0 and -0.0 gives the bound (the second operand)."""
    if not (x > low or x != x):
        x = low
    if not (x < high or x != x):
        x = high
    return x


@njit
def _vector(x: float, y: float, field: float, speed: float, max_speed: float, gap: float,
            reach: float, heading_error: float, cos_h: float, sin_h: float,
            upcoming: np.ndarray, wp_scale: float, rays: np.ndarray, slots: np.ndarray,
            coverage: float, progress: float, time_fraction: float, extra: np.ndarray,
            low: np.ndarray) -> np.ndarray:
    """The observation vector from its parts, element by element: the float64 entries that
    NumPy's concatenation of the parts would hold (the same divisions and subtractions; that
    form is the test's oracle), clipped to [``low``, 1] as NumPy clips, then rounded to
    float32."""
    out = np.empty(low.shape[0], np.float32)
    head = (x / field, y / field, speed / max_speed, gap / reach, heading_error / math.pi,
            cos_h, sin_h)
    k = 0
    for v in head:
        out[k] = clip_like_numpy(v, low[k], 1.0)
        k += 1
    for i in range(upcoming.shape[0]):
        out[k] = clip_like_numpy((upcoming[i, 0] - x) / wp_scale, low[k], 1.0)
        out[k + 1] = clip_like_numpy((upcoming[i, 1] - y) / wp_scale, low[k + 1], 1.0)
        k += 2
    for i in range(rays.shape[0]):
        out[k] = clip_like_numpy(rays[i] / reach, low[k], 1.0)
        k += 1
    for i in range(slots.shape[0]):
        for j in range(slots.shape[1]):
            out[k] = clip_like_numpy(slots[i, j], low[k], 1.0)
            k += 1
    for v in (coverage, progress, time_fraction):
        out[k] = clip_like_numpy(v, low[k], 1.0)
        k += 1
    for i in range(extra.shape[0]):
        out[k] = clip_like_numpy(extra[i], low[k], 1.0)
        k += 1
    return out


class Route(Protocol):
    """The waypoints an episode's follower walks: the spiral's, or an adaptive sweep's."""

    waypoints: np.ndarray
    blocked: np.ndarray


class Observer:
    """Reads the observation of one episode off the world and the follower.

    Args:
        config: the episode's configuration.
        spiral: the waypoints the follower walks and their blocked marks: the episode's spiral,
            or the adaptive sweep's pruned plan.
        noise_rng: source of the moving-obstacle measurement noise.
    """

    def __init__(self, config: AOASSConfig, spiral: Route,
                 noise_rng: np.random.Generator) -> None:
        self.config = config
        self._low = observation_space(config).low.astype(np.float64)
        self._no_extra = np.zeros(0)
        self._free = np.flatnonzero(~spiral.blocked)
        self._free_xy = spiral.waypoints[self._free]
        self._rng = noise_rng
        step = config.path_step
        self._wp_scale = config.obs_waypoints * step
        self._v_scale = velocity_scale(config)
        self._upcoming_index = -1
        self._upcoming = self._free_xy[:0]
        #: (D, 4) the moving obstacles detected by the last observation, world frame: x, y (m),
        #: vx, vy (m/s), noisy, nearest first (all of them, not only the observation's slots)
        self.detections = np.zeros((0, 4))
        #: d_obs (m) of the last observation (the world's gap to the nearest obstacle then)
        self.obstacle_gap = float(config.sensing_range)
        self._slots = np.zeros((config.obs_moving_obstacles, len(MOVING_FIELDS)))

    def upcoming(self, index: int) -> np.ndarray:
        """(K, 2) the next K free waypoints from spiral index ``index`` on (the last one
        repeated near the end of the path); read-only, cached per index."""
        if index != self._upcoming_index:
            k = self.config.obs_waypoints
            first = int(np.searchsorted(self._free, index))
            rows = np.minimum(np.arange(first, first + k), len(self._free) - 1)
            self._upcoming = self._free_xy[rows]
            self._upcoming.flags.writeable = False
            self._upcoming_index = index
        return self._upcoming

    def moving(self, world: World) -> np.ndarray:
        """(M, 5) slots of the nearest moving obstacles in sensing range, noisy, nearest first.

        Also records every detection of this observation, in the world frame and unclipped, in
        :attr:`detections`: what the Kalman tracker reads.
        """
        c = self.config
        slots = np.zeros((c.obs_moving_obstacles, len(MOVING_FIELDS)))
        self.detections = np.zeros((0, 4))
        n = c.n_moving_obstacles
        if n == 0:      # (with no slot, obs_moving_obstacles 0, the tracker still reads them)
            return slots
        position = world.position
        px, py = position.tolist()
        noise = self._rng.normal(size=(n, 4))
        # none in range, the common case, decided on squared distances of the offsets
        # (moving_positions - position, in floats: the same subtractions): only a distance
        # within a relative 1e-9 of the range could be decided otherwise by np.hypot below
        r2 = c.sensing_range * c.sensing_range * (1.0 + 1e-9)
        for mx, my in world.moving_xy:
            dx, dy = mx - px, my - py
            if dx * dx + dy * dy <= r2:
                break
        else:
            return slots
        rel = world.moving_positions - position
        seen = np.flatnonzero(np.hypot(rel[:, 0], rel[:, 1]) <= c.sensing_range)
        if seen.size == 0:
            return slots
        meas_pos = rel[seen] + c.obs_position_noise * noise[seen, :2]
        meas_vel = world.moving_velocities[seen] + c.obs_velocity_noise * noise[seen, 2:]
        order = np.argsort(np.hypot(meas_pos[:, 0], meas_pos[:, 1]), kind="stable")
        self.detections = np.hstack([position + meas_pos[order], meas_vel[order]])
        order = order[:c.obs_moving_obstacles]
        m = len(order)
        slots[:m, :2] = meas_pos[order] / c.sensing_range
        slots[:m, 2:4] = meas_vel[order] / self._v_scale
        slots[:m, 4] = 1.0
        return slots

    def sense(self, world: World) -> None:
        """Measure what an observation measures: d_obs (:attr:`obstacle_gap`) and the noisy
        moving-obstacle slots and :attr:`detections` (this draws the measurement noise). A
        step whose observation vector nobody reads (inside :class:`~aoass_env.wrappers.
        ActionRepeat`) runs only this; :meth:`vector` builds the vector from it later."""
        self.obstacle_gap = world.nearest_obstacle_distance()
        self._slots = self.moving(world)

    def __call__(self, world: World, *, follower_index: int, heading_error: float,
                 coverage: float, progress: float, time_fraction: float,
                 coverage_map: CoverageMap) -> np.ndarray:
        """The observation vector (float32) for the current state: :meth:`sense`, then
        :meth:`vector`.

        Args:
            world: the episode's world.
            follower_index: spiral index the follower is heading for.
            heading_error: follower heading - anchor heading (rad, wrapped to [-pi, pi]).
            coverage: Eq. 18 coverage ratio.
            progress: fraction of the spiral's waypoints reached or skipped.
            time_fraction: elapsed steps / step limit.
            coverage_map: the anchor's coverage map (read when ``obs_coverage_sectors`` > 0).
        """
        self.sense(world)
        return self.vector(world, follower_index=follower_index, heading_error=heading_error,
                           coverage=coverage, progress=progress, time_fraction=time_fraction,
                           coverage_map=coverage_map)

    def vector(self, world: World, *, follower_index: int, heading_error: float,
               coverage: float, progress: float, time_fraction: float,
               coverage_map: CoverageMap) -> np.ndarray:
        """The observation vector (float32) of the state the last :meth:`sense` measured (the
        world unmoved since), arguments as for :meth:`__call__`; no side effects."""
        c = self.config
        position, h = world.position, world.heading
        x, y = position.tolist()
        extra = self._no_extra
        if c.obs_coverage_sectors:
            extra = np.append(coverage_map.sector_deficits(position, h, c.obs_coverage_sectors,
                                                           2.0 * c.radio_range),
                              coverage_map.ratio)
        # the parts in order (docstring's table), clipped and rounded as
        # np.minimum(np.maximum(np.concatenate(parts), low), 1.0).astype(np.float32)
        return _vector(x, y, float(c.field_size), float(world.speed),
                       float(c.anchor_max_speed), float(self.obstacle_gap),
                       float(c.sensing_range), float(heading_error), math.cos(h), math.sin(h),
                       self.upcoming(follower_index), self._wp_scale, world.ray_distances(),
                       self._slots, float(coverage), float(progress), float(time_fraction),
                       extra, self._low)
