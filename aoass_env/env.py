"""AOASS-v0: the Gymnasium environment of the mobile anchor (orchestration only).

The maths lives elsewhere: the simulation core in :mod:`aoass_env.simulator`, the observation in
:mod:`aoass_env.observation`, the reward in :mod:`aoass_env.reward`, the metrics in
:mod:`aoass_env.metrics`, the drawing in :mod:`aoass_env.render`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from copy import deepcopy
from typing import Any, NamedTuple

import gymnasium as gym
import numpy as np
from gymnasium.wrappers import TimeLimit

from aoass_env.action import ActionType, AdaptiveAction, ResidualAction, action_type_named
from aoass_env.beacon_log import BeaconLog
from aoass_env.config import AOASSConfig, ConfigError, config_for_map, config_with, map_side
from aoass_env.maps import MapError, ObstacleMap, load_map
from aoass_env.observation import Observer, observation_layout, observation_space
from aoass_env.planning import AdaptiveConfig, AdaptiveSweep, WaypointFollower
from aoass_env.planning.adaptive import sweep_config
from aoass_env.planning.square_spiral import episode_spiral
from aoass_env.reward import energy_imbalance, online_rmse, reward_terms
from aoass_env.simulator import (
    Simulator,
    check_waypoint_step,
    episode_step_limit,
    episode_summary,
)
from aoass_env.validators import keyword_names
from aoass_env.world import wrap_angle

__all__ = ["COST_KEYS", "AOASSEnv", "AnchorState", "EndOnTruncation", "EpisodeTimeLimit",
           "agent_step_limit", "make_env", "max_episode_steps", "reset_options"]


#: The per-step safe-RL cost keys of ``info``: the step's new contacts, all, with static
#: obstacles and walls, and with moving obstacles (docs/env.md).
COST_KEYS = ("cost", "cost_static", "cost_moving")


class AnchorState(NamedTuple):
    """The anchor at the current step, as a wrapper reads it (world frame)."""

    position: np.ndarray        #: (2,) m
    velocity: np.ndarray        #: (2,) m/s
    heading: float              #: rad
    speed: float                #: m/s
    obstacle_gap: float         #: d_obs: gap to the nearest wall, static or moving obstacle (m)


def max_episode_steps(config: AOASSConfig, obstacle_map: ObstacleMap | None = None) -> int:
    """Step limit of an episode: ``time_limit_factor`` x the ideal spiral's duration at nominal
    speed, in control periods (1552 x 5 = 7760 steps for the default config), over the field of
    ``obstacle_map`` (default: an empty ``config.field_size`` square)."""
    field = (ObstacleMap(config.field_size, config.field_size) if obstacle_map is None
             else ObstacleMap(obstacle_map.width, obstacle_map.height))
    check_waypoint_step(config, field)
    spiral = episode_spiral(config, field)
    return episode_step_limit(config, spiral.nominal_time(config.anchor_nominal_speed),
                              "the spiral")


def _option_map(value: Any, name: str = "reset option 'map'") -> ObstacleMap:
    """The map ``value`` (an ObstacleMap, a shipped name or a file path) at its own size; an
    error naming ``name`` (the config field or the reset option) otherwise."""
    if isinstance(value, ObstacleMap):
        return value
    if not isinstance(value, (str, os.PathLike)):
        raise ValueError(f"{name} must be an ObstacleMap, a shipped map name or a map file "
                         f"path, got {type(value).__name__} {value!r}")
    try:
        return load_map(value)
    except MapError as exc:
        raise ConfigError(f"{name}={str(value)!r}: {exc}") from None


class AOASSEnv(gym.Env[np.ndarray, np.ndarray]):
    """A single mobile anchor sweeps a sensor field along a square spiral and broadcasts beacons.

    ## Description

    The anchor (a disc robot, pymunk physics) drives through a square field of static sensor
    nodes with static obstacle polygons and moving disc obstacles. Every ``beacon_interval``
    metres travelled (Table 1's Δs = 2 m) it broadcasts its position; nodes within radio range R
    and line of sight hear it. A nominal path follower steers along the square spiral of the
    paper's Eq. 1-2, skipping waypoints inside obstacles, detouring around obstacles in the way
    and resuming the spiral after them. The agent acts on top of that follower (Eq. 6's action
    is a residual), trading coverage (Eq. 18) against energy balance and localization error
    (Eq. 14). Reference: Naguib, AOASS, IJCNC 18(1), 2026; see docs/env.md.

    ## Action Space

    ``Box(-1, 1, (2,), float32)``: Eq. 6's a = [Δv, Δθ]. The commanded speed is the
    follower's speed + Δv x ``action_speed_scale`` (1 m/s), clipped to [0, ``anchor_max_speed``]
    (2 m/s); the commanded heading is the follower's heading + Δθ x ``action_heading_scale``
    (π/2 rad). The anchor reaches them within its limits (``anchor_max_accel`` 1 m/s²,
    ``anchor_max_turn_rate`` π/2 rad/s) over one control period ``dt`` = 0.5 s of
    ``physics_substeps`` = 5 pymunk steps. **The zero action follows the spiral.** Values outside
    [-1, 1] are clipped; NaN or infinite values raise ``ValueError``.

    ## Observation Space

    A bounded float32 ``Box`` (57 entries by default); ``env.unwrapped.obs_layout`` maps each
    part's name to its slice. The first five entries are Eq. 6's s = [x, y, v, d_obs, Δθ]
    (normalised), followed by the heading (cos, sin), the next K = 8 spiral waypoints relative to
    the anchor, the 16 range-sensor distances, the M = 3 nearest moving obstacles within sensing
    range (noisy relative position and velocity, presence flag), the coverage ratio, the path
    progress and the elapsed fraction of the time limit. Layout and scales:
    :mod:`aoass_env.observation`.

    ## Rewards

    Eq. 14 exactly: ``w1 * ΔCoverage - w2 * (max E_i / E_avg - 1) - w3 * RMSE_loc`` with
    w1 = 100, w2 = 0.01, w3 = 0.005 /m. ΔCoverage is the step's gain of the Eq. 18 coverage
    ratio; E_i the energy node i has spent so far; RMSE_loc an online estimate (covered nodes at
    the centroid of their heard beacons). Each weighted term is in ``info["reward_terms"]``;
    the opt-in shaping term ``w_collision`` (per new contact) defaults to 0. See
    :mod:`aoass_env.reward`.

    ## Starting State

    Each ``reset`` builds a new episode from ``self.np_random``: a generated obstacle map of
    ``obstacle_density`` (unless ``map`` is set), ``n_nodes`` nodes uniform over free space,
    moving obstacles at random free places with random headings, and the anchor at rest on the
    first free spiral waypoint from which the field is reachable (the field centre by
    default), facing +x.

    ## Episode End

    * Termination: the follower has reached or skipped every spiral waypoint (path complete).
    * Truncation: ``max_episode_steps`` control periods, ``time_limit_factor`` (5) times the
      ideal spiral's duration at nominal speed (7760 steps for the default config);
      ``gymnasium.make`` reports the same limit in ``env.spec.max_episode_steps`` (the limit
      of the env as made; a map given as a reset option brings its episode's own).

    Every step's ``info`` holds coverage, collisions, path length, beacons sent, energy, the
    online RMSE, the reward terms, and the follower's ``recoveries`` (back-outs after its
    progress watchdog found it stuck) and ``skipped_waypoints`` (free spiral waypoints it gave
    up as unreachable: ``env.unwrapped.follower.skipped`` says which, when and why); the last
    step's ``info["episode_metrics"]`` adds the Eq. 16-19 metrics. ``env.unwrapped.beacon_log``
    is the episode's :class:`BeaconLog`.

    ## Arguments

    ``gymnasium.make("AOASS-v0", render_mode=None, config=None, **keywords)``: any field of
    :class:`~aoass_env.config.AOASSConfig` as a keyword (e.g. ``field_size=200``,
    ``n_nodes=300``, ``obstacle_density=0.4``, ``map="test/d0.40_f100_s509"``,
    ``n_moving_obstacles=5``, ``radio_range=25``, ``beacon_interval=2``, ``w1``, ``w2``,
    ``w3``), or a whole ``config`` (an :class:`~aoass_env.config.AOASSConfig` or a dict of its
    fields; keywords override it); bad values raise ``ConfigError`` naming the field and its
    valid range. ``render_mode``: ``"rgb_array"`` or ``"human"`` (pygame window).
    ``reset(options={"map": ...})`` uses a map (name, path or ``ObstacleMap``) for one episode.

    ## Version History

    * v0: initial version.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 20}

    def __init__(self, render_mode: str | None = None,
                 config: AOASSConfig | Mapping[str, Any] | None = None,
                 action_type: ActionType | str | None = None,
                 adaptive: AdaptiveConfig | Mapping[str, Any] | None = None,
                 **kwargs: Any) -> None:
        self.config = config_with(config, kwargs, also=keyword_names(AOASSEnv.__init__))
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode={render_mode!r} is not one of "
                             f"{self.metadata['render_modes']} or None")
        self.render_mode = render_mode
        self._map = None
        given = {*kwargs, *(config if isinstance(config, Mapping) else ())}
        if isinstance(config, AOASSConfig) and config.obstacle_density != \
                AOASSConfig.__dataclass_fields__["obstacle_density"].default:
            given.add("obstacle_density")       # a config object's own: as good as given
        if self.config.map is not None:     # a map keeps its own size, never rescaled
            self._map = _option_map(self.config.map, "map")
            if "obstacle_density" in given:     # it would be ignored, yet logged as the episode's
                raise ConfigError(
                    f"obstacle_density={self.config.obstacle_density!r} sets the density of "
                    f"generated maps; map={self.config.map!r} brings its own obstacles "
                    f"(density {self._map.density:.2f}): give one of the two")
            self.config = config_for_map(self.config, self._map,
                                         explicit="field_size" in given)
        self.max_episode_steps = max_episode_steps(self.config)
        if isinstance(action_type, str):
            action_type = action_type_named(action_type).from_config(self.config)
        elif action_type is not None and not isinstance(action_type, ActionType):
            raise TypeError(f"action_type must be an aoass_env.action.ActionType or one of "
                            f"'residual', 'adaptive', got {type(action_type).__name__}")
        #: what an action means (:mod:`aoass_env.action`): the config's residual by default
        self.action_type = action_type or ResidualAction.from_config(self.config)
        #: the adaptive sweep's rule, used with the adaptive action type
        self.adaptive = AdaptiveConfig.coerce(adaptive, "adaptive")
        self._sweeps = isinstance(self.action_type, AdaptiveAction)
        if adaptive is not None and not self._sweeps:
            raise ValueError("adaptive= configures the adaptive sweep, which only the adaptive "
                             "action type drives; add action_type='adaptive' or leave adaptive "
                             "out")
        self._base_config = self.config      # the spiral of the time limit
        if self._sweeps:      # the adaptive sweep's passes
            self.config = sweep_config(self.config, self.adaptive, self.config.field_size)
        self.action_space = self.action_type.space
        self.observation_space = observation_space(self.config)
        self.obs_layout = observation_layout(self.config)
        self.sim: Simulator | None = None
        self._renderer: Any = None
        self._log: BeaconLog | None = None
        #: Set by :class:`~aoass_env.wrappers.ActionRepeat` around the steps whose observation
        #: nobody reads: such a step returns ``None`` for it and only measures what it would
        #: measure (:meth:`Observer.sense`); :meth:`deferred_observation` builds it on demand.
        self.defer_observation = False
        self._deferred = False

    # --- episode ----------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        self.sim = None         # a reset that fails leaves no episode to step on
        options = reset_options(options)
        episode_map = options.pop("map", None)
        if options:
            raise ValueError(f"unknown reset option(s) {sorted(options)}; valid: ['map']")
        config, limit = self.config, self._base_config
        if episode_map is not None:
            # the episode's map as its config (and beacon log) names it: the option's name or
            # path, None for a map object (it used to keep the constructor's map)
            name = str(episode_map) if isinstance(episode_map, (str, os.PathLike)) else None
            episode_map = _option_map(episode_map)
            side = map_side(episode_map, "reset option 'map'")
            if not math.isclose(side, config.field_size, rel_tol=1e-9):   # its own size
                config = limit = limit.replace(field_size=side, map=None)
                if self._sweeps:
                    config = sweep_config(config, self.adaptive, side)
            if config.map != name:
                config = config.replace(map=name)
        self.episode_config = config
        self.max_episode_steps = max_episode_steps(limit)
        sim = Simulator(config, self.np_random,
                        obstacle_map=episode_map if episode_map is not None else self._map,
                        seed=seed, method="aoass-env")
        noise_rng = self.np_random.spawn(1)[0]
        self._follower: WaypointFollower | AdaptiveSweep = (
            sim.adaptive_sweep(self.adaptive) if self._sweeps else sim.follower(recovery=True))
        # the waypoints observed are those the follower walks (a pruned spiral's, with the sweep)
        route = self._follower.follower if self._sweeps else sim.spiral
        self._observe = Observer(config, route, noise_rng)
        self._steps = 0
        self._deferred = False
        self._log = None
        self._static_contacts = self._moving_contacts = 0
        self._rmse = 0.0
        self._imbalance = energy_imbalance(sim.network.node_energy)
        self._command = self._follower.command(sim.world.position, sim.world.heading,
                                               self.config.dt)
        self.sim = sim          # the episode exists once every part of it does
        if self.render_mode == "human":
            self.render()
        return self._observation(), self._info()

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        sim = self.sim
        if sim is None:
            raise RuntimeError("call reset() before step()")
        if self._log is not None:
            raise RuntimeError("the episode has ended; call reset() to start a new one")
        c = self.config
        command, knobs = self.action_type.decode(action, self._command)
        record = sim.step(*command)
        if knobs is not None:
            self._follower.knobs = knobs
        self._steps += 1
        self._command = self._follower.command(sim.world.position, sim.world.heading, c.dt)
        if len(record.beacons):     # energies and estimates change only with beacons
            self._rmse = online_rmse(sim.nodes, sim.network.beacon_centroid,
                                     sim.network.covered)
            self._imbalance = energy_imbalance(sim.network.node_energy)
        world = sim.world
        static, moving = world.static_contacts + world.wall_contacts, world.moving_contacts
        cost_static, cost_moving = static - self._static_contacts, moving - self._moving_contacts
        self._static_contacts, self._moving_contacts = static, moving
        terms = reward_terms(c, delta_coverage=record.newly_covered / sim.network.n_nodes,
                             imbalance=self._imbalance, rmse=self._rmse,
                             new_contacts=cost_static + cost_moving)
        terminated = self._follower.done
        truncated = not terminated and self._steps >= self.max_episode_steps
        info = self._info()
        info["reward_terms"] = terms
        info.update(cost=float(cost_static + cost_moving), cost_static=float(cost_static),
                    cost_moving=float(cost_moving))
        if terminated or truncated:
            self._log = sim.finish()
            info["episode_metrics"] = self._episode_metrics()
        if self.render_mode == "human":
            self.render()
        self._deferred = self.defer_observation
        if self._deferred:
            self._observe.sense(sim.world)
            return None, float(sum(terms.values())), terminated, truncated, info
        return self._observation(), float(sum(terms.values())), terminated, truncated, info

    def deferred_observation(self) -> np.ndarray:
        """The observation the last step deferred (:attr:`defer_observation`), the vector it
        would have returned: the state has not changed since."""
        self._started("deferred_observation")
        if not self._deferred:
            raise RuntimeError("deferred_observation() reads the observation of a step run with "
                               "defer_observation set; the last step returned its own")
        return self._observation_vector()

    def end_episode(self) -> dict[str, Any]:
        """End the episode now, as a time limit outside the environment does
        (:class:`EndOnTruncation`), and return its
        ``info["episode_metrics"]``; the beacon log is complete from here on."""
        sim = self._started("end_episode")
        if self._log is None:
            self._log = sim.finish()
        return self._episode_metrics()

    # --- what the agent and the user see -----------------------------------------------------
    def _observation(self) -> np.ndarray:
        self._observe.sense(self.sim.world)
        return self._observation_vector()

    def _observation_vector(self) -> np.ndarray:
        """The observation vector of the state :meth:`Observer.sense` last measured."""
        sim = self.sim
        heading_error = (wrap_angle(self._command[1] - sim.world.heading)
                         if not self._follower.done else 0.0)
        return self._observe.vector(sim.world, follower_index=self._follower.index,
                                    heading_error=heading_error,
                                    coverage=sim.network.coverage_ratio,
                                    progress=self._follower.progress(),
                                    time_fraction=min(self._steps / self.max_episode_steps, 1.0),
                                    coverage_map=sim.coverage_map)

    def _info(self) -> dict[str, Any]:
        sim, net = self.sim, self.sim.network
        return {"coverage": net.coverage_ratio, "covered_nodes": net.n_covered,
                "collisions": sim.collisions, "static_contacts": sim.world.static_contacts,
                "wall_contacts": sim.world.wall_contacts,
                "moving_contacts": sim.world.moving_contacts,
                "path_length": net.distance_travelled, "beacons": net.beacons_sent,
                "energy_anchor": net.anchor_energy, "energy_nodes": net.node_energy_total,
                "energy_total": net.energy_total, "rmse_online": self._rmse,
                "progress": self._follower.progress(), "time": sim.world.time,
                "recoveries": self._follower.recoveries,
                "skipped_waypoints": len(self._follower.skipped),
                "area_coverage": sim.coverage_map.ratio,
                "passed_waypoints": self._passed()}

    def _passed(self) -> int:
        """Spiral waypoints the adaptive sweep passed over by choice (0 for the follower)."""
        return len(self._follower.passed) if isinstance(self._follower, AdaptiveSweep) else 0

    def _episode_metrics(self) -> dict[str, Any]:
        """:func:`~aoass_env.simulator.episode_summary` of the episode, with the online RMSE
        (m), the control periods taken, and the follower's recoveries and skipped waypoints."""
        return {**episode_summary(self.sim, self._follower.done), "rmse_online": self._rmse,
                "steps": self._steps, "recoveries": self._follower.recoveries,
                "skipped_waypoints": len(self._follower.skipped),
                "area_coverage": self.sim.coverage_map.ratio,
                "passed_waypoints": self._passed()}

    # --- what wrappers read (world frame) -------------------------------------------------------
    def _started(self, what: str) -> Simulator:
        if self.sim is None:
            raise RuntimeError(f"call reset() before reading {what}")
        return self.sim

    @property
    def nominal_command(self) -> tuple[float, float]:
        """The follower's (speed [m/s], heading [rad]) for the next step: what the zero action
        commands (``action_type`` maps an action onto it)."""
        self._started("nominal_command")
        return self._command

    @property
    def anchor(self) -> AnchorState:
        """The anchor's position, velocity, heading and speed now, and its gap to the nearest
        obstacle as the last observation measured it (d_obs; the world has not moved since)."""
        world = self._started("anchor").world
        return AnchorState(world.position, world.velocity, world.heading, world.speed,
                           self._observe.obstacle_gap)

    @property
    def obstacle_map(self) -> ObstacleMap:
        """The episode's static obstacle map (at its own size)."""
        return self._started("obstacle_map").map

    @property
    def detections(self) -> np.ndarray:
        """(D, 4) the moving obstacles the last observation detected, world frame: x, y (m),
        vx, vy (m/s), with the sensor's noise, nearest first; every one in sensing range (the
        observation holds only the nearest ``obs_moving_obstacles``, normalised and clipped)."""
        self._started("detections")
        return self._observe.detections

    @property
    def follower(self) -> WaypointFollower | AdaptiveSweep:
        """The episode's controller: the nominal path follower, or the adaptive sweep under the
        adaptive action type (their ``skipped`` waypoints and ``recoveries``)."""
        if self.sim is None:
            raise RuntimeError("call reset() before reading follower")
        return self._follower

    @property
    def beacon_log(self) -> BeaconLog | None:
        """The episode's :class:`BeaconLog`: complete once the episode has ended, a snapshot of
        the episode so far before that; None before the first reset."""
        if self._log is not None:
            return self._log
        return self.sim.finish() if self.sim is not None else None

    # --- rendering ---------------------------------------------------------------------------
    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode="
                            "'rgb_array' or 'human' to gymnasium.make")
            return None
        if self.sim is None:
            raise RuntimeError("call reset() before render()")
        if self._renderer is None:
            from aoass_env.render import Renderer
            self._renderer = Renderer(self.render_mode, self.metadata["render_fps"])
        return self._renderer.draw(self.sim, self._follower)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


def reset_options(options: Any) -> dict[str, Any]:
    """A copy of ``reset(options=...)`` as a dict (None: no option); ValueError naming
    ``options`` for anything but a mapping with string keys (a string or a list of pairs was
    read as pairs, or failed deep in ``dict()``)."""
    if options is None:
        return {}
    if not isinstance(options, Mapping) or not all(isinstance(k, str) for k in options):
        raise ValueError(f"reset options must be a dict like {{'map': 'test/d0.10_f100_s500'}} "
                         f"or None, got {type(options).__name__} {options!r:.80}")
    return dict(options)


class EpisodeTimeLimit(TimeLimit):
    """A ``TimeLimit`` that takes each episode's own limit at ``reset``: a map given with
    ``reset(options={"map": ...})`` brings its own field size and so its own limit.

    Its ``spec`` keeps the limit of the environment as made (the recipe ``gymnasium.make(
    env.spec)`` rebuilds it from; a reset option is not part of it); the episode's own limit is
    ``env.unwrapped.max_episode_steps``."""

    def __init__(self, env: gym.Env, max_episode_steps: int) -> None:
        super().__init__(env, max_episode_steps)
        self._made_limit = max_episode_steps

    def reset(self, **kwargs: Any) -> Any:
        out = super().reset(**kwargs)
        self._max_episode_steps = self.env.unwrapped.max_episode_steps
        return out

    @property
    def spec(self) -> gym.envs.registration.EnvSpec | None:
        spec = self.env.spec
        if spec is None:
            return None
        spec = deepcopy(spec)
        spec.max_episode_steps = self._made_limit
        return spec


def agent_step_limit(env: gym.Env) -> int:
    """The current episode's step limit (steps of ``env``): the environment's own limit
    (:attr:`AOASSEnv.max_episode_steps`), rounded up over the control periods each step of a
    wrapper in between holds (its ``periods_per_step``, :class:`~aoass_env.wrappers.
    ActionRepeat`'s ``repeat``), innermost first."""
    holds = []
    layer = env
    while isinstance(layer, gym.Wrapper):
        holds.append(getattr(layer, "periods_per_step", 1))
        layer = layer.env
    if not isinstance(layer, AOASSEnv):
        raise TypeError(f"agent_step_limit reads an AOASS-v0 environment, got "
                        f"{type(layer).__name__}")
    limit = layer.max_episode_steps
    for periods in reversed(holds):
        limit = math.ceil(limit / periods)
    return limit


def make_env(**kwargs: Any) -> gym.Env:
    """An :class:`AOASSEnv` built from ``kwargs`` in a ``TimeLimit`` of its own step limit."""
    env = AOASSEnv(**kwargs)
    return EpisodeTimeLimit(env, env.max_episode_steps)


make_env.metadata = AOASSEnv.metadata  # lets gymnasium.make check render modes


class EndOnTruncation(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """The outermost wrapper of every registered id: ``gymnasium.make`` applies it outside the
    ``TimeLimit`` that ``gymnasium.make(..., max_episode_steps=N)`` adds, and when that limit
    ends an episode the environment has not ended itself, it ends it
    (:meth:`AOASSEnv.end_episode <aoass_env.env.AOASSEnv.end_episode>`) and adds
    ``info["episode_metrics"]``.

    ``env.spec`` keeps the limit of the environment as made, whatever map a reset option
    brings (the spec is the recipe ``gymnasium.make(env.spec)`` rebuilds the environment from;
    it used to report the last episode's limit, so that an env remade after a reset on a
    smaller map cut every episode at that map's limit, and after a bigger one was refused). An
    outer ``TimeLimit`` of exactly that limit -- what ``gymnasium.make(env.spec)`` adds --
    follows each episode's own limit (:func:`agent_step_limit`), as the environment's own
    does; any other limit of yours stays fixed."""

    def __init__(self, env: gym.Env) -> None:
        gym.utils.RecordConstructorArgs.__init__(self)
        gym.Wrapper.__init__(self, env)
        if not isinstance(env.unwrapped, AOASSEnv):
            raise TypeError(f"EndOnTruncation wraps an AOASS-v0 environment, got "
                            f"{type(env.unwrapped).__name__}")
        inner = env.env if type(env) is TimeLimit else None
        self._repeated = env if inner is not None and inner.spec is not None \
            and env._max_episode_steps == inner.spec.max_episode_steps else None
        if self._repeated is not None:
            self._repeated.spec    # noqa: B018  (cached now: the limit as made, not an episode's)
        own = None if inner is None or inner.spec is None else inner.spec.max_episode_steps
        if own is not None and env._max_episode_steps > own:
            # the environment truncates itself at its own limit: the spec would report a
            # limit no episode reaches
            factor = env.unwrapped.config.time_limit_factor
            raise ConfigError(
                f"max_episode_steps={env._max_episode_steps} is above the environment's own "
                f"limit of {own} agent steps (time_limit_factor={factor:g} x the ideal "
                f"spiral's duration on this field), which would end every episode first; for "
                f"longer episodes raise time_limit_factor (the limit grows in proportion to "
                f"it), or give max_episode_steps <= {own}")

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        out = self.env.reset(**kwargs)
        if self._repeated is not None:
            self._repeated._max_episode_steps = agent_step_limit(self._repeated.env)
        return out

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        if (terminated or truncated) and "episode_metrics" not in info:
            info["episode_metrics"] = self.env.unwrapped.end_episode()
        return obs, reward, terminated, truncated, info
