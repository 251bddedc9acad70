"""FDPP (reconstructed): online, range-free path planning by a Mamdani fuzzy rule base.

Alomari, Phillips, Aslam & Comeau, "Dynamic Fuzzy-Logic Based Path Planning for
Mobility-Assisted Localization in WSNs", Sensors 17(8):1904, 2017. The anchor builds its path
online in straight segments under a maximum travel distance; a fuzzy decision over information
from nearby unlocalized nodes picks each next move. No code was published; the rule base below
is ours (docs/baselines.md):

* Stops: the anchor stops at the end of every segment (a step of about R).
* Answers: at a stop, the unlocalized neighbours answer the broadcast. The controller reads
  them from the simulator: ``sim.radio.receivers(position)`` (in range and line of sight) that
  are not ``sim.network.covered`` -- the nodes that would answer in the protocol. No node
  position is used beyond what an answering node could report (its bearing and distance
  class, here taken exactly).
* Decision: six headings 60 deg apart (0, 60, ..., 300 deg); each unlocalized neighbour falls in
  the sector of the nearest heading. Per heading the fuzzy inputs are the sector's share of the
  answering nodes (0..1) and their mean distance / R (0..1); the outputs are a desirability
  (0..1) and a step as a fraction of R. Each heading's step is cut to the longest of R, R/2,
  R/4 that stays clear of the obstacles dilated by the anchor radius plus the detour margin and
  inside the field shrunk by the edge margin; a heading with none is dropped (obstacle
  extension); when all are dropped, R/4 hops to free ends are reached by detours.
  Ranking: fewest earlier stops within R/2 of the step's end first (without it
  the anchor shuttles along one line, whose collinear beacons localize nobody -- our
  addition), then desirability, then the smallest turn, so with nobody answering the anchor
  keeps going straight where it can.
* End: when the travelled distance reaches the budget (the AOASS square spiral's length of the
  same config, ``sim.spiral.length``) or no unlocalized node has answered for ``patience``
  consecutive stops, or no heading is free.

The fuzzy engine is :class:`aoass_env.safety.fuzzy.FuzzyController` with its two input roles
(``distance``, ``heading``) and two output roles (``turn``, ``speed``) re-labelled: distance ->
mean distance / R, heading -> share of nodes (in [0, 1], so the heading wrap leaves it
unchanged), turn -> step fraction, speed -> desirability.
"""

from __future__ import annotations

import math

import numpy as np

from aoass_env.config import AOASSConfig
from aoass_env.maps import ObstacleMap
from aoass_env.planning.baselines.common import check_positive, point_follower
from aoass_env.planning.detour import DetourPlanner
from aoass_env.planning.follower import WaypointFollower
from aoass_env.planning.path import PlannedMethod, WaypointPath
from aoass_env.safety.fuzzy import FuzzyController, FuzzyVariable
from aoass_env.simulator import Simulator, episode_spiral

#: Candidate headings (rad): six, 60 deg apart.
HEADINGS = np.deg2rad(np.arange(0.0, 360.0, 60.0))
#: Stops in a row without an unlocalized neighbour after which the anchor ends its tour.
DEFAULT_PATIENCE = 8


def fdpp_rules() -> FuzzyController:
    """The rule base: (mean distance / R, share of nodes) -> (step / R, desirability).

    More unlocalized nodes in a sector make it more desirable; at equal share, farther nodes
    are preferred (near ones keep hearing the next beacons anyway) and get a full step, near
    ones a shorter step so the anchor stops among them.
    """
    distance = FuzzyVariable("mean distance / R", (0.0, 1.0, 101), {
        "near": (0.0, 0.0, 0.3, 0.6),
        "far": (0.3, 0.7, 1.0, 1.0),
    })
    share = FuzzyVariable("share of nodes", (0.0, 1.0, 101), {
        "none": (0.0, 0.0, 0.1),
        "few": (0.0, 0.2, 0.45),
        "many": (0.25, 0.6, 1.0, 1.0),
    })
    step = FuzzyVariable("step / R", (-1.1, 1.1, 221), {
        "short": (0.4, 0.6, 0.8),
        "full": (0.8, 1.0, 1.1),
    })
    desirability = FuzzyVariable("desirability", (-0.1, 1.1, 241), {
        "low": (-0.1, 0.0, 0.3),
        "medium": (0.2, 0.5, 0.8),
        "high": (0.7, 1.0, 1.1),
    })
    rules = {
        ("near", "none"): ("full", "low"),
        ("far", "none"): ("full", "low"),
        ("near", "few"): ("short", "medium"),
        ("far", "few"): ("full", "medium"),
        ("near", "many"): ("short", "high"),
        ("far", "many"): ("full", "high"),
    }
    return FuzzyController(distance=distance, heading=share, turn=step, speed=desirability,
                           rules=rules)


def sector_inputs(position: np.ndarray, nodes: np.ndarray, radio_range: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Fuzzy inputs per candidate heading from the unlocalized neighbours ``nodes`` (K, 2) (m)
    heard at ``position`` (2,) (m): (mean distance / R, share of the K nodes), each (6,).
    A sector without nodes has mean distance 0 and share 0."""
    r = check_positive("radio_range", radio_range)
    share, mean = np.zeros(len(HEADINGS)), np.zeros(len(HEADINGS))
    d = np.asarray(nodes, dtype=np.float64).reshape(-1, 2) - np.asarray(position)
    if len(d) == 0:
        return mean, share
    bearing = np.arctan2(d[:, 1], d[:, 0])
    sector = np.round(np.mod(bearing, 2 * math.pi) / (math.pi / 3)).astype(int) % len(HEADINGS)
    counts = np.bincount(sector, minlength=len(HEADINGS))
    sums = np.bincount(sector, weights=np.hypot(d[:, 0], d[:, 1]), minlength=len(HEADINGS))
    share = counts / len(d)
    mean = np.clip(np.divide(sums, np.maximum(counts, 1)) / r, 0.0, 1.0)
    return mean, share


def choose_heading(position: np.ndarray, heading: float, nodes: np.ndarray, reach: np.ndarray,
                   radio_range: float, flc: FuzzyController,
                   visited: np.ndarray | None = None) -> tuple[int, float] | None:
    """Index into :data:`HEADINGS` and step (m) of the next segment, or None when every
    heading's free ``reach`` (6,) (m) is 0. The step is the fuzzy step, at most the reach.

    Ranking: fewest ``visited`` stops (S, 2) (m) within R/2 of the end of the heading's step
    first (no back-and-forth on one line), then higher desirability, then the smaller turn
    from the current ``heading`` (rad).
    """
    reach = np.asarray(reach, dtype=np.float64)
    if not np.any(reach > 0):
        return None
    mean, share = sector_inputs(position, nodes, radio_range)
    step, desirability = flc(mean, share)
    step = np.minimum(np.asarray(step) * radio_range, reach)
    turn = np.abs(np.angle(np.exp(1j * (HEADINGS - heading))))
    revisit = np.zeros(len(HEADINGS), dtype=np.int64)
    if visited is not None and len(visited):
        ends = np.asarray(position) + step[:, None] * np.stack([np.cos(HEADINGS),
                                                                np.sin(HEADINGS)], axis=1)
        gap = np.linalg.norm(ends[:, None] - np.asarray(visited)[None], axis=2)
        revisit = (gap < radio_range / 2).sum(axis=1)
    order = np.lexsort((turn, -np.round(desirability, 9), revisit))
    best = int(next(i for i in order if reach[i] > 0))
    return best, float(step[best])


def free_reach(planner: DetourPlanner, obstacle_map: ObstacleMap, position: np.ndarray,
               radio_range: float, margin: float) -> np.ndarray:
    """(6,) the longest of R, R/2, R/4 (m) that a straight step along each heading can go from
    ``position`` (m) clear of the planner's dilated obstacles and inside the field shrunk by
    ``margin`` (m); 0 where none can. When no heading has a straight step, R/4 wherever the
    step's end is free (the follower then detours to it)."""
    p = np.asarray(position, dtype=np.float64)
    unit = np.stack([np.cos(HEADINGS), np.sin(HEADINGS)], axis=1)
    reach = np.zeros(len(HEADINGS))
    for length in (radio_range / 4, radio_range / 2, radio_range):
        ends = p + length * unit
        ok = obstacle_map.bounds_contain(ends, margin) & np.array(
            [planner.visible(p, e) for e in ends])
        reach[ok] = length
    if not reach.any():     # hemmed in (e.g. a stop by an obstacle): short hops to free ends
        ends = p + radio_range / 4 * unit
        ok = obstacle_map.bounds_contain(ends, margin) & np.array(
            [planner.visible(e, e) for e in ends])
        reach[ok] = radio_range / 4
    return reach


class FDPPController:
    """Online FDPP driver (module docstring).

    Args:
        sim: the episode (radio, network and map are read at every stop).
        patience: stops in a row without an answering unlocalized node before the tour ends.
        budget: travel budget (m); default the square spiral's length ``sim.spiral.length``.

    Attributes:
        stops: the stop positions (m), in order.
    """

    def __init__(self, sim: Simulator, patience: int = DEFAULT_PATIENCE,
                 budget: float | None = None) -> None:
        if isinstance(patience, bool) or not isinstance(patience, int) or patience < 1:
            raise ValueError(f"patience={patience!r} must be an integer >= 1")
        self.sim = sim
        self.patience = patience
        self.budget = check_positive("budget", sim.spiral.length if budget is None else budget)
        self.flc = fdpp_rules()
        self.stops: list[np.ndarray] = []
        self._silent = 0
        self._follower: WaypointFollower | None = None
        self._done = False

    @property
    def done(self) -> bool:
        """True once the budget is spent or the tour has ended."""
        return self._done or self.sim.network.distance_travelled >= self.budget

    def command(self, position: np.ndarray, heading: float, dt: float) -> tuple[float, float]:
        """(speed [m/s], heading [rad]) for the next ``dt`` seconds."""
        while not self.done:
            if self._follower is not None and not self._follower.done:
                speed, bearing = self._follower.command(position, heading, dt)
                if not self._follower.done:
                    return speed, bearing
            self._done = not self._stop(np.asarray(position, dtype=np.float64), heading)
        return 0.0, 0.0

    def _stop(self, position: np.ndarray, heading: float) -> bool:
        """Decide the next segment at a stop; False when the tour ends."""
        sim, c = self.sim, self.sim.config
        self.stops.append(position.copy())
        heard = sim.radio.receivers(position)
        unlocalized = heard[~sim.network.covered[heard]]
        self._silent = 0 if len(unlocalized) else self._silent + 1
        if self._silent >= self.patience:
            return False
        reach = free_reach(sim.planner, sim.map, position, c.radio_range, c.edge_margin)
        choice = choose_heading(position, heading, sim.nodes[unlocalized], reach,
                                c.radio_range, self.flc, np.array(self.stops))
        if choice is None:
            return False
        k, step = choice
        step = min(step, self.budget - sim.network.distance_travelled)
        if step <= c.beacon_interval:                  # budget as good as spent
            return False
        target = position + step * np.array([math.cos(HEADINGS[k]), math.sin(HEADINGS[k])])
        self._follower = point_follower(c, np.vstack([position, target]), sim.planner)
        return True


def plan(obstacle_map: ObstacleMap, config: AOASSConfig) -> WaypointPath:
    """The AOASS square spiral of the same config. FDPP never follows it: it fixes the start
    (the spiral's first free waypoint) and the travel budget (its length), and the
    simulator's step limit scales with it."""
    spiral = episode_spiral(config, obstacle_map)
    return WaypointPath(spiral.waypoints, spiral.arc_length, spiral.blocked)


FDPP = PlannedMethod(
    name="fdpp",
    label="FDPP (reconstructed)",
    source=("A. Alomari, W. Phillips, N. Aslam, F. Comeau, \"Dynamic Fuzzy-Logic Based Path "
            "Planning for Mobility-Assisted Localization in Wireless Sensor Networks\", "
            "Sensors 17(8):1904, 2017, doi 10.3390/s17081904"),
    plan=plan,
    controller=FDPPController,
    reconstructed=True,
)
