"""One validated configuration for the whole simulator.

Every tunable number of the simulation core lives in :class:`AOASSConfig`. Each field carries its
unit, its valid range and a one-line description as dataclass metadata; validation reads that
metadata, so the documentation and the checks cannot drift apart. Build a config from user
keywords with :meth:`AOASSConfig.from_kwargs`, which rejects unknown keywords with a
did-you-mean suggestion.

Defaults follow Table 1 of the paper where it gives a figure (R = 25 m, Δs = 2 m beacon interval,
E_0 = 2 J per node, 50 nJ/bit radio, 0.8 J/m anchor motion) and are documented choices where the
paper is silent (docs/interpretations.md).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from aoass_env.validators import ConfigError, ValidatedConfig, param, unknown_key_message

__all__ = ["AOASSConfig", "ConfigError", "check_keywords", "config_for_map", "config_with",
           "map_side", "unknown_key_message"]

#: The largest spiral :class:`AOASSConfig` accepts, roughly estimated from its fields: legs
#: and waypoints (more exhausted memory or ran for minutes before failing).
MAX_SPIRAL_LEGS = 50_000
MAX_SPIRAL_WAYPOINTS = 2_000_000


@dataclass(frozen=True)
class AOASSConfig(ValidatedConfig):
    """All parameters of the simulation core (units in each field's metadata and docs/env.md)."""

    # --- field and map -------------------------------------------------------------------
    field_size: float = param(100.0, "side of the square field", unit="m", low=10.0, high=2000.0)
    n_nodes: int = param(100, "number of static sensor nodes", low=1, high=100_000, kind="int")
    obstacle_density: float = param(
        0.2, "obstacle area / field area of a generated map", low=0.0, high=0.6)
    map: str | None = param(
        None, "None: generate a map per episode; else a map file path or a shipped map name",
        kind="str", optional=True)
    map_clearance: float = param(
        2.5, "narrowest passage a map must keep open for the anchor (generated maps are built "
        "so; loaded maps are checked)", unit="m",
        low=0.0, high=20.0, low_open=True)

    # --- moving obstacles ----------------------------------------------------------------
    n_moving_obstacles: int = param(3, "number of moving obstacles", low=0, high=200, kind="int")
    moving_obstacle_radius: float = param(
        1.0, "radius of a moving obstacle", unit="m", low=0.0, high=10.0, low_open=True)
    moving_obstacle_speed: tuple[float, float] = param(
        (0.3, 1.0), "(min, max) speed of moving obstacles", unit="m/s", low=0.0, high=10.0,
        kind="range")
    moving_obstacle_turn_rate: float = param(
        0.1, "mean number of random heading changes per second (Poisson)", unit="1/s",
        low=0.0, high=10.0)

    # --- anchor dynamics and sensing -----------------------------------------------------
    anchor_radius: float = param(0.5, "anchor body radius", unit="m", low=0.0, high=5.0,
                              low_open=True)
    anchor_nominal_speed: float = param(
        1.0, "cruise speed of the path follower", unit="m/s", low=0.0, high=20.0, low_open=True)
    anchor_max_speed: float = param(2.0, "speed limit", unit="m/s", low=0.0, high=20.0,
                                 low_open=True)
    anchor_max_accel: float = param(1.0, "acceleration limit", unit="m/s^2", low=0.0, high=50.0,
                                 low_open=True)
    anchor_max_turn_rate: float = param(
        math.pi / 2, "turn-rate limit", unit="rad/s", low=0.0, high=20.0, low_open=True)
    dt: float = param(0.5, "control period (one env step)", unit="s", low=0.0, high=10.0,
                   low_open=True)
    physics_substeps: int = param(5, "pymunk steps per control period", low=1, high=100,
                               kind="int")
    n_rays: int = param(16, "range-sensor rays, evenly spread over 360 deg", low=1, high=360,
                     kind="int")
    sensing_range: float = param(10.0, "range-sensor reach", unit="m", low=0.0, high=200.0,
                              low_open=True)

    # --- spiral and beacons --------------------------------------------------------------
    beacon_interval: float = param(
        2.0, "distance travelled between beacons (Table 1's step size)", unit="m", low=0.0,
        high=100.0, low_open=True)
    spiral_spacing: float | None = param(
        None, "distance between parallel spiral passes (Eq. 2 leg increment); None = derived "
        "from R (planning.square_spiral.default_spacing)", unit="m", low=0.0, high=1000.0,
        low_open=True, optional=True)
    spiral_origin: tuple[float, float] | None = param(
        None, "(x0, y0) of the spiral; None = field centre", unit="m", kind="point",
        optional=True)
    waypoint_step: float | None = param(
        None, "distance between waypoints along a leg (Eq. 1 step); None = beacon_interval",
        unit="m", low=0.0, high=1000.0, low_open=True, optional=True)
    edge_margin: float = param(
        1.5, "inset of the outermost spiral pass from the field border", unit="m", low=0.0,
        high=100.0)

    # --- radio ---------------------------------------------------------------------------
    radio_range: float = param(25.0, "communication range R", unit="m", low=0.0, high=1000.0,
                            low_open=True)
    line_of_sight: bool = param(True, "obstacles block radio links", kind="bool")
    doi: float = param(0.0, "degree of irregularity of the radio range (0 = unit disk)",
                    low=0.0, high=0.5)
    packet_bits: int = param(256, "size of a beacon packet", unit="bit", low=1, high=1_000_000,
                          kind="int")
    e_elec: float = param(50e-9, "radio electronics energy (Table 1)", unit="J/bit", low=0.0,
                       high=1e-3)
    e_amp: float = param(10e-12, "transmit amplifier energy (free-space, d^2)", unit="J/bit/m^2",
                      low=0.0, high=1e-6)
    node_initial_energy: float = param(2.0, "initial energy of a node (Table 1)", unit="J",
                                    low=0.0, high=1e6, low_open=True)
    anchor_motion_energy: float = param(0.8, "anchor motion cost (Table 1)", unit="J/m",
                                     low=0.0, high=1e3)
    collinearity_tol: float = param(
        1.0, "Eq. 18: heard beacons count as non-collinear when their root-sum-square distance "
        "from the best-fit line is at least this", unit="m", low=0.0, high=100.0, low_open=True)
    coverage_cell: float = param(
        2.5, "cell side of the anchor's own coverage map (planning.coverage: Eq. 18 over the "
        "free field as the anchor knows it)", unit="m", low=0.1, high=100.0)

    # --- reward (Eq. 14) -----------------------------------------------------------------
    w1: float = param(100.0, "Eq. 14 weight of the coverage gain", low=0.0, high=1e6)
    w2: float = param(0.01, "Eq. 14 weight of the energy imbalance", low=0.0, high=1e6)
    w3: float = param(0.005, "Eq. 14 weight of the online localization RMSE", unit="1/m",
                   low=0.0, high=1e6)
    w_collision: float = param(
        0.0, "opt-in shaping, not in Eq. 14: penalty per new anchor contact with an obstacle",
        low=0.0, high=1e6)

    # --- path follower: progress watchdog and recovery ------------------------------------
    watchdog_time: float = param(
        8.0, "the environment's follower is stuck when its distance to go has not shrunk by "
        "watchdog_progress for this long; it then backs out and re-plans around the spot, and "
        "gives the target up after two tries", unit="s", low=0.0, high=1e4, low_open=True)
    watchdog_progress: float = param(
        1.0, "progress along the follower's plan that resets the watchdog", unit="m", low=0.0,
        high=100.0, low_open=True)
    backout_distance: float = param(
        3.0, "how far back along its own track a stuck follower retreats before re-planning",
        unit="m", low=0.0, high=100.0)
    replan_excess: float | None = param(
        None, "a stuck follower's re-plan round its keep-outs longer than the plain way to the "
        "target by more than this is not taken (None: always taken)", unit="m", low=0.0,
        high=1e4, optional=True)

    # --- environment: observation, action, episode ---------------------------------------
    obs_waypoints: int = param(8, "K: upcoming spiral waypoints in the observation", low=1,
                            high=100, kind="int")
    obs_moving_obstacles: int = param(
        3, "M: nearest moving obstacles within sensing range in the observation", low=0,
        high=100, kind="int")
    obs_position_noise: float = param(
        0.3, "std of the Gaussian noise on observed moving-obstacle positions", unit="m",
        low=0.0, high=100.0)
    obs_velocity_noise: float = param(
        0.2, "std of the Gaussian noise on observed moving-obstacle velocities", unit="m/s",
        low=0.0, high=100.0)
    obs_coverage_sectors: int = param(
        0, "sectors of the egocentric coverage summary in the observation (mean coverage "
        "deficit by bearing within 2 R; 0: none, the adaptive setup uses 8)", low=0, high=64,
        kind="int")
    action_speed_scale: float = param(
        1.0, "speed change commanded by action[0] = +-1 on top of the follower's speed",
        unit="m/s", low=0.0, high=20.0, low_open=True)
    action_heading_scale: float = param(
        math.pi / 2, "heading change commanded by action[1] = +-1 on top of the follower's "
        "heading", unit="rad", low=0.0, high=math.pi, low_open=True)
    time_limit_factor: float = param(
        5.0, "episode time limit as a multiple of the ideal path's duration at nominal speed "
        "(the environment's: of the ideal spiral's; every evaluated method gets the same)",
        low=1.0, high=100.0)

    def _check(self) -> None:
        if self.anchor_nominal_speed > self.anchor_max_speed:
            raise ConfigError(
                f"anchor_nominal_speed={self.anchor_nominal_speed} must not exceed "
                f"anchor_max_speed={self.anchor_max_speed}")
        if self.map_clearance < 2 * self.anchor_radius:
            raise ConfigError(
                f"map_clearance={self.map_clearance} m must be at least the anchor diameter "
                f"2 * anchor_radius = {2 * self.anchor_radius} m")
        lo, hi = self.moving_obstacle_speed
        if lo > hi:
            raise ConfigError(f"moving_obstacle_speed=({lo}, {hi}): min must be <= max")
        if 2 * self.map_clearance >= self.field_size:
            raise ConfigError(f"map_clearance={self.map_clearance} m must be less than half of "
                              f"field_size={self.field_size} m (no free space would remain)")
        if 2 * self.edge_margin >= self.field_size:
            raise ConfigError(f"edge_margin={self.edge_margin} must be less than half of "
                              f"field_size={self.field_size}")
        if self.anchor_radius > self.edge_margin:
            # the outermost pass runs edge_margin from the border: a start there overlapped
            # the wall (a ValueError at some resets)
            raise ConfigError(f"edge_margin={self.edge_margin} m must be at least anchor_radius="
                              f"{self.anchor_radius} m (the outermost pass runs edge_margin "
                              f"from the border)")
        if self.beacon_interval >= self.radio_range:
            raise ConfigError(f"beacon_interval={self.beacon_interval} m must be below "
                              f"radio_range={self.radio_range} m (Eq. 5's spacing)")
        widest = math.sqrt(self.radio_range**2 - self.beacon_interval**2) - self.edge_margin
        if self.spiral_spacing is None and widest <= 0:
            raise ConfigError(
                f"edge_margin={self.edge_margin} m leaves no spiral spacing: Eq. 5's "
                f"sqrt(radio_range^2 - beacon_interval^2) - edge_margin = {widest:.4g} m for "
                f"radio_range={self.radio_range} m and beacon_interval={self.beacon_interval} m")
        # the spiral's size: the fitted spacing is at least half the widest (module docs of
        # planning.square_spiral) or the field's half; a spiral of millions of waypoints or
        # legs exhausted memory or ran for minutes before failing
        spacing = self.spiral_spacing or min(widest / 2, self.field_size / 2 - self.edge_margin)
        legs = 2 * self.field_size / spacing
        waypoints = (self.field_size**2 / spacing + 4 * self.field_size) / self.path_step
        if not (legs <= MAX_SPIRAL_LEGS and waypoints <= MAX_SPIRAL_WAYPOINTS):
            raise ConfigError(
                f"the spiral would have about {legs:.3g} legs and {waypoints:.3g} waypoints "
                f"(at most {MAX_SPIRAL_LEGS} and {MAX_SPIRAL_WAYPOINTS}): field_size="
                f"{self.field_size} m, spiral_spacing={self.spiral_spacing}, waypoint step "
                f"{self.path_step} m (waypoint_step, else beacon_interval); use a larger "
                f"spacing or step")
        if self.cell_range <= self.coverage_cell:     # (it used to fail at every reset)
            raise ConfigError(
                f"coverage_cell={self.coverage_cell:g} m is too large for radio_range="
                f"{self.radio_range:g} m and doi={self.doi:g}: the guaranteed range R (1 - doi) "
                f"- cell / sqrt(2) must exceed one cell")
        if self.spiral_origin is not None:    # the spiral runs inside the edge margin
            x, y = self.spiral_origin
            lo, hi = self.edge_margin, self.field_size - self.edge_margin
            if not (lo <= x <= hi and lo <= y <= hi):
                raise ConfigError(
                    f"spiral_origin={self.spiral_origin} must lie inside the field shrunk by "
                    f"edge_margin={self.edge_margin}: [{lo:g}, {hi:g}] x [{lo:g}, {hi:g}] m")
    # --- derived quantities ----------------------------------------------------------
    @property
    def substep_dt(self) -> float:
        """Physics step (s)."""
        return self.dt / self.physics_substeps

    @property
    def cell_range(self) -> float:
        """r_cell (m): the range within which a coverage cell surely hears a beacon, the
        guaranteed range R (1 - doi) less half a cell's diagonal
        (:mod:`aoass_env.planning.coverage`)."""
        return self.radio_range * (1.0 - self.doi) - self.coverage_cell / math.sqrt(2.0)

    @property
    def path_step(self) -> float:
        """Distance between the waypoints of a planned path (m): ``waypoint_step``, else
        ``beacon_interval``."""
        return self.waypoint_step or self.beacon_interval


def check_keywords(keywords: Iterable[str], also: Iterable[str] = ()) -> None:
    """:class:`ConfigError` for the first of ``keywords`` that is neither a field of
    :class:`AOASSConfig` nor one of ``also`` (the caller's own keywords), with a did-you-mean
    suggestion drawn from both."""
    names = [f.name for f in dataclasses.fields(AOASSConfig)]
    own = [name for name in also if name not in names]
    for key in keywords:
        if key not in names and key not in own:
            raise ConfigError(unknown_key_message(key, [*names, *own], AOASSConfig.KEYWORD))


def config_with(config: AOASSConfig | Mapping[str, Any] | None, keywords: Mapping[str, Any],
                also: Iterable[str] = ()) -> AOASSConfig:
    """The config of ``config`` (an :class:`AOASSConfig`, a HighwayEnv-style dict of its
    fields, or None: the defaults) with ``keywords`` overriding it; :class:`ConfigError` naming
    ``config`` for another type, or the unknown key with a did-you-mean suggestion among the
    fields and ``also`` (the caller's own keywords, which a misspelling may have meant)."""
    check_keywords(keywords, also)
    plain = dict(config) if isinstance(config, Mapping) else config
    return AOASSConfig.coerce(plain, "config").replace(**keywords)


def map_side(obstacle_map: Any, name: Any = "map") -> float:
    """The side (m) of a square map (an :class:`~aoass_env.maps.ObstacleMap` read at its own
    size); :class:`ConfigError` naming ``map`` for a map that is not square."""
    width, height = float(obstacle_map.width), float(obstacle_map.height)
    if not math.isclose(width, height, rel_tol=1e-9):
        raise ConfigError(f"map={name!r} is {width:g} x {height:g} m; the field must be square "
                          f"(field_size is one side)")
    return width


def config_for_map(config: AOASSConfig, obstacle_map: Any, *,
                   explicit: bool = False) -> AOASSConfig:
    """``config`` for ``obstacle_map`` (its ``map``, read at its own size: a map is never
    rescaled): as it is when the map is a ``field_size`` square, with the map's side as
    ``field_size`` when that was left at its default (and not given ``explicit``-ly), else a
    :class:`ConfigError` naming ``map`` and ``field_size``."""
    name = config.map
    side = map_side(obstacle_map, name)
    meta = AOASSConfig.__dataclass_fields__["field_size"].metadata
    if not meta["low"] <= side <= meta["high"]:
        raise ConfigError(f"map={name!r} is a {side:g} m field; a map's side must be in "
                          f"[{meta['low']:g}, {meta['high']:g}] m (field_size's range)")
    if math.isclose(side, config.field_size, rel_tol=1e-9):
        return config
    if not explicit and config.field_size == _DEFAULT_FIELD_SIZE:
        return config.replace(field_size=side)
    raise ConfigError(f"map={name!r} is a {side:g} m field but field_size={config.field_size:g}: "
                      f"a map keeps its own size; give field_size={side:g} or leave field_size "
                      f"out")


_DEFAULT_FIELD_SIZE = AOASSConfig.__dataclass_fields__["field_size"].default
