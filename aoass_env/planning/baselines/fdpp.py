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
  (0..1) and a step as a fraction of R. Each heading's reach is the longest of R, R/2, R/4 whose
  end is free (obstacles dilated by the anchor radius plus the detour margin, field shrunk by
  the edge margin) and reached straight or by a ``sim.planner`` detour of at most
  ``DETOUR_FACTOR`` x the step; a heading with none is dropped. Ranking: fewest earlier stops
  within R/2 of the step's end first (without it the anchor shuttles along one line, whose
  collinear beacons localize nobody -- our addition), then desirability, then the smallest turn.
* Exploration [I]: when no unlocalized node answers (or no heading is free, or the last move
  went nowhere), the anchor goes to the nearest open cell of its own trajectory memory
  (:class:`CellMemory`, cells of side R at first; distance = route length). A cell is done
  once the anchor has been in it or it was a goal; cells inside obstacles or unreachable are
  done. When all are done the cells are halved (marked from the trajectory so far) down to R/4.
* End: when the travelled distance reaches the budget (default the AOASS square spiral's length
  of the same config, ``sim.spiral.length``; detours count) or, with nobody answering, every
  reachable cell of the finest size has been visited. Every route is cut to the budget left.

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
from aoass_env.planning.baselines.common import point_follower
from aoass_env.planning.detour import DetourPlanner
from aoass_env.planning.follower import WaypointFollower
from aoass_env.planning.path import WaypointPath
from aoass_env.planning.square_spiral import episode_spiral
from aoass_env.planning.sweep import PlannedMethod, SweepState
from aoass_env.safety.fuzzy import FuzzyController, FuzzyVariable
from aoass_env.validators import positive

#: Candidate headings (rad): six, 60 deg apart.
HEADINGS = np.deg2rad(np.arange(0.0, 360.0, 60.0))
#: Side of the first (coarsest) exploration cells as a fraction of R [I].
CELL_FRACTION = 1.0
#: Exploration cells are halved, once all are done, down to this fraction of R [I].
MIN_CELL_FRACTION = 0.25
#: A fuzzy step may detour around obstacles up to this factor times its straight length [I].
DETOUR_FACTOR = 2.0


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
    r = positive("radio_range", radio_range, "m")
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


def path_length(path: np.ndarray) -> float:
    """Length (m) of the polyline ``path`` (K, 2) (m)."""
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())


def truncate(path: np.ndarray, length: float) -> np.ndarray:
    """The first ``length`` (m) of the polyline ``path`` (K, 2) (m); all of it when shorter."""
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    if length >= cum[-1]:
        return path
    i = int(np.searchsorted(cum, length, side="right"))        # cum[i-1] <= length < cum[i]
    t = (length - cum[i - 1]) / seg[i - 1]
    return np.vstack([path[:i], path[i - 1] + t * (path[i] - path[i - 1])])


def route(planner: DetourPlanner, obstacle_map: ObstacleMap, start: np.ndarray, end: np.ndarray,
          margin: float, max_length: float = math.inf) -> np.ndarray | None:
    """Collision-free polyline (K, 2) (m) from ``start`` to ``end`` (m): straight when clear,
    else the planner's detour. None when ``end`` lies outside the field shrunk by ``margin`` (m)
    or in the planner's dilated obstacles, cannot be reached, or the route is longer than
    ``max_length`` (m)."""
    start, end = np.asarray(start, dtype=np.float64), np.asarray(end, dtype=np.float64)
    if not (obstacle_map.bounds_contain(end, margin)[0] and planner.visible(end, end)):
        return None
    if planner.visible(start, end):
        return np.vstack([start, end])
    path = planner.path(start, end)
    return None if path is None or path_length(path) > max_length else path


def free_reach(planner: DetourPlanner, obstacle_map: ObstacleMap, position: np.ndarray,
               radio_range: float, margin: float) -> np.ndarray:
    """(6,) the longest of R, R/2, R/4 (m) whose step end along each heading from ``position``
    (m) is free, inside the field shrunk by ``margin`` (m) and reached by a :func:`route` of at
    most :data:`DETOUR_FACTOR` times the step; 0 where none is."""
    p = np.asarray(position, dtype=np.float64)
    unit = np.stack([np.cos(HEADINGS), np.sin(HEADINGS)], axis=1)
    reach = np.zeros(len(HEADINGS))
    for k in range(len(HEADINGS)):
        for length in (radio_range, radio_range / 2, radio_range / 4):
            if route(planner, obstacle_map, p, p + length * unit[k], margin,
                     DETOUR_FACTOR * length) is not None:
                reach[k] = length
                break
    return reach


class CellMemory:
    """The anchor's memory of where it has been (its own trajectory), on square cells.

    The field is cut into cells of side ``side`` (m). A cell is done once the anchor's centre
    has been in it or it was an exploration goal. Each cell's goal is the free point of the
    planner's grid (at least the planner's radius plus one grid step from obstacles, inside the
    field shrunk by ``margin`` (m)) nearest the cell's centre; cells without one (inside
    obstacles) are done from the start.
    """

    def __init__(self, planner: DetourPlanner, obstacle_map: ObstacleMap, side: float,
                 margin: float) -> None:
        self.side = positive("cell_side", side, "m")
        self.shape = (math.ceil(obstacle_map.width / self.side),
                      math.ceil(obstacle_map.height / self.side))
        free = planner.centres[planner.free.ravel()]
        free = free[obstacle_map.bounds_contain(free, margin) & ~obstacle_map.inside_obstacle(
            free, dilation=planner.radius + planner.res)]        # the grid's clearance is coarse
        cell = self.index(free)
        centres = (np.stack(np.unravel_index(cell, self.shape), axis=1) + 0.5) * self.side
        order = np.lexsort((np.linalg.norm(free - centres, axis=1), cell))
        _, first = np.unique(cell[order], return_index=True)
        nearest = order[first]
        self.goals = np.full((self.shape[0] * self.shape[1], 2), np.nan)
        self.goals[cell[nearest]] = free[nearest]
        self.done = np.isnan(self.goals[:, 0])

    def index(self, points: np.ndarray) -> np.ndarray:
        """Flat cell index of each of ``points`` (M, 2) (m), (M,)."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        ij = np.floor(pts / self.side).astype(int)
        ij = np.clip(ij, 0, np.array(self.shape) - 1)
        return np.ravel_multi_index((ij[:, 0], ij[:, 1]), self.shape)

    def visit(self, points: np.ndarray) -> None:
        """Mark the cells holding ``points`` (M, 2) or (2,) (m) done."""
        self.done[self.index(points)] = True

    def nearest(self, planner: DetourPlanner, obstacle_map: ObstacleMap, position: np.ndarray,
                margin: float) -> np.ndarray | None:
        """:func:`route` (K, 2) (m) from ``position`` to the open cell whose goal is nearest by
        route length, that cell then marked done; cells whose goal cannot be reached are marked
        done. None when every cell is done. The straight distance bounds the route length from
        below, so the search stops at the first goal straight-farther than the best route."""
        p = np.asarray(position, dtype=np.float64)
        cells = np.flatnonzero(~self.done)
        straight = np.linalg.norm(self.goals[cells] - p, axis=1)
        best: tuple[float, int, np.ndarray] | None = None
        for i in np.argsort(straight, kind="stable"):
            if best is not None and straight[i] >= best[0]:
                break
            path = route(planner, obstacle_map, p, self.goals[cells[i]], margin)
            if path is None:
                self.done[cells[i]] = True
            elif best is None or path_length(path) < best[0]:
                best = (path_length(path), int(cells[i]), path)
        if best is None:
            return None
        self.done[best[1]] = True
        return best[2]


class FDPPController:
    """Online FDPP driver (module docstring).

    Args:
        sim: the episode (radio, network and map are read at every stop).
        budget: travel budget (m); default the square spiral's length ``sim.spiral.length``.
        cell_side: side of the first exploration cells (m); default :data:`CELL_FRACTION` x R.
        min_cell_side: the cells are halved while at least this side (m); default
            :data:`MIN_CELL_FRACTION` x R.

    Attributes:
        stops: the stop positions (m), in order.
        cells: the exploration memory.
        explored: stops at which the anchor explored (no fuzzy move).
    """

    def __init__(self, sim: SweepState, budget: float | None = None,
                 cell_side: float | None = None, min_cell_side: float | None = None) -> None:
        c = sim.config
        self.sim = sim
        self.budget = positive("budget", sim.spiral.length if budget is None else budget, "m")
        side = positive("cell_side", CELL_FRACTION * c.radio_range
                        if cell_side is None else cell_side, "m")
        self.min_cell_side = positive(
            "min_cell_side", MIN_CELL_FRACTION * c.radio_range
            if min_cell_side is None else min_cell_side, "m", high=side)
        self.cells = CellMemory(sim.planner, sim.map, side, c.edge_margin)
        self.flc = fdpp_rules()
        self.stops: list[np.ndarray] = []
        self.explored = 0
        self._follower: WaypointFollower | None = None
        self._done = False

    @property
    def done(self) -> bool:
        """True once the budget is spent or the tour has ended."""
        return self._done or self.sim.network.distance_travelled >= self.budget

    def command(self, position: np.ndarray, heading: float, dt: float) -> tuple[float, float]:
        """(speed [m/s], heading [rad]) for the next ``dt`` seconds."""
        position = np.asarray(position, dtype=np.float64)
        while not self.done:
            self.cells.visit(position)
            if self._follower is not None and not self._follower.done:
                speed, bearing = self._follower.command(position, heading, dt)
                if not self._follower.done:
                    return speed, bearing
            self._done = not self._stop(position, heading)
        return 0.0, 0.0

    def _fuzzy_move(self, position: np.ndarray, heading: float, unlocalized: np.ndarray
                    ) -> np.ndarray | None:
        """Route (K, 2) (m) of the fuzzy step, or None when no heading has a free step."""
        sim, c = self.sim, self.sim.config
        reach = free_reach(sim.planner, sim.map, position, c.radio_range, c.edge_margin)
        choice = choose_heading(position, heading, sim.nodes[unlocalized], reach,
                                c.radio_range, self.flc, np.array(self.stops))
        if choice is None:
            return None
        k, step = choice
        unit = np.array([math.cos(HEADINGS[k]), math.sin(HEADINGS[k])])
        for length in (step, reach[k]):         # the fuzzy step, else the checked free reach
            path = route(sim.planner, sim.map, position, position + length * unit,
                         c.edge_margin, DETOUR_FACTOR * length)
            if path is not None:
                return path
        return None

    def _explore(self, position: np.ndarray) -> np.ndarray | None:
        """Route (K, 2) (m) to the nearest open cell, halving the cells (marked from the
        trajectory so far) while all are done; None when the finest cells are all done."""
        sim, c = self.sim, self.sim.config
        while (path := self.cells.nearest(sim.planner, sim.map, position, c.edge_margin)) is None:
            if self.cells.side / 2 < self.min_cell_side:
                return None
            self.cells = CellMemory(sim.planner, sim.map, self.cells.side / 2, c.edge_margin)
            self.cells.visit(sim.recorder.path_points)
        return path

    def _stop(self, position: np.ndarray, heading: float) -> bool:
        """Decide the next segment at a stop; False when the tour ends."""
        sim, c = self.sim, self.sim.config
        moved = not self.stops or np.hypot(*(position - self.stops[-1])) > c.anchor_radius
        self.stops.append(position.copy())
        remaining = self.budget - sim.network.distance_travelled
        if remaining <= c.beacon_interval:               # budget as good as spent
            return False
        heard = sim.radio.receivers(position)
        unlocalized = heard[~sim.network.covered[heard]]
        path = self._fuzzy_move(position, heading, unlocalized) \
            if len(unlocalized) and moved else None
        if path is None:
            self.explored += 1
            path = self._explore(position)
            if path is None:                             # every reachable cell visited
                return False
        self._follower = point_follower(c, truncate(path, remaining), sim.planner)
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
