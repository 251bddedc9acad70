"""The AOASS safety stack as Gymnasium wrappers around AOASS-v0.

* :class:`KalmanObstacleTracker` (observation side, Section 3.5 step 2): tracks the moving
  obstacles with constant-velocity Kalman filters (:mod:`aoass_env.safety.kalman`), replaces the
  noisy moving-obstacle block of the observation with the filtered tracks and appends their
  predicted positions ``horizon`` seconds ahead.
* :class:`FuzzyORCASafety` (action side, Eq. 7-10): agent action -> desired velocity -> fuzzy
  controller (:mod:`aoass_env.safety.fuzzy`) -> ORCA (:mod:`aoass_env.safety.orca`) against the
  static obstacles near the anchor and the Kalman-tracked moving obstacles -> the speed and
  heading the anchor executes (:mod:`aoass_env.safety.unicycle`), sent to AOASS-v0 as its action.
  ``info["safety"]`` reports the intervention.
* :class:`ActionRepeat`: holds each agent action for several control periods (the safety stack
  still filters every period), so that one decision has a measurable effect on the reward.

The full stack in one line (also registered as ``AOASS-Safe-v0``)::

    env = aoass_env.make_safe_env(obstacle_density=0.3)

docs/safety.md describes every part and the measured safety record.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from copy import deepcopy
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.envs.registration import EnvSpec
from gymnasium.utils import seeding

from aoass_env.action import ResidualAction, action_type_named
from aoass_env.config import AOASSConfig, ConfigError, check_keywords, config_with
from aoass_env.env import COST_KEYS, AnchorState, AOASSEnv, make_env, reset_options
from aoass_env.jit import njit
from aoass_env.maps import ObstacleMap, list_maps, load_map, validation_split
from aoass_env.observation import MOVING_FIELDS, clip_like_numpy, velocity_scale
from aoass_env.planning import AdaptiveConfig
from aoass_env.safety.config import SafetyConfig, TrackerConfig
from aoass_env.safety.filter_period import (
    ACTIVE_SLACK,
    PeriodSettings,
    filter_period,
    fused,
    orca_lines_of,
)
from aoass_env.safety.fuzzy import FULL_TURN, FuzzyController
from aoass_env.safety.kalman import MultiTargetTracker
from aoass_env.safety.lookahead import (
    Escape,
    EscapeBudget,
    bounce_reach,
    escape_velocity,
    look_ahead_horizon,
    position_std,
    rollout_reach,
)
from aoass_env.safety.orca import (
    OrcaAgent,
    OrcaLines,
    StaticObstacles,
    active_constraints,
    solve_velocity,
)
from aoass_env.safety.unicycle import BrakingEnvelope, unicycle_command
from aoass_env.validators import integer, keyword_names, real
from aoass_env.world import wrap_angle

__all__ = ["ActionRepeat", "EnergyCost", "FuzzyORCASafety", "KalmanObstacleTracker",
           "MapSampler", "POLICY_STACK_KEYS", "TRAINING_SPLITS", "make_safe_env",
           "make_training_env"]

#: Measurement-noise floor of the tracker (m, m/s): a noiseless observation still needs a
#: positive noise for the filter's innovation covariance.
NOISE_FLOOR = 1e-3


class _EntryPointWrapper(gym.Wrapper):
    """A wrapper that a registered entry point applies itself: the spec's entry point and
    keywords rebuild it, so it is not one of the spec's ``additional_wrappers`` (which
    ``gymnasium.make`` applies on top of the entry point)."""

    @property
    def spec(self) -> EnvSpec | None:
        return self.env.spec


def _aoass(env: gym.Env, wrapper: str) -> AOASSEnv:
    base = env.unwrapped
    if not isinstance(base, AOASSEnv):
        raise TypeError(f"{wrapper} wraps an AOASS-v0 environment, got {type(base).__name__}")
    return base


def _own_size(obstacle_map: ObstacleMap, name: str | os.PathLike, field_size: float
              ) -> ObstacleMap:
    """``obstacle_map`` (map ``name`` read at its own size) as :class:`MapSampler` keeps it: a
    map of the config's ``field_size`` read as the sampler always read it (scaled to that
    side, which moves a vertex by a rounding error at most: the training runs' maps, bit for
    bit), any other at its own size."""
    if obstacle_map.width == obstacle_map.height == field_size:
        return load_map(name, field_size=field_size)
    return obstacle_map


class MapSampler(_EntryPointWrapper):
    """A map drawn for every episode from a list (a seeded reset fixes the sequence of draws),
    or taken in turn (``cycle=True``, for evaluation; a seeded reset starts again from the
    first map, so that the same seed gives the same episodes).

    Args:
        env: an AOASS-v0 environment (possibly wrapped).
        maps: shipped map names (``"train/d0.10_f100_s000"``), paths or ``ObstacleMap`` objects;
            loaded once here, so a bad name fails now, each at its own size (an episode on a
            map of another size than the config's field takes the map's, as a map given at
            reset does; it used to be rescaled to the config's field, its passages with it).
        cycle: take the maps in order instead of at random.
    """

    def __init__(self, env: gym.Env, maps: Sequence[str | ObstacleMap], *,
                 cycle: bool = False) -> None:
        super().__init__(env)
        base = _aoass(env, "MapSampler")
        try:                                 # any iterable of names, paths or maps
            given = [] if isinstance(maps, (str, ObstacleMap)) else list(maps)
        except TypeError:
            given = []
        if not given:
            raise ValueError(f"maps must be a non-empty list of maps, got {maps!r}")
        maps = given
        self.maps = [m if isinstance(m, ObstacleMap) else
                     _own_size(load_map(m), m, base.config.field_size) for m in maps]
        if not isinstance(cycle, bool):
            raise ValueError(f"cycle must be a bool, got {cycle!r}")
        self.cycle = cycle
        self._next = 0
        self._rng: np.random.Generator | None = None

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        options = reset_options(options)
        if seed is not None:
            seeding.np_random(seed)      # Gymnasium's one-line refusal of a bad seed, first
        if seed is not None or self._rng is None:
            # a seed fixes the draws from here on; no seed ever: OS entropy, as in gymnasium
            self._rng = np.random.default_rng(None if seed is None else [seed, 0x4D4150])
        if seed is not None:
            self._next = 0
        if options.get("map") is None:   # {"map": None} is no map given, as AOASS-v0 reads it
            if self.cycle:
                options["map"] = self.maps[self._next % len(self.maps)]
                self._next += 1
            else:
                options["map"] = self.maps[int(self._rng.integers(len(self.maps)))]
        return self.env.reset(seed=seed, options=options)


class KalmanObstacleTracker(_EntryPointWrapper, gym.ObservationWrapper):
    """Kalman tracks of the moving obstacles in the observation.

    Each step the tracker takes AOASS-v0's world-frame detections (``env.unwrapped.detections``:
    every moving obstacle in sensing range, with the sensor's noise, unclipped) and updates its
    tracks. The wrapped observation is AOASS-v0's with its ``moving_obstacles`` block (M slots of
    dx, dy, vx, vy, present) holding the M confirmed tracks nearest the anchor (filtered
    position relative to the anchor / sensing range, filtered velocity / velocity scale) instead
    of the raw noisy detections, and a new block ``moving_predicted`` appended at the end: each
    slot's predicted position ``horizon`` seconds ahead relative to the anchor's current
    position, / sensing range, clipped to [-1, 1] (zeros for empty slots). ``obs_layout`` maps
    the names to slices.

    Args:
        env: an AOASS-v0 environment (possibly wrapped).
        config: the tracker's :class:`~aoass_env.safety.config.TrackerConfig`, or a mapping of
            its keywords (default: its defaults).
    """

    def __init__(self, env: gym.Env, config: TrackerConfig | dict[str, Any] | None = None
                 ) -> None:
        super().__init__(env)
        self._base = base = _aoass(env, "KalmanObstacleTracker")
        self.config = config = TrackerConfig.coerce(config, "tracker")
        c = base.config
        self.horizon = config.horizon
        self.tracker = MultiTargetTracker(
            c.dt, position_noise=max(c.obs_position_noise, NOISE_FLOOR),
            velocity_noise=max(c.obs_velocity_noise, NOISE_FLOOR),
            process_noise=config.process_noise, gate=config.gate,
            birth_hits=config.birth_hits, max_misses=config.max_misses,
            maneuver_speed=config.maneuver_speed)
        layout = dict(base.obs_layout)
        self._moving = layout["moving_obstacles"]
        self._slots = c.obs_moving_obstacles
        self._v_scale = velocity_scale(c)
        inner = env.observation_space
        n = inner.shape[0]
        layout["moving_predicted"] = slice(n, n + 2 * self._slots)
        self.obs_layout = layout
        self.observation_space = spaces.Box(
            np.concatenate([inner.low, np.full(2 * self._slots, -1.0, np.float32)]),
            np.concatenate([inner.high, np.ones(2 * self._slots, np.float32)]),
            dtype=np.float32)
        self._low, self._high = self.observation_space.low, self.observation_space.high
        self._horizon = real("horizon", self.horizon, "s", low=0.0)   # as predict_positions
        self._no_ahead = np.zeros(2 * self._slots, np.float32)   # empty slots' block
        self._no_ahead.flags.writeable = False
        self._inner_shape = inner.shape

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        self.tracker.reset()
        return super().reset(seed=seed, options=options)

    @property
    def last_detections(self) -> np.ndarray:
        """(n, 4) the detections of the last observation, world frame: x, y (m), vx, vy (m/s)."""
        return self._base.detections

    @property
    def tracked_obstacles(self) -> np.ndarray:
        """(m, 5) confirmed tracks in the world frame: x, y (m), vx, vy (m/s), radius (m)."""
        states = self.tracker.states()
        tracks = np.empty((len(states), 5))
        tracks[:, :4] = states
        tracks[:, 4] = self._base.config.moving_obstacle_radius
        return tracks

    @property
    def tracked_covariances(self) -> np.ndarray:
        """(m, 4, 4) covariances (m^2, m^2/s, m^2/s^2) of the confirmed tracks' states, rows as
        in :attr:`tracked_obstacles` (the filterpy filters' ``P``)."""
        return self.tracker.covariances()

    def observation(self, observation: np.ndarray | None) -> np.ndarray | None:
        detections = self._base.detections
        if len(detections) or self.tracker.n_tracks:
            self.tracker.step(detections)
        # else no track, no detection: tracker.step() would return at once
        if observation is None:     # a deferred step (ActionRepeat): the tracker steps all the same
            return None
        return self._with_tracks(observation)

    def deferred_observation(self) -> np.ndarray:
        """The observation the last step deferred (``AOASSEnv.defer_observation``): the
        inner one (:meth:`AOASSEnv.deferred_observation <aoass_env.env.AOASSEnv.
        deferred_observation>`) with this step's tracks."""
        return self._with_tracks(self._base.deferred_observation())

    def _with_tracks(self, observation: np.ndarray) -> np.ndarray:
        """``observation`` with the confirmed tracks in the moving-obstacle slots and their
        predicted positions appended."""
        observation = np.asarray(observation)
        if observation.shape != self._inner_shape:
            raise ValueError(f"KalmanObstacleTracker got an observation of shape "
                             f"{observation.shape}; the env it wraps has {self._inner_shape}")
        states = self.tracker.states() if self.tracker.n_tracks else ()
        if len(states) == 0:        # no confirmed track: empty slots (the lines below, in short)
            if observation.dtype == np.float32:
                return _empty_slots(observation, self._moving.start, self._moving.stop,
                                    self._low, self._high)
            out = np.concatenate([observation, self._no_ahead])
            out[self._moving] = 0.0
            return self._clipped(out)
        if observation.dtype not in (np.float32, np.float64):   # NumPy's float64, as before
            observation = observation.astype(np.float64)
        return _track_slots(observation, states, *self._base.sim.world.position.tolist(),
                            self._horizon, self._base.config.sensing_range, self._v_scale,
                            self._slots, self._moving.start, self._low, self._high)

    def _clipped(self, out: np.ndarray) -> np.ndarray:
        """``out`` clipped to the observation space, as float32: ``np.clip``'s values without
        its dispatch. A float32 ``out`` (AOASS-v0's observation with empty slots) is clipped
        in float32: the same comparisons of the same values as in float64 (float32 widens
        exactly), so the same floats, without the two conversions."""
        return np.minimum(np.maximum(out, self._low), self._high).astype(np.float32,
                                                                         copy=False)


@njit
def _deviations(sx: float, sy: float, dx: float, dy: float, px: float, py: float
                ) -> tuple[float, float]:
    """|v* - v_des| and |v* - v_pref| (m/s) of the velocities (``sx``, ``sy``), (``dx``,
    ``dy``) and (``px``, ``py``): the C library's hypot, as ``np.hypot`` calls it (the same
    floats, one compiled call instead of two ufunc calls)."""
    return math.hypot(sx - dx, sy - dy), math.hypot(sx - px, sy - py)


@njit
def _empty_slots(observation: np.ndarray, start: int, stop: int, low: np.ndarray,
                 high: np.ndarray) -> np.ndarray:
    """The tracker's observation without a confirmed track, from a float32 ``observation``:
    ``observation`` and a zero block, the moving-obstacle slots [start, stop) zeroed, clipped to
    [``low``, ``high``] (float32) as ``np.minimum(np.maximum(out, low), high)`` clips, element
    by element in float32: a NaN kept, and a tie (+0.0 against -0.0) giving the bound, the
    second operand, as NumPy's array maximum and minimum give it."""
    out = np.empty(low.shape[0], np.float32)
    n = observation.shape[0]
    for i in range(low.shape[0]):
        x = observation[i] if i < n and not start <= i < stop else np.float32(0.0)
        out[i] = clip_like_numpy(x, low[i], high[i])
    return out


@njit
def _track_slots(observation: np.ndarray, states: np.ndarray, ax: float, ay: float,
                 horizon: float, reach: float, v_scale: float, slots: int, start: int,
                 low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """The tracker's observation with confirmed tracks, from a float32 or float64
    ``observation``: NumPy's array code (tests/test_wrappers.py) element by element. The tracks
    ``states`` (m, 4) nearest the anchor (ax, ay) (m) first (a stable order of their
    ``np.hypot`` distances, the C library's hypot as NumPy's) fill the ``slots`` moving-obstacle
    slots from ``start`` ([dx, dy] / ``reach``, [vx, vy] / ``v_scale``, 1) and their positions
    ``horizon`` (s) ahead the appended block ((x + horizon vx - ax) / ``reach``, ...); the rest
    is zero. The float64 entries are clipped to [``low``, ``high``] as NumPy clips, then
    rounded to float32."""
    n = observation.shape[0]
    out = np.empty(n + 2 * slots)
    for i in range(n):
        out[i] = observation[i]
    out[n:] = 0.0
    out[start:start + len(MOVING_FIELDS) * slots] = 0.0
    distance = np.empty(states.shape[0])
    for j in range(states.shape[0]):
        distance[j] = np.hypot(states[j, 0] - ax, states[j, 1] - ay)
    order = np.argsort(distance, kind="mergesort")
    for k in range(min(slots, states.shape[0])):
        j = order[k]
        row = start + len(MOVING_FIELDS) * k
        out[row] = (states[j, 0] - ax) / reach
        out[row + 1] = (states[j, 1] - ay) / reach
        out[row + 2] = states[j, 2] / v_scale
        out[row + 3] = states[j, 3] / v_scale
        out[row + 4] = 1.0
        out[n + 2 * k] = (states[j, 0] + horizon * states[j, 2] - ax) / reach
        out[n + 2 * k + 1] = (states[j, 1] + horizon * states[j, 3] - ay) / reach
    clipped = np.empty(out.shape[0], np.float32)
    for i in range(out.shape[0]):
        clipped[i] = clip_like_numpy(out[i], np.float64(low[i]), np.float64(high[i]))
    return clipped


def _braking_reach(c: AOASSConfig, radius: float) -> float:
    """How far (m) from the anchor the braking envelope takes the static edges: one period and
    a full stop from top speed, plus its disc ``radius`` (m)."""
    top = c.anchor_max_speed
    return top * c.dt + top * top / (2.0 * c.anchor_max_accel) + radius


#: Most half-period samples of the look-ahead's rollout (the defaults: 4.5 s / 0.25 s = 18).
MAX_LOOK_AHEAD_SAMPLES = 2000


def _horizon(c: AOASSConfig, cfg: SafetyConfig) -> float:
    """The look-ahead's horizon (s): ``look_ahead_horizon``, else the anchor's reaction time
    (:func:`~aoass_env.safety.lookahead.look_ahead_horizon`); :class:`ConfigError` when it
    takes more than :data:`MAX_LOOK_AHEAD_SAMPLES` half-period samples (a slow turn rate or
    acceleration made every step slow, then ran out of memory: 1e-9 rad/s asked for 94 GiB)."""
    horizon = cfg.look_ahead_horizon or look_ahead_horizon(
        c.anchor_max_speed, c.anchor_max_accel, c.anchor_max_turn_rate, c.dt)
    if cfg.look_ahead and not horizon / (0.5 * c.dt) <= MAX_LOOK_AHEAD_SAMPLES:
        raise ConfigError(
            f"the safety stack's look-ahead horizon {horizon:.4g} s (dt + anchor_max_speed / "
            f"anchor_max_accel + pi / anchor_max_turn_rate, or safety look_ahead_horizon) takes "
            f"more than {MAX_LOOK_AHEAD_SAMPLES} samples of dt / 2 = {0.5 * c.dt:g} s; raise "
            f"anchor_max_turn_rate={c.anchor_max_turn_rate:g} rad/s or anchor_max_accel="
            f"{c.anchor_max_accel:g} m/s^2, or set the safety config's look_ahead_horizon")
    return horizon


class FuzzyORCASafety(_EntryPointWrapper, gym.ActionWrapper):
    """Fuzzy-logic + ORCA velocity filter between the agent and AOASS-v0 (Eq. 7-10).

    The agent's action means what AOASS-v0's config says (:class:`~aoass_env.action.
    ResidualAction` of its ``action_speed_scale`` and ``action_heading_scale``): a residual on
    the spiral follower giving the desired speed and heading. Then:

    1. Eq. 7: the fuzzy controller maps the gap to the nearest obstacle d (m) and the heading
       error (desired - current heading) to a turn-rate fraction and a speed fraction; the
       preferred velocity points where the anchor heads after turning at that rate for one
       control period, at the desired speed times the speed fraction.
    2. Eq. 8-10: ORCA returns the velocity v* closest to the preferred one that is collision-free
       for ``time_horizon_obst`` (s) against the static obstacles near the anchor (the
       boundary of free space of the episode's map, field border included) and for
       ``time_horizon`` (s) against the tracker's moving obstacles (which do not
       reciprocate: the anchor takes full responsibility). The anchor's radius is inflated by
       ``margin`` (m), the moving obstacles' by ``moving_margin`` (m).
    3. The anchor is commanded v*'s heading and the largest speed up to |v*| that stays safe on
       every heading it passes through while it turns; it turns only as far as the headings
       stay safe at the speed it cannot shed within the period, and no faster on any heading
       than lets it stop, after one period, before its disc (radius + ``margin``) reaches a
       static edge (the braking envelope: ORCA assumes an instant change of velocity, the
       anchor's lags; :mod:`aoass_env.safety.unicycle`).

    The command is sent to AOASS-v0 through its own action type, which must reach every speed
    and heading (:meth:`ResidualAction.full_range <aoass_env.action.ResidualAction.full_range>`;
    :func:`make_safe_env` builds it so).

    ``info["safety"]`` holds ``intervention`` = |v* - v_des| (m/s, the agent's desired
    velocity), ``orca_correction`` = |v* - v_pref| (m/s), the fuzzy outputs, the executed
    speed and heading, and the number of ORCA constraints (``constraints``, ``static``) and of
    those active at v* (``active``, ``active_static``).

    Args:
        env: an AOASS-v0 environment wrapped by ``tracker`` (possibly among other wrappers).
        tracker: the :class:`KalmanObstacleTracker` whose tracks are the moving obstacles ORCA
            avoids.
        config: the filter's :class:`~aoass_env.safety.config.SafetyConfig`, or a mapping of
            its keywords (default: its defaults).
        controller: the fuzzy controller (default: :meth:`FuzzyController.default`).
    """

    def __init__(self, env: gym.Env, tracker: KalmanObstacleTracker,
                 config: SafetyConfig | dict[str, Any] | None = None, *,
                 controller: FuzzyController | None = None) -> None:
        super().__init__(env)
        self._base = base = _aoass(env, "FuzzyORCASafety")
        if not isinstance(tracker, KalmanObstacleTracker) or tracker.unwrapped is not base:
            raise TypeError("tracker must be the KalmanObstacleTracker of the same AOASS-v0 "
                            "environment; build the stack with aoass_env.make_safe_env")
        inner = base.action_type
        if not (isinstance(inner, ResidualAction) and inner.reaches_every_command):
            raise ValueError(
                "FuzzyORCASafety needs an AOASS-v0 whose action reaches every speed and heading "
                "(action_type=ResidualAction.full_range(config)); build the stack with "
                "aoass_env.make_safe_env")
        self._tracker = tracker
        self.config = config = SafetyConfig.coerce(config, "safety")
        #: the look-ahead's horizon (s); the configs are fixed for the env's life
        self._look_ahead_s = _horizon(base.config, config)
        #: what the agent's action means: the environment's action type (residual or
        #: adaptive) with its config's scales
        self.agent_action = type(inner).from_config(base.config)
        if controller is not None and not isinstance(controller, FuzzyController):
            raise TypeError(f"controller must be a FuzzyController, got "
                            f"{type(controller).__name__}")
        self.controller = controller if controller is not None else FuzzyController.default()
        self.action_space = self.agent_action.space
        self._static: StaticObstacles | None = None
        self._static_map: Any = None
        #: the config the ORCA settings were made for, and the settings (_orca_agent)
        self._orca = (base.config, self._orca_settings(base.config))
        #: the look-ahead's escape budget and whether it escaped last period (hysteresis)
        self.escape_budget = EscapeBudget(config.escape_budget)
        self._escaping = False
        #: whether filter_period gives this wrapper's floats here, and its settings (for the
        #: ORCA settings they were made with)
        self._fused = fused()
        self._period: tuple[OrcaAgent | None, PeriodSettings | None] = (None, None)

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        self.escape_budget.reset()
        self._escaping = False
        return super().reset(seed=seed, options=options)

    def _static_obstacles(self) -> StaticObstacles:
        """The boundary of free space of the episode's map (built once per map)."""
        episode_map = self._base.obstacle_map
        if episode_map is not self._static_map:
            self._static = StaticObstacles.from_loops(episode_map.free_space_loops)
            self._static_map = episode_map
        return self._static

    def _orca_settings(self, c: AOASSConfig) -> OrcaAgent:
        """The anchor's ORCA settings under the env's config ``c``: its radius inflated by
        ``margin``, the filter's horizons, the control period."""
        cfg = self.config
        return OrcaAgent(c.anchor_radius + cfg.margin, c.anchor_max_speed, cfg.time_horizon,
                         cfg.time_horizon_obst, c.dt)

    def _orca_agent(self, c: AOASSConfig) -> OrcaAgent:
        """:meth:`_orca_settings` of ``c``, checked once per config."""
        if self._orca[0] is not c:
            self._orca = (c, self._orca_settings(c))
        return self._orca[1]

    def _braking_envelope(self, position: np.ndarray, static: StaticObstacles
                          ) -> BrakingEnvelope:
        """The edges of ``static`` within the anchor's reach in one period and a full stop
        from top speed, as speed caps by heading (:class:`~aoass_env.safety.unicycle.
        BrakingEnvelope`; the anchor's radius is inflated by ``margin``, as for ORCA)."""
        c = self._base.config
        radius = c.anchor_radius + self.config.margin
        starts, ends = static.segments_near(position, _braking_reach(c, radius))
        return BrakingEnvelope(starts, ends, np.asarray(position, dtype=np.float64), radius,
                               c.anchor_max_accel, c.dt)

    def _period_settings(self, c: AOASSConfig) -> PeriodSettings:
        """:func:`filter_period`'s settings under the env's config ``c`` (made once per
        config, with :meth:`_orca_agent`'s)."""
        agent = self._orca_agent(c)
        if self._period[0] is not agent:
            self._period = (agent, PeriodSettings(
                agent, max_turn=c.anchor_max_turn_rate * c.dt, max_dv=c.anchor_max_accel * c.dt,
                reach=_braking_reach(c, agent.radius), max_accel=c.anchor_max_accel, dt=c.dt))
        return self._period[1]

    def _moving_obstacles(self) -> np.ndarray | None:
        """Kalman-tracked moving obstacles (x, y, vx, vy, radius + moving_margin +
        covariance_sigma x the std of the position estimate along its worst axis); None when
        there is no confirmed track (what :func:`orca_lines` reads as none)."""
        if not self._tracker.tracker.confirmed:
            return None
        tracks = self._tracker.tracked_obstacles
        tracks[:, 4] += self.config.moving_margin
        if self.config.covariance_sigma > 0.0:
            std = position_std(self._tracker.tracked_covariances, np.zeros(1))[:, 0]
            tracks[:, 4] += self.config.covariance_sigma * std
        return tracks

    def _look_ahead(self, v_star: np.ndarray, v_pref: np.ndarray, anchor: AnchorState,
                    static: StaticObstacles) -> Escape:
        """The look-ahead's verdict on ORCA's ``v_star`` (:func:`~aoass_env.safety.lookahead.
        escape_velocity`) for the ``anchor`` as it is this period: the tracks' prediction and
        covariance against the anchor's unicycle rolled out among the static edges."""
        c, cfg = self._base.config, self.config
        horizon = self._look_ahead_s
        tracks = self._tracker.tracked_obstacles
        tracks[:, 4] += c.anchor_radius
        radius = c.anchor_radius + cfg.margin
        step = 0.5 * c.dt
        starts, ends = static.segments_near(
            anchor.position, rollout_reach(c.anchor_max_speed, horizon, step, radius))
        # the tracks' own reach: an obstacle out of the anchor's reach still bounces off the
        # walls near it, back into the anchor's way
        bounce_starts, bounce_ends = static.segments_near_any(
            tracks[:, :2], bounce_reach(tracks, horizon, step, c.moving_obstacle_radius))
        react = cfg.look_ahead_react or c.dt + c.anchor_max_speed / c.anchor_max_accel
        yielding = self.escape_budget.yielding
        return escape_velocity(
            v_star, v_pref, anchor.position, anchor.heading, anchor.speed, tracks,
            self._tracker.tracked_covariances, max_speed=c.anchor_max_speed,
            max_accel=c.anchor_max_accel, max_turn_rate=c.anchor_max_turn_rate,
            horizon=horizon, step=step, starts=starts, ends=ends, radius=radius,
            sigma=cfg.covariance_sigma, maneuver=0.0 if yielding else cfg.maneuver_share,
            clearance=cfg.look_ahead_clearance, obstacle_radius=c.moving_obstacle_radius,
            react=None if self._escaping else react,
            progress_weight=cfg.yield_progress_weight if yielding else cfg.progress_weight,
            tolerance=cfg.yield_shortfall_tolerance if yielding else cfg.shortfall_tolerance,
            bounce_starts=bounce_starts, bounce_ends=bounce_ends)

    def step(self, action: np.ndarray) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        executed, report = self._filter(action)
        # the look-ahead's memory moves on with the steps taken (not with action() previews)
        self._escaping = report["escaping"]
        if self.config.look_ahead:
            self.escape_budget.update(self._escaping, self._base.config.dt)
        observation, reward, terminated, truncated, info = self.env.step(executed)
        info["safety"] = report
        return observation, reward, terminated, truncated, info

    def action(self, action: np.ndarray) -> np.ndarray:
        return self._filter(action)[0]

    def _filter(self, action: np.ndarray) -> tuple[np.ndarray, dict[str, Any]]:
        base, cfg = self._base, self.config
        c = base.config
        nominal = base.nominal_command          # raises before the first reset
        anchor = base.anchor
        (speed_des, heading_des), knobs = self.agent_action.decode(action, nominal)
        # the desired and preferred velocities: speed x (cos, sin), in floats (an array times
        # a float multiplies each entry alone: the same floats)
        v_des = (speed_des * math.cos(heading_des), speed_des * math.sin(heading_des))

        heading = anchor.heading
        turn, slow = self.controller(anchor.obstacle_gap, wrap_angle(heading_des - heading))
        max_turn = c.anchor_max_turn_rate * c.dt
        # the controller's turn is a fraction of FULL_TURN at most: the same floats wherever
        # the anchor turns no farther per period (the defaults turn exactly FULL_TURN)
        heading_pref = heading + float(turn) * min(max_turn, FULL_TURN)
        speed_pref = float(slow) * speed_des
        pref = (speed_pref * math.cos(heading_pref), speed_pref * math.sin(heading_pref))

        static = self._static_obstacles()
        moving = self._moving_obstacles()
        escape = None
        if self._fused:     # where ORCA and the lines alone decide, one call decides
            done, rows, n_static, sx, sy, speed_cmd, heading_cmd, active, active_static = \
                filter_period(static, moving, self._period_settings(c),
                              anchor.position.tolist(), anchor.velocity.tolist(), pref,
                              heading, anchor.speed, heading_pref, cfg.look_ahead)
            n_lines = len(rows)
            if not done:    # handed back: the same lines and v*
                lines, v_star = orca_lines_of(rows, n_static), np.array([sx, sy])
        else:
            done = False
            lines, v_star = self._orca_agent(c).velocity(anchor.position, anchor.velocity, pref,
                                                         static, moving)
        if not done:
            if cfg.look_ahead and len(lines) > lines.n_static:
                escape = self._look_ahead(v_star, np.array(pref), anchor, static)
                if escape.escaping:
                    # the rollouts chose among the moving obstacles: the static lines stay hard
                    lines = OrcaLines(lines.point[:lines.n_static],
                                      lines.direction[:lines.n_static], lines.n_static,
                                      lines.table[:lines.n_static])
                    v_star = solve_velocity(lines, escape.velocity, c.anchor_max_speed)
            speed_cmd, heading_cmd = unicycle_command(
                v_star, heading, anchor.speed, max_turn, c.anchor_max_accel * c.dt,
                lines.point, lines.direction, heading_pref,
                self._braking_envelope(anchor.position, static))
            # constraints active at v*: on the line (within ACTIVE_SLACK m/s) or violated
            sx, sy = v_star.tolist()
            active, active_static = active_constraints(lines, v_star, ACTIVE_SLACK)
            n_lines, n_static = len(lines), lines.n_static
        executed = base.action_type.action(speed_cmd, heading_cmd, nominal, knobs)
        intervention, correction = _deviations(sx, sy, *v_des, *pref)
        report = {"intervention": intervention, "orca_correction": correction,
                  "flc_turn": float(turn), "flc_speed": float(slow),
                  "speed_cmd": speed_cmd, "heading_cmd": heading_cmd,
                  "constraints": n_lines, "static": n_static,
                  "active": active, "active_static": active_static,
                  "escaping": bool(escape is not None and escape.escaping),
                  "look_ahead_shortfall": 0.0 if escape is None else escape.shortfall,
                  "yielding": self.escape_budget.yielding}
        return executed, report


class EnergyCost(_EntryPointWrapper):
    """Opt-in reward shaping outside Eq. 14: each step's reward less ``weight`` times the
    energy the episode spent in it (the growth of ``info["energy_total"]``, J: the anchor's
    motion and beacons and the nodes' receptions, Table 1). Eq. 14 charges time (its per-step
    penalties) but not the anchor's travel, so a policy trained on it alone drives faster
    along a longer path; this term puts E_total into the objective. ``info["energy_cost"]``
    holds the step's term (<= 0); the Eq. 14 terms stay in ``info["reward_terms"]``. Outside
    :class:`ActionRepeat`, a held action's term is the energy of all its periods."""

    def __init__(self, env: gym.Env, weight: float) -> None:
        weight = real("energy_weight", weight, "per J", low=0.0)     # np.float32 too
        super().__init__(env)
        self.weight = float(weight)
        self._spent = 0.0

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(**kwargs)
        self._spent = float(info["energy_total"])
        return obs, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        spent = float(info["energy_total"])
        cost = -self.weight * (spent - self._spent)
        self._spent = spent
        info["energy_cost"] = cost
        return obs, float(reward) + cost, terminated, truncated, info


class ActionRepeat(_EntryPointWrapper):
    """Holds each action for ``repeat`` steps of the wrapped environment (fewer when the episode
    ends first); the reward is their sum, and so are ``info["reward_terms"]`` (Eq. 14 term by
    term) and the cost signal; the observation and the rest of info are the last step's.

    An agent's decision period becomes ``repeat`` x ``dt`` seconds: a residual speed command held
    for one 0.5 s period moves the anchor at most 0.5 m, too little for a critic to tell its
    effect on Eq. 14 from noise. Wrapped outside the safety stack, the velocity filter still runs
    every control period.

    Only the last step's observation is returned, so on AOASS-v0 and the safety stack the
    steps before it defer theirs (``AOASSEnv.defer_observation``): they measure what the
    filter and the tracker read (d_obs, the noisy detections) but build no vector (no rays);
    when the episode ends on such a step, its observation is built then, from the same state.
    The episodes are the same as with every observation built. Any other wrapper between
    this one and AOASS-v0 might read the observations, so then every step builds its own, as
    it does with ``defer=False``.

    Args:
        env: the environment whose steps are held.
        repeat: control periods per action, an integer >= 1.
        defer: defer the observations nobody reads (as above), or build every one.
    """

    def __init__(self, env: gym.Env, repeat: int, defer: bool = True) -> None:
        repeat = integer("action_repeat", repeat, "control periods", low=1)  # 16.0, np.int64
        if not isinstance(defer, bool):
            raise TypeError(f"defer must be a bool, got {type(defer).__name__}")
        super().__init__(env)
        self.repeat = repeat
        # where a deferred observation is built (the outermost layer that transforms it), or
        # None: every held step builds its own
        self._source: KalmanObstacleTracker | AOASSEnv | None = None
        if defer:
            layer, tracker = env, None
            # the layers under which observations may be deferred: they read none (the filter,
            # time limits), or step without one and build it on demand (the tracker)
            while isinstance(layer, (FuzzyORCASafety, KalmanObstacleTracker,
                                     gym.wrappers.TimeLimit)):
                if tracker is None and isinstance(layer, KalmanObstacleTracker):
                    tracker = layer
                layer = layer.env
            if isinstance(layer, AOASSEnv):
                self._source = tracker or layer

    @property
    def periods_per_step(self) -> int:
        """Control periods one step of this wrapper holds (:func:`~aoass_env.env.agent_step_limit`
        counts the episode's limit in these steps)."""
        return self.repeat

    @property
    def spec(self) -> EnvSpec | None:
        """The inner spec with ``max_episode_steps`` in agent steps: ⌈inner limit / repeat⌉."""
        spec = self.env.spec
        if spec is None or spec.max_episode_steps is None:
            return spec
        spec = deepcopy(spec)
        spec.max_episode_steps = math.ceil(spec.max_episode_steps / self.repeat)
        return spec

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        total = 0.0
        costs = dict.fromkeys(COST_KEYS, 0.0)
        terms: dict[str, float] | None = None      # the Eq. 14 terms of the held periods
        base = self.env.unwrapped if self._source is not None else None
        try:
            for k in range(self.repeat):
                if base is not None:
                    base.defer_observation = k < self.repeat - 1
                obs, reward, terminated, truncated, info = self.env.step(action)
                total += float(reward)
                for key in COST_KEYS:
                    costs[key] += info[key]
                step_terms = info.get("reward_terms")
                if step_terms is not None:
                    terms = (dict(step_terms) if terms is None else
                             {key: terms[key] + value for key, value in step_terms.items()})
                if terminated or truncated:
                    break
        finally:
            if base is not None:
                base.defer_observation = False
        if obs is None and self._source is not None:    # the episode ended on a deferred step
            obs = self._source.deferred_observation()
        info.update(costs)
        if terms is not None:
            info["reward_terms"] = terms
        return obs, total, terminated, truncated, info


def make_safe_env(*, config: AOASSConfig | Mapping[str, Any] | None = None,
                  render_mode: str | None = None,
                  tracker: TrackerConfig | dict[str, Any] | None = None,
                  safety: SafetyConfig | dict[str, Any] | None = None,
                  action_repeat: int = 1, action_type: str = "residual",
                  adaptive: AdaptiveConfig | dict[str, Any] | None = None,
                  energy_weight: float = 0.0, **kwargs: Any) -> gym.Env:
    """The full AOASS stack: AOASS-v0 (in its ``TimeLimit``) -> :class:`KalmanObstacleTracker`
    -> :class:`FuzzyORCASafety` (-> :class:`ActionRepeat` when ``action_repeat`` > 1) (->
    :class:`EnergyCost` when ``energy_weight`` > 0).

    Args:
        config, kwargs: the environment's configuration, as for ``gymnasium.make("AOASS-v0")``
            (an :class:`AOASSConfig` or a dict of its fields, keywords overriding it);
            its ``action_speed_scale`` and ``action_heading_scale`` are what the agent's action
            means. The inner AOASS-v0 takes the filter's commands through a full-range
            residual (:meth:`~aoass_env.action.ResidualAction.full_range`).
        render_mode: as for AOASS-v0.
        tracker: the tracker's :class:`~aoass_env.safety.config.TrackerConfig` (or keywords).
        safety: the filter's :class:`~aoass_env.safety.config.SafetyConfig` (or keywords).
        action_repeat: control periods each agent action is held (1: every period).
        action_type: what the agent's action means: ``"residual"`` (Eq. 6's [Δv, Δθ] on the
            spiral follower) or ``"adaptive"`` (the same and the adaptive sweep's knobs,
            :class:`~aoass_env.action.AdaptiveAction`).
        adaptive: the adaptive sweep's :class:`~aoass_env.planning.AdaptiveConfig` (or
            keywords), used with ``action_type="adaptive"``.
        energy_weight: reward shaping outside Eq. 14, per J of E_total spent
            (:class:`EnergyCost`; 0: none, the reward is Eq. 14's).
    """
    cfg = config_with(config, kwargs, also=keyword_names(make_safe_env))
    tracker_config = TrackerConfig.coerce(tracker, "tracker")
    safety_config = SafetyConfig.coerce(safety, "safety")
    env = make_env(config=cfg, render_mode=render_mode,
                   action_type=action_type_named(action_type).full_range(cfg),
                   adaptive=adaptive)
    tracked = KalmanObstacleTracker(env, tracker_config)
    env = FuzzyORCASafety(tracked, tracked, safety_config)
    action_repeat = integer("action_repeat", action_repeat, "control periods", low=1)
    if action_repeat != 1:
        env = ActionRepeat(env, action_repeat)
    if real("energy_weight", energy_weight, "per J", low=0.0) != 0:
        env = EnergyCost(env, energy_weight)
    return env


make_safe_env.metadata = AOASSEnv.metadata  # lets gymnasium.make check render modes


#: Where training environments take their maps from: the maps to fit on, or the held-out ones.
TRAINING_SPLITS = ("train", "validation")
#: Training-environment keywords that set up the stack a policy acts in (reused when it is
#: evaluated, kept by a resume): decisions held for ``action_repeat`` control periods, the
#: tracker's and the safety filter's configs, and what its actions and observations mean (the
#: residual's scales, the action type and its sweep, the coverage sectors).
POLICY_STACK_KEYS = ("action_repeat", "tracker", "safety", "action_speed_scale",
                     "action_heading_scale", "action_type", "adaptive", "obs_coverage_sectors")


def make_training_env(*, split: str = "train", field_size: float = 100.0,
                      densities: Sequence[float] = (0.1, 0.4), cycle: bool = False,
                      safety: SafetyConfig | dict[str, Any] | None = None,
                      tracker: TrackerConfig | dict[str, Any] | None = None,
                      **config: Any) -> gym.Env:
    """The full safety stack on shipped training maps with ``field_size`` (m) and density in
    ``densities`` (low, high), one map per episode (drawn, or in turn with ``cycle``):
    ``split="train"`` takes the maps to fit on, ``"validation"`` the ones held out for model
    selection (:func:`aoass_env.maps.validation_split`); maps/test is never used. ``config``:
    further :func:`make_safe_env` keywords (e.g. ``n_nodes``, ``action_repeat``).
    ``AOASS-Train-v0`` is the shipped policy's setup (docs/env.md)."""
    check_keywords(config, also=(*keyword_names(make_training_env),
                                 *keyword_names(make_safe_env)))
    if split not in TRAINING_SPLITS:
        raise ValueError(f"split={split!r} must be one of {TRAINING_SPLITS} (maps/test is for "
                         f"reported results only)")
    if "obstacle_density" in config:    # it shapes generated maps only: it would be ignored
        raise ConfigError(f"obstacle_density={config['obstacle_density']!r}: a training setup "
                          f"draws shipped maps whose density lies in densities (here "
                          f"{list(densities)}); obstacle_density sets the density of generated "
                          f"maps only (AOASS-Safe-v0)")
    fit, held_out = validation_split(list_maps("train", field_size=field_size,
                                               densities=densities))
    maps = fit if split == "train" else held_out
    if not maps:
        raise ValueError(f"no shipped {split} maps with field_size={field_size} and densities "
                         f"in {list(densities)}")
    env = make_safe_env(field_size=field_size, tracker=tracker, safety=safety, **config)
    if env.unwrapped.config.map is not None:   # MapSampler would replace it every episode
        raise ConfigError(f"map={env.unwrapped.config.map!r}: a training setup draws its map "
                          f"from the shipped {split} maps (split, field_size, densities); for "
                          f"one map use AOASS-Safe-v0 with map=..., or reset(options={{'map': "
                          f"...}})")
    return MapSampler(env, maps, cycle=cycle)


make_training_env.metadata = AOASSEnv.metadata  # lets gymnasium.make check render modes
