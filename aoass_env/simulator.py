"""One episode of the simulation core, wired together.

:class:`Simulator` builds an episode from a config and a random generator -- obstacle map, sensor
nodes, square spiral, pymunk world, radio, network state and beacon-log recorder -- and advances
it one control period at a time from (speed, heading) commands. It holds no geometry, radio or
energy maths of its own: each part lives in its module. The Gymnasium environment wraps it.

Random draws happen in a fixed order (map, nodes, moving obstacles, radio irregularity, then the
moving obstacles' motion), all from the one generator, so a seed fixes the whole episode.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from aoass_env.beacon_log import BeaconLog, BeaconLogRecorder, episode_config_json
from aoass_env.config import AOASSConfig, ConfigError, config_for_map
from aoass_env.maps import MapError, ObstacleMap, generate_map, load_map
from aoass_env.metrics import energy_efficiency_ratio, energy_per_beacon, trajectory_efficiency
from aoass_env.network import Network
from aoass_env.planning import (
    AdaptiveConfig,
    AdaptiveSweep,
    CoverageMap,
    SquareSpiral,
    WaypointFollower,
    WaypointPath,
)
from aoass_env.planning.detour import DETOUR_MARGIN, DetourPlanner
from aoass_env.planning.square_spiral import config_spacing, episode_spiral
from aoass_env.planning.sweep import Controller
from aoass_env.radio import Radio, receivers_at
from aoass_env.trajectory import beacons_of_rows
from aoass_env.world import World


@dataclass(frozen=True)
class StepRecord:
    """What one control period produced.

    Attributes:
        beacons: (B, 3) rows (t [s], x [m], y [m]) broadcast during the period.
        newly_covered: nodes that became covered (Eq. 18) during the period.
        distance: distance the anchor travelled (m).
    """

    beacons: np.ndarray
    newly_covered: int
    distance: float


def episode_map(config: AOASSConfig, rng: np.random.Generator) -> ObstacleMap:
    """The episode's obstacle map: ``config.map`` if set, else a fresh generated one."""
    if config.map is None:
        return generate_map(config.field_size, config.obstacle_density, rng,
                            clearance=config.map_clearance)
    return load_map(config.map)          # at its own size: a map is never rescaled


#: The longest episode (control periods) :func:`episode_step_limit` gives.
MAX_EPISODE_STEPS = 10**9


def episode_step_limit(config: AOASSConfig, nominal_time: float, what: str) -> int:
    """Control periods an episode may take: ``time_limit_factor`` times ``nominal_time`` (s,
    a path's duration at nominal speed), ``ceil(factor * (nominal_time / dt))``, for the env
    and the Simulator alike. :class:`ConfigError` beyond :data:`MAX_EPISODE_STEPS`; ``what``
    names the path in it."""
    limit = config.time_limit_factor * (nominal_time / config.dt)   # the env's order, to the bit
    if not limit <= MAX_EPISODE_STEPS:          # math.ceil(inf) was an OverflowError
        raise ConfigError(
            f"the episode would last {limit:.3g} control periods (at most {MAX_EPISODE_STEPS}):"
            f" time_limit_factor={config.time_limit_factor} x {what}'s "
            f"{nominal_time:.3g} s at anchor_nominal_speed="
            f"{config.anchor_nominal_speed} m/s, over dt={config.dt} s")
    return math.ceil(limit)


def check_waypoint_step(config: AOASSConfig, obstacle_map: ObstacleMap) -> None:
    """:class:`ConfigError` naming ``waypoint_step`` when it exceeds the spiral's pass spacing
    on ``obstacle_map``'s field: longer steps cut the legs' corners and skip whole stretches."""
    spacing = config_spacing(config, obstacle_map.width, obstacle_map.height)
    if config.waypoint_step is not None and config.waypoint_step > spacing:
        raise ConfigError(f"waypoint_step={config.waypoint_step:g} m must not exceed the "
                          f"spiral's pass spacing {spacing:.3g} m (spiral_spacing, else derived "
                          f"from radio_range): longer steps skip whole stretches of the field")


class Simulator:
    """One episode: map, nodes, spiral, world, radio, network and beacon log.

    Args:
        config: the validated configuration.
        rng: the episode's only source of randomness.
        obstacle_map: use this map instead of ``config.map`` / a generated one.
        seed: recorded in the beacon log's config (the seed that made ``rng``).
        method: recorded in the beacon log's config (the method that drives the anchor).
        path: the path the anchor sweeps (a baseline planner's); default the square spiral.
            The anchor starts on its first free waypoint from which the field is reachable.

    Attributes:
        spiral: the episode's square spiral (the environment's reference path).
        path: the swept path: ``path`` if given, else ``spiral``.
    """

    def __init__(self, config: AOASSConfig, rng: np.random.Generator, *,
                 obstacle_map: ObstacleMap | None = None, seed: int | None = None,
                 method: str = "spiral", path: WaypointPath | None = None) -> None:
        self.map = obstacle_map if obstacle_map is not None else episode_map(config, rng)
        if obstacle_map is None and config.map is not None:
            config = config_for_map(config, self.map)     # a named map brings its own size
        check_waypoint_step(config, self.map)
        self.config = config
        try:
            self.map.check_traversable(config.map_clearance)
        except MapError as err:
            certified = AOASSConfig.map_clearance          # scripts/make_maps.py's clearance
            if config.map is None or config.map_clearance >= certified:
                raise
            raise MapError(f"{err}; the shipped maps are made and checked at map_clearance="
                           f"{certified:g} m: below it, room behind a narrower neck counts as "
                           f"cut off") from None
        self.nodes = self.map.sample_free_points(config.n_nodes, rng)
        self.spiral = episode_spiral(config, self.map)
        self.path: SquareSpiral | WaypointPath = (
            self.spiral if path is None else path.with_obstacles(self.map, config.anchor_radius))
        #: index of the waypoint the anchor starts on; the nominal follower sweeps from there
        self.start_index = self._start_index()
        start = self.path.waypoints[self.start_index]
        self.world = World(config, self.map, rng, tuple(start))
        self.radio = Radio.from_config(self.nodes, self.map, config, rng)
        self.network = Network(config.n_nodes, config)
        #: the anchor's own coverage map (:mod:`aoass_env.planning.coverage`), updated with
        #: every beacon
        self.coverage_map = CoverageMap(self.map, config)
        self.recorder = BeaconLogRecorder(
            config_json=episode_config_json(config, seed=seed, method=method),
            obstacle_map=self.map, nodes=self.nodes, radio_range=config.radio_range)
        self._odometer = 0.0
        self.recorder.add_path_point(0.0, start)
        self._broadcast(np.array([[0.0, *start]]))

    def _start_index(self) -> int:
        """The waypoint the anchor starts on: the path's first free waypoint from which the
        detour planner reaches the map's main free region (not one shut in a pocket, or wedged
        against an obstacle's corner) and which leads out by exact clearance
        (:meth:`~aoass_env.planning.detour.DetourPlanner.leads_out`: not a nook whose exit
        only the planner's grid takes for open); else the first that reaches the main region;
        else the first free waypoint.

        Raises:
            MapError: every waypoint lies inside an obstacle.
        """
        free = np.flatnonzero(~self.path.blocked)
        if len(free) == 0:
            raise MapError(
                f"every waypoint of the path lies inside an obstacle (map "
                f"{self.map.name or 'given'}, {self.map.width:g} m, density "
                f"{self.map.density:.2f}); nowhere to start: a "
                f"lower obstacle_density, a larger field_size or a smaller spiral_spacing")
        radius, points = self.config.anchor_radius, self.path.waypoints
        first = None
        for i in free:
            if self.planner.can_start(points[i], radius):
                if self.planner.leads_out(points[i]):
                    return int(i)
                first = i if first is None else first
        return int(free[0] if first is None else first)

    def _broadcast(self, beacons: np.ndarray) -> int:
        newly = 0
        for t, x, y in beacons.tolist():     # Python floats: the recorder's fast path
            pos = np.array([x, y])
            # the nodes' and the coverage map's links in one line-of-sight test
            receivers, cells = receivers_at(pos, [(self.radio, None),
                                                  self.coverage_map.listeners()])
            newly += self.network.record_beacon(pos, receivers)
            self.coverage_map.add_beacon(pos, cells)
            self.recorder.add_beacon(t, (x, y), receivers)
        return newly

    def step(self, speed_cmd: float, heading_cmd: float) -> StepRecord:
        """Advance one control period with a commanded speed (m/s) and heading (rad)."""
        rows = self.world.advance(speed_cmd, heading_cmd)
        start = self._odometer
        beacons, odometer = beacons_of_rows(rows, start, self.config.beacon_interval)
        distance = odometer - start
        self._odometer = odometer
        self.network.charge_motion(distance)
        newly = self._broadcast(beacons) if len(beacons) else 0
        t, x, y = rows[-1]
        self.recorder.add_path_point(t, (x, y))
        return StepRecord(beacons, newly, distance)

    @functools.cached_property
    def planner(self) -> DetourPlanner:
        """Detour planner for the anchor on this episode's map (built on first use)."""
        return DetourPlanner.for_map(self.map, self.config.anchor_radius + DETOUR_MARGIN)

    def follower(self, recovery: bool = False) -> WaypointFollower:
        """A nominal follower of this episode's path from the start waypoint on; ``recovery``
        adds the progress watchdog that backs out of traps and re-plans (the environment's
        follower, whose zero action sweeps the spiral); without it, the plain follower of the
        spiral and the baselines, which has only its stall timer."""
        return WaypointFollower.nominal(self.config, self.path.waypoints, self.path.blocked,
                                        self.planner, start=self.start_index, recovery=recovery)

    def adaptive_sweep(self, rule: AdaptiveConfig | None = None) -> AdaptiveSweep:
        """The adaptive sweep (:mod:`aoass_env.planning.adaptive`) of this episode's spiral, on
        the episode's coverage map, with the recovering follower."""
        return AdaptiveSweep(self.follower(recovery=True), self.coverage_map, self.planner,
                             self.config, rule if rule is not None else AdaptiveConfig(),
                             time_limit=self.step_limit() * self.config.dt,
                             density=self.map.density)

    def step_limit(self) -> int:
        """Control periods a method may take: ``time_limit_factor`` times the path's nominal
        duration (detours at density 0.5-0.6 take up to about 3-4 times as long), rounded up
        once as the env's limit is (:func:`episode_step_limit`)."""
        return episode_step_limit(
            self.config, self.path.nominal_time(self.config.anchor_nominal_speed), "the path")

    def run(self, max_steps: int | None = None, controller: Controller | None = None
            ) -> BeaconLog:
        """Drive ``controller`` (default: the nominal follower of the path) until it is done
        (or ``max_steps``, default ``time_limit_factor`` times the path's nominal duration, as
        the environment's limit); return the
        finished beacon log."""
        follower = controller if controller is not None else self.follower()
        limit = max_steps if max_steps is not None else self.step_limit()
        for _ in range(limit):
            speed, heading = follower.command(self.world.position, self.world.heading,
                                              self.config.dt)
            if follower.done:
                break
            self.step(speed, heading)
        return self.finish()

    @property
    def collisions(self) -> int:
        """Anchor contacts with static obstacles, walls and moving obstacles."""
        return self.world.contacts

    def finish(self) -> BeaconLog:
        """The episode's beacon log with final energies, contacts and node links."""
        return self.recorder.finish(node_energy=self.network.node_energy,
                                    anchor_energy=self.network.anchor_energy,
                                    collisions=self.collisions,
                                    node_links=self.radio.node_links())


def episode_summary(sim: Simulator, complete: bool) -> dict[str, Any]:
    """The metrics of a finished episode, with one set of keys (``episodes.csv``'s columns;
    AOASS-v0's ``info["episode_metrics"]`` adds its own): coverage (Eq. 18), beacons, path
    length and its ideal (m), travel time and its ideal (s), eta_traj (Eq. 19), anchor contacts
    (all, static obstacles and walls, moving obstacles), E_total (J), E_norm (Eq. 16,
    J/beacon), EER (Eq. 17, beacons/J), and ``path_complete``: whether the method ended the
    sweep itself (1) or the step limit did (0)."""
    net, world, path = sim.network, sim.world, sim.path
    ideal_time = path.nominal_time(sim.config.anchor_nominal_speed)
    return {"coverage": net.coverage_ratio, "beacons": net.beacons_sent,
            "path_length": net.distance_travelled, "ideal_length": path.length,
            "travel_time": world.time, "ideal_time": ideal_time,
            "eta_traj": trajectory_efficiency(path.length, net.distance_travelled,
                                              ideal_time, world.time),
            "collisions": sim.collisions,
            "collisions_static": world.static_contacts + world.wall_contacts,
            "collisions_moving": world.moving_contacts,
            "energy_total": net.energy_total,
            "e_norm": energy_per_beacon(net.energy_total, net.beacons_sent),
            "eer": energy_efficiency_ratio(net.energy_total, net.beacons_sent),
            "path_complete": int(complete)}
