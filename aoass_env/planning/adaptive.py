"""The adaptive sweep: a square spiral that skips what the anchor's coverage map already covers,
then densifies where coverage is still missing (Section 3.3: "the anchor can easily skip or
locally reconfigure sub-segments of the spiral").

:class:`AdaptiveSweep` drives the nominal follower (:class:`~aoass_env.planning.follower.
WaypointFollower`, with its detours and its recovery from traps) and reads the anchor's own
:class:`~aoass_env.planning.coverage.CoverageMap`:

1. **Skip.** The *need* of a spiral waypoint is the mean coverage deficit of the free cells within
   ``skip_radius`` of it that it sees (line of sight, within the cells' guaranteed range).
   Every control period, while the follower's target has need <= ``skip_need``, the target is
   passed over: stretches and whole legs that earlier passes covered are not driven again.
   A target the anchor cannot reach straight is passed over when its need is at most
   ``detour_need``, and also when the detour is longer than the straight way by more than
   ``detour_excess`` metres: the spiral's later passes often cover what lies behind the
   obstacle; such a waypoint stays *open*. By default none of this happens (``skip_need`` and
   ``detour_need`` -0.25, below any need, ``detour_excess`` 1e4 m): the pruned plan has
   already left out what the rest covers, and passing its far waypoints over broke its order
   (docs/adaptive.md). The agent's knobs at +1 raise the two needs to 0 (skip what is covered).
   On a dense map (obstacle density above ``dense_above``, 0.45) the ``dense_`` thresholds
   stand in for the three (0, 0 and 20 m: the online skips on), where they shortened the sweep.
   A plan's localizing points (:attr:`~aoass_env.planning.pruning.PrunedPlan.localizing`: those
   its class limit needs) are never passed over as covered unless ``skip_localizing``: the
   coverage map judges Eq. 18 alone, not which beacons a cell hears.
   **Side of a detour.** When the sweep does detour to a target, it can weigh the planner's
   shortest way against the shortest way round the other side of the obstacle (a keep-out
   fence on the perpendicular through the first way's widest point, out to the field's
   border): it takes the other side when the coverage deficit of the free cells within
   ``skip_radius`` of that way, summed, exceeds the shortest way's by more than ``side_rate``
   per extra metre (Section 3.2's "detour direction"), heading first for that way's widest
   point. Off by default (``side_rate`` = ``SIDE_OFF``): on training maps it cost more path
   for no reliable coverage gain (docs/planning.md).
0. **Plan.** Before it moves (``prune``, ``reorder``), the sweep prunes Eq. 5's spiral on the
   static map (:mod:`aoass_env.planning.pruning`): it leaves out the free waypoints whose
   surroundings the rest of the spiral's beacons cover, reorders the kept ones where that is
   shorter, and its follower walks the plan. With ``sites`` it walks instead a tour through
   beacon sites chosen by set cover of the cells the whole spiral would cover (each heard by
   ``site_need`` sites), repaired where its beacons leave such cells uncovered, then pruned
   the same way. Without a plan, ``wide_passes`` lays wider passes
   than Eq. 5's (:func:`sweep_config`: the ring count rounded down instead of up, 2 rings
   instead of 3 on the default 100 m field) and leaves the gaps to the densify phase.

2. **Densify.** When the spiral is done, the sweep revisits the open waypoints whose need is
   still above ``densify_need``: each run starts at the open waypoint the anchor reaches by the
   shortest way and follows the spiral while its waypoints stay open (the skip rule still
   passing over those the run's own beacons have covered). When no open waypoint is left, it
   heads for the free cells the map lacks (deficit above ``cell_need``; with a plan, only the
   cells the whole spiral would cover), the cheapest first. **Sites** (``cell_sites``, off):
   for a cell that heard two beacons or more, the sweep heads not for its centre, whose
   straight approach lays beacons on the line the cell already heard, but for the cheapest
   point of a 1 m lattice from which one more beacon completes the cell's Eq. 18 spread (with
   a beacon interval to spare), in its guaranteed range and sight; a cell gets two tries, then
   is given up. Without a site the sweep heads for the centre until the cell is covered,
   reached within two cells, or given up.
3. **End.** The sweep ends when the map's covered share of the free field reaches
   ``end_coverage``, or when no open waypoint needs a visit. Visiting every spiral waypoint is
   no longer the only ending.

Three knobs in [-1, 1] (:class:`SweepKnobs`, the adaptive action's last three entries) move the
rule: ``skip`` raises ``skip_need`` by ``knob_step`` x skip (skip more); ``detour`` raises
``detour_need`` the same way and divides ``detour_excess`` by 2^detour (detour less);
``densify`` raises ``densify_need`` (densify less). A knob's shift grows linearly to its full
size at ±``knob_full`` (0.9) and stays there, so that a tanh actor reaches every setting without
sitting exactly on its bound. The zero knobs are the hand-written rule
(evaluate.py's ``aoass-rule`` method). Chosen on training maps (docs/planning.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar, NamedTuple

import numpy as np

from aoass_env.config import AOASSConfig, ConfigError
from aoass_env.network import Network
from aoass_env.planning.coverage import CoverageMap
from aoass_env.planning.detour import DetourPlanner
from aoass_env.planning.follower import Skip, WaypointFollower
from aoass_env.planning.pruning import PrunedPlan, plan_sites, prune_spiral
from aoass_env.planning.square_spiral import config_spacing
from aoass_env.radio import Radio
from aoass_env.validators import ValidatedConfig, param

__all__ = ["AdaptiveConfig", "AdaptiveSweep", "SweepKnobs", "check_rule", "coverable", "site_radio",
           "sweep_config"]

#: Open waypoints (nearest first) whose way the planner measures to choose the next densify run.
DENSIFY_CANDIDATES = 5
#: A cell to densify counts as visited within this many cell sides of its centre.
CELL_CAPTURE_CELLS = 2.0
#: Seconds a cell to densify gets beyond twice its travel time at the nominal speed along the
#: planner's way, weighted by its clearance cost (and the follower's allowance for a detour),
#: before it is given up.
CELL_STALL_TIME = 5.0
#: Cells within this distance (m) of a cell the sweep gave up on the way to are given up too.
GIVE_UP_RADIUS = 10.0
#: Radius (m) and spacing of the keep-outs that fence off the shortest way's side of an
#: obstacle, from its widest point out to the field's border.
SIDE_KEEPOUT = 4.0
#: ``side_rate`` at which a detour always takes the shortest way (the default: on training
#: maps, weighing the other side cost 1-11 % more path for no reliable coverage gain).
SIDE_OFF = 1000.0
#: Spacing (m) of the points along a way whose surroundings count toward its coverage deficit.
SIDE_SAMPLE = 4.0
#: Spacing (m) of the lattice of points a lacking cell's beacon may be sent from (the planner's
#: free cells of the main region, thinned to about this).
SITE_SPACING = 1.0
#: With ``cell_sites``, the times a lacking cell is headed for before it is given up.
CELL_TRIES = 2


@dataclass(frozen=True)
class AdaptiveConfig(ValidatedConfig):
    """The adaptive sweep's rule (module docstring; docs/planning.md)."""

    KEYWORD: ClassVar[str] = "adaptive keyword"

    prune: bool = param(True, "before it moves, leave out the spiral's free waypoints whose "
                        "surroundings the rest of the spiral covers on the static map "
                        "(aoass_env.planning.pruning)", kind="bool")
    prune_beacons: float = param(6.0, "the pruned plan keeps a cell the full spiral covers "
                                 "with at least this many beacons at this many", low=3.0,
                                 high=1000.0)
    prune_spread: float = param(2.0, "... and their spread at least this many times Eq. 18's "
                                "collinearity_tol", low=1.0, high=100.0)
    prune_error: float = param(2.0, "... and, above 0, a cell's class error (the distance "
                               "from its centre to the mean of the cells hearing the same "
                               "planned beacons, pruning.class_error) at most the larger of "
                               "this and the full spiral's; with sites, the tour's wider "
                               "classes are split by inserted sites first (0: not checked; "
                               "chosen on training maps, docs/adaptive.md)", unit="m",
                               low=0.0, high=1000.0)
    sites: bool = param(True, "with prune, walk a tour through beacon sites chosen by set "
                        "cover of the cells the whole spiral would cover, repaired and pruned, "
                        "instead of the spiral's own waypoints pruned (pruning.plan_sites; "
                        "chosen on training maps, docs/adaptive.md)", kind="bool")
    site_need: int = param(4, "... the set cover's sites each such cell hears (Eq. 18 needs "
                           "three beacons)", low=1, high=20, kind="int")
    reorder: bool = param(True, "with prune, also reorder the kept waypoints (2-opt on the "
                          "planner's ways, every reference cell still covered)", kind="bool")
    wide_passes: bool = param(False, "lay the spiral's passes with the ring count of Eq. 5's "
                              "spacing rounded down, not up (spiral_spacing left unset): wider "
                              "passes, the gaps left to the densify phase", kind="bool")
    skip_radius: float = param(8.0, "a spiral waypoint's surroundings: the free cells within "
                               "this distance that a beacon sent there reaches (in sight, and "
                               "no farther than the cells' guaranteed range r_cell); at least "
                               "half a cell's diagonal, coverage_cell / sqrt 2", unit="m",
                               low=0.0, high=1000.0, low_open=True)
    skip_need: float = param(-0.25, "a target whose surroundings' mean coverage deficit (in "
                             "[0, 1]) is at most this is passed over (below 0: never, unless "
                             "the agent's knob raises it; the pruned plan has already left out "
                             "what the rest covers, docs/adaptive.md; the rule without a plan "
                             "used 0)", low=-1.0, high=1.0)
    skip_localizing: bool = param(False, "the online skips may pass over a plan point that "
                                  "the plan's class limit needs (PrunedPlan.localizing: "
                                  "its surroundings may be covered while the cells around "
                                  "still share one class); off: such points are visited, "
                                  "so the skip does not undo the plan's class split "
                                  "(docs/adaptive.md)", kind="bool")
    detour_need: float = param(-0.25, "the same for a target the anchor cannot reach straight "
                               "(it would detour round an obstacle; the rule without a plan used "
                               "0)", low=-1.0, high=1.0)
    detour_excess: float = param(1e4, "a target whose detour is longer than the straight way "
                                 "by more than this is passed over whatever its need (the "
                                 "spiral's later passes and the densify phase cover what it "
                                 "leaves; 1e4: never, the plan's order stands; the rule without "
                                 "a plan used 20)", unit="m", low=0.0, high=1e4)
    dense_above: float = param(0.45, "on a map whose obstacle density (the static map's "
                               "obstacle area / field area) is above this, the three dense_ "
                               "thresholds below stand in for skip_need, detour_need and "
                               "detour_excess (1: never; chosen on training and fresh maps, "
                               "docs/adaptive.md)", low=0.0, high=1.0)
    dense_skip_need: float = param(0.0, "skip_need on a dense map", low=-1.0, high=1.0)
    dense_detour_need: float = param(0.0, "detour_need on a dense map", low=-1.0, high=1.0)
    dense_detour_excess: float = param(20.0, "detour_excess on a dense map", unit="m",
                                       low=0.0, high=1e4)
    densify_need: float = param(0.0, "after the spiral, uncovered cells with a deficit above "
                                "this are visited, nearest first", low=-1.0, high=1.0)
    cell_need: float = param(0.0, "then, free cells with a deficit above this (0: every cell "
                             "not covered; 0.5: heard at most one beacon) are visited, the "
                             "cheapest first (with prune, only the cells the whole spiral "
                             "would cover)", low=-1.0, high=1.0)
    beyond_below: float = param(0.92, "with prune, on a map where the whole spiral would "
                                "cover less than this share of the free cells (a dense map), "
                                "the cells phase also visits the others (beyond_need); 0: never "
                                "(0.92 separates densities 0.4 and 0.5 on the fitting split; "
                                "chosen with the site tour, docs/adaptive.md)", low=0.0,
                                high=1.0)
    beyond_need: float = param(0.5, "... those of them with a deficit above this (0.5: heard at "
                               "most one beacon)", low=-1.0, high=1.0)
    beyond_time: float = param(0.8, "... until this share of the episode's time limit has "
                               "passed", low=0.0, high=1.0)
    cell_sites: bool = param(False, "in the cells phase, head for the cheapest point from "
                             "which one beacon completes the cell's Eq. 18 spread (in its "
                             "guaranteed range and sight), not for the cell's centre, whose "
                             "straight approach lays collinear beacons; a cell gets CELL_TRIES "
                             "tries (off: more of the cells phase's targets get covered, but on "
                             "validation and fresh maps the sweep's coverage and path were "
                             "level, docs/adaptive.md)", kind="bool")
    cell_hop: float = param(1e4, "a lacking cell is headed for only when the planner's way "
                            "to it costs at most this (the cells phase ends when none is that "
                            "near)", unit="m", low=0.0, high=1e4, low_open=True)
    end_coverage: float = param(0.995, "the sweep ends when the coverage map's covered share "
                                "of the free field reaches this", low=0.0, high=1.0,
                                low_open=True)
    side_rate: float = param(SIDE_OFF, "a detour goes round the other side of the obstacle when "
                             "the summed coverage deficit along that way exceeds the shortest "
                             "way's by more than this per extra metre (SIDE_OFF = 1000: "
                             "always the shortest way, the other side is not weighed)",
                             unit="1/m", low=0.0, high=1000.0)
    knob_step: float = param(0.25, "threshold shift of a knob at full reach (knob_full)",
                             low=0.0, high=1.0)
    knob_full: float = param(0.9, "a knob at or beyond +-this shifts the thresholds fully, "
                             "linearly from 0 (1: only at +-1, where a tanh actor arrives only "
                             "in the limit, and the corners' effects, e.g. skip_need reaching 0, "
                             "lie on the bound; docs/adaptive.md)", low=0.0, high=1.0,
                             low_open=True)
    beacon_interval: float | None = param(None, "distance the adaptive anchor travels between "
                                          "beacons, in the plan and in the sweep (None: the "
                                          "environment's beacon_interval); the spiral's "
                                          "waypoints keep the environment's spacing", unit="m",
                                          low=0.0, high=100.0, low_open=True, optional=True)


def sweep_config(config: AOASSConfig, rule: AdaptiveConfig, side: float) -> AOASSConfig:
    """``config`` for the adaptive sweep on a ``side`` (m) square field: with
    ``rule.wide_passes`` and no ``spiral_spacing`` of its own, the wide passes'
    (:func:`~aoass_env.planning.square_spiral.default_spacing` with ``wide``); with
    ``rule.beacon_interval``, that interval between beacons, the spiral's waypoints still
    ``config.path_step`` apart. A ``rule.skip_radius`` below half a cell's diagonal is a
    :class:`~aoass_env.config.ConfigError` (:func:`check_rule`)."""
    check_rule(config, rule)
    if rule.beacon_interval is not None and rule.beacon_interval != config.beacon_interval:
        config = config.replace(beacon_interval=rule.beacon_interval,
                                waypoint_step=config.path_step)
    if not rule.wide_passes or config.spiral_spacing is not None:
        return config
    return config.replace(spiral_spacing=config_spacing(config, side, side, wide=True))


def check_rule(config: AOASSConfig, rule: AdaptiveConfig) -> None:
    """:class:`~aoass_env.config.ConfigError` unless ``rule`` fits ``config``'s coverage
    map: a ``skip_radius`` shorter than half a cell's diagonal (coverage_cell / sqrt 2) can
    hold no cell centre around a waypoint, whose need would read 0 (nothing to cover) and pass
    it over as covered, unheard."""
    least = config.coverage_cell / math.sqrt(2.0)
    if rule.skip_radius < least:
        raise ConfigError(f"adaptive skip_radius={rule.skip_radius:g} m must be at least half "
                          f"a coverage cell's diagonal, coverage_cell / sqrt 2 = {least:.3g} m "
                          f"(coverage_cell={config.coverage_cell:g} m): a waypoint's "
                          f"surroundings would hold no cell")


class OnlineThresholds(NamedTuple):
    """The thresholds of the online skips in force on a map (:class:`AdaptiveConfig`)."""

    skip_need: float
    detour_need: float
    detour_excess: float


class SweepKnobs(NamedTuple):
    """The agent's knobs on the rule, each in [-1, 1] (0: the rule as configured)."""

    skip: float = 0.0
    detour: float = 0.0
    densify: float = 0.0


@dataclass
class AdaptiveSweep:
    """The adaptive sweep (module docstring): a :class:`~aoass_env.planning.sweep.Controller`.

    Args:
        follower: the spiral's nominal follower (with recovery); the sweep passes its targets
            over.
        coverage: the episode's coverage map (the simulator updates it with every beacon).
        planner: the detour planner of the episode's map.
        config: the episode's configuration (the densify followers are built from it).
        rule: the rule's thresholds.
        time_limit: the episode's time limit (s), for ``beyond_time``.
        density: the static map's obstacle density (obstacle area / field area), for
            ``dense_above``.

    Attributes:
        knobs: the knobs in force (the environment sets them from the action).
        passed: spiral waypoints passed over (index, time, "covered", "covered, detour" or
            "long detour").
        revisits: the densify runs: (first spiral index, time) of each.
        sides: detours taken round the other side of an obstacle: (spiral index or -1, time).
        plan: with the rule's ``prune``, the pruned spiral; the follower then walks its
            waypoints (``plan.order``), and every index above is one of them.
    """

    follower: WaypointFollower
    coverage: CoverageMap
    planner: DetourPlanner
    config: AOASSConfig
    rule: AdaptiveConfig = field(default_factory=AdaptiveConfig)
    time_limit: float = math.inf
    density: float = 0.0
    knobs: SweepKnobs = field(default_factory=SweepKnobs)
    passed: list[Skip] = field(default_factory=list)
    revisits: list[tuple[int, float]] = field(default_factory=list)
    sides: list[tuple[int, float]] = field(default_factory=list)
    plan: PrunedPlan | None = None
    _clock: float = 0.0
    _via: WaypointFollower | None = None
    _near: dict[int, np.ndarray] = field(default_factory=dict)
    # need() per waypoint, with the coverage map's beacon count it was computed at
    _needs: dict[int, tuple[int, float]] = field(default_factory=dict)
    _runner: WaypointFollower | None = None
    _open: np.ndarray | None = None
    _cell: int = -1
    _site: np.ndarray | None = None
    _tries: int = 0
    _judged: int = -1
    _localizing: np.ndarray | None = None
    _dropped: np.ndarray | None = None
    _recoveries: int = 0      # back-outs of the runs and ways retired so far
    _retired: WaypointFollower | None = None   # the last run counted in _recoveries
    _done: bool = False

    def __post_init__(self) -> None:
        check_rule(self.config, self.rule)
        if sweep_config(self.config, self.rule, self.config.field_size) != self.config:
            # the rule's beacon interval and wide passes live in the simulator's config: a
            # sweep on any other config ignored them, silently
            raise ConfigError(
                f"the adaptive rule's beacon_interval={self.rule.beacon_interval} / wide_passes="
                f"{self.rule.wide_passes} are not in the simulator's config; build the "
                f"Simulator with sweep_config(config, rule, field side) (AOASS-v0 does)")
        if self.rule.prune:
            self.plan = self._prune()
            if not self.rule.skip_localizing:
                self._localizing = self.plan.localizing
        self._runner = self.follower
        self._open = np.zeros(len(self.follower.waypoints), dtype=bool)
        self._dropped = np.zeros(self.coverage.n_cells, dtype=bool)

    def _prune(self) -> PrunedPlan:
        """Prune the spiral ahead (:mod:`aoass_env.planning.pruning`); the sweep's follower then
        walks the plan's waypoints in the plan's order (its indices are the plan's)."""
        follower, cov, config, rule = self.follower, self.coverage, self.config, self.rule
        # everything else the plan depends on (the raster's settings are the coverage map's)
        key = ("plan", follower.waypoints.tobytes(), follower.blocked.tobytes(), follower.index,
               self.planner.radius, self.planner.res, config.beacon_interval,
               config.collinearity_tol, rule.prune_beacons, rule.prune_spread, rule.reorder,
               rule.prune_error, rule.sites, rule.site_need if rule.sites else None)
        margin = (rule.prune_beacons, rule.prune_spread)
        if rule.sites:
            plan = cov.derived(key, lambda: plan_sites(
                follower.waypoints, follower.blocked, follower.index, self.planner, cov.radio,
                cov.n_cells, config.beacon_interval, config.collinearity_tol, margin,
                need=rule.site_need, reorder=rule.reorder, error_limit=rule.prune_error or None))
        else:
            plan = cov.derived(key, lambda: prune_spiral(
                follower.waypoints, follower.blocked, follower.index, self.planner, cov.radio,
                cov.n_cells, config.beacon_interval, config.collinearity_tol, margin,
                rule.reorder, error_limit=rule.prune_error or None))
        self.follower = WaypointFollower.nominal(config, plan.points[plan.order],
                                                 planner=self.planner, recovery=True)
        self.follower.stall_travel = True          # the kept waypoints can lie far apart
        return plan

    # --- the Controller protocol --------------------------------------------------------------
    @property
    def done(self) -> bool:
        """True once the map says the field is covered or nothing is left to densify."""
        return self._done

    @property
    def cell(self) -> int:
        """The coverage map's cell the cells phase heads for (-1: none)."""
        return self._cell

    @property
    def densifying(self) -> bool:
        """Whether the spiral is done and the sweep revisits what it passed over."""
        return self._runner is not self.follower

    @property
    def index(self) -> int:
        """The spiral waypoint the sweep heads for (len(waypoints) when done or heading for a
        cell)."""
        if self._done or self._cell >= 0:
            return len(self.follower.waypoints)
        return self._runner.index

    @property
    def skipped(self) -> list[Skip]:
        """Waypoints given up as unreachable by the spiral's follower (not the ones passed over
        by choice: :attr:`passed`)."""
        return self.follower.skipped

    @property
    def recoveries(self) -> int:
        """Back-outs of the spiral's follower, of the densify runs and of the ways round the
        other side."""
        extra = (self._runner.recoveries
                 if self.densifying and self._runner is not self._retired else 0)
        via = self._via.recoveries if self._via is not None else 0
        return self.follower.recoveries + self._recoveries + extra + via

    def progress(self) -> float:
        """Fraction of spiral waypoints reached, skipped or passed over, in [0, 1]."""
        return self.follower.progress()

    @property
    def target(self) -> np.ndarray | None:
        """The point the sweep is heading for (a spiral waypoint, a cell, or the widest point
        of a way round the other side), None when done."""
        if self._done:
            return None
        return self._via.target if self._via is not None else self._runner.target

    def command(self, position: np.ndarray, heading: float, dt: float) -> tuple[float, float]:
        """(speed [m/s], heading [rad]) for the next control period (module docstring)."""
        self._clock += dt
        while not self._done:
            if self.coverage.ratio >= self.rule.end_coverage:
                self._done = True
                break
            cell_done = self._cell >= 0 and self._cell_done(position)
            if self._via is not None:
                if not (self._via.done or cell_done):
                    return self._via.command(position, heading, dt)
                self._recoveries += self._via.recoveries
                self._via = None
            runner = self._runner
            if not runner.done and not cell_done:
                if self._cell < 0:
                    self._pass_covered(position, runner)
                if not runner.done:
                    return runner.command(position, heading, dt)
            self._next_run(position)
        return 0.0, 0.0

    # --- skip ------------------------------------------------------------------------------
    def _reach(self, knob: float) -> float:
        """A knob's share of its full shift, in [-1, 1] (full at ``knob_full`` and beyond)."""
        return min(1.0, max(-1.0, float(knob) / self.rule.knob_full))

    def _threshold(self, base: float, knob: float) -> float:
        return base + self.rule.knob_step * self._reach(knob)

    def need(self, index: int) -> float:
        """Mean coverage deficit of the free cells within ``skip_radius`` of spiral waypoint
        ``index`` that a beacon sent there reaches (in sight, within the cells' guaranteed
        range: :meth:`~aoass_env.planning.coverage.CoverageMap.visible_near`; 0 when there is
        none, all obstacle around it)."""
        beacons = self.coverage.beacons      # the deficits change only with a beacon
        known = self._needs.get(index)
        if known is not None and known[0] == beacons:
            return known[1]
        cells = self._near.get(index)
        if cells is None:
            cells = self.coverage.visible_near(self.follower.waypoints[index],
                                               self.rule.skip_radius)
            self._near[index] = cells
        need = float(self.coverage.deficit_at(cells).mean()) if len(cells) else 0.0
        self._needs[index] = (beacons, need)
        return need

    def online_thresholds(self) -> OnlineThresholds:
        """The rule's skip_need, detour_need and detour_excess (m) on this map: the ``dense_``
        ones when the map's obstacle density is above ``dense_above``."""
        rule = self.rule
        if self.density > rule.dense_above:
            return OnlineThresholds(rule.dense_skip_need, rule.dense_detour_need,
                                    rule.dense_detour_excess)
        return OnlineThresholds(rule.skip_need, rule.detour_need, rule.detour_excess)

    def _pass_covered(self, position: np.ndarray, runner: WaypointFollower) -> None:
        """Pass over the runner's targets the rule says to skip; on the spiral, those with
        coverage still missing stay open for the densify runs. Whether to detour to a target is
        judged once, when it becomes the target (a planner search); its coverage every
        period."""
        base = self.online_thresholds()
        skip_need = self._threshold(base.skip_need, self.knobs.skip)
        detour_need = self._threshold(base.detour_need, self.knobs.detour)
        max_excess = base.detour_excess * 2.0 ** -self._reach(self.knobs.detour)
        on_spiral = runner is self.follower
        while not runner.done:
            need = self.need(runner.index)
            kept = self._localizing is not None and self._localizing[runner.index]
            if need <= skip_need and not kept:
                reason = "covered"
            elif runner.index == self._judged or self.planner.visible(position, runner.target):
                self._judged = runner.index
                return
            elif need <= detour_need and not kept:
                reason = "covered, detour"
            else:
                way = self.planner.path(position, runner.target)
                if on_spiral and _excess(way, position, runner.target) > max_excess:
                    reason = "long detour"
                    self._open[runner.index] = True
                else:
                    self._judged = runner.index
                    if way is not None:
                        self._choose_side(position, runner.target, way, runner.index)
                    return
            self.passed.append(Skip(runner.index, self._clock, reason))
            runner.pass_target()

    def _detour_excess(self, position: np.ndarray, target: np.ndarray) -> float:
        """How much longer (m) the planner's way to ``target`` is than the straight line (inf
        when there is none)."""
        return _excess(self.planner.path(position, target), position, target)

    # --- side of a detour ------------------------------------------------------------------
    def _choose_side(self, position: np.ndarray, target: np.ndarray, way: np.ndarray,
                     index: int) -> None:
        """Weigh the shortest ``way`` to ``target`` against the way round the other side
        (module docstring); when that wins, head first for its widest point."""
        if len(way) < 3 or self.rule.side_rate >= SIDE_OFF:
            return
        apex = way[_widest(way, position, target)]
        other = self.planner.path(position, target, self._fence(apex, position, target),
                                  SIDE_KEEPOUT)
        if other is None or len(other) < 3:
            return
        wide = _widest(other, position, target)
        if _side(other[wide], position, target) * _side(apex, position, target) >= 0:
            return                                   # no way round the other side
        extra = _length(other) - _length(way)
        if self._way_deficit(other) - self._way_deficit(way) > self.rule.side_rate * extra:
            self.sides.append((index, self._clock))
            self._via = WaypointFollower.nominal(self.config, other[wide][None, :],
                                                 planner=self.planner, recovery=True)

    def _fence(self, apex: np.ndarray, start: np.ndarray, goal: np.ndarray) -> np.ndarray:
        """Keep-out points every :data:`SIDE_KEEPOUT` metres on the perpendicular through
        ``apex`` to the line start -> goal, from that line out past ``apex`` to the field's
        border: the way round that side is shut."""
        d = goal - start
        normal = np.array([-d[1], d[0]]) / max(float(np.hypot(*d)), 1e-12)
        foot = apex - _side(apex, start, goal) * normal
        if _side(apex, start, goal) < 0:
            normal = -normal
        width, height = self.coverage.shape[0] * self.coverage.cell, \
            self.coverage.shape[1] * self.coverage.cell
        points = foot + np.arange(0.0, math.hypot(width, height), SIDE_KEEPOUT)[:, None] * normal
        inside = ((points[:, 0] >= 0) & (points[:, 0] <= width)
                  & (points[:, 1] >= 0) & (points[:, 1] <= height))
        return points[inside]

    def _way_deficit(self, way: np.ndarray) -> float:
        """Summed coverage deficit of the free cells within ``skip_radius`` of points every
        :data:`SIDE_SAMPLE` metres along ``way`` that they see."""
        cells = [self.coverage.visible_near(p, self.rule.skip_radius)
                 for p in _samples(way, SIDE_SAMPLE)]
        seen = np.unique(np.concatenate(cells)) if cells else np.zeros(0, dtype=np.int64)
        return float(self.coverage.deficit_at(seen).sum())

    # --- densify ---------------------------------------------------------------------------
    def _next_run(self, position: np.ndarray) -> None:
        """Start the next densify run: from the open waypoint (passed over for a long detour,
        coverage still missing) the anchor reaches by the shortest way, along the spiral while
        the waypoints stay open; done when none is left."""
        if self.densifying and self._runner is not self._retired:
            # counted once: the run stays the runner when no other follows it
            self._recoveries += self._runner.recoveries
            self._retired = self._runner
        self._judged = -1
        if self._cell >= 0:
            cell, self._cell, self._site = self._cell, -1, None
            if (self.rule.cell_sites and not self.coverage.covered[cell]
                    and self._tries < CELL_TRIES and self._head_for(position, cell)):
                return            # again, from a site that the beacons laid since call for
            # what beacons around here can give that cell, they have given
            capture = CELL_CAPTURE_CELLS * self.coverage.cell
            self._dropped[cell] = True
            self._dropped[self.coverage.near(position, capture)] = True
            centre = self.coverage.centres[cell]
            if (not self.coverage.covered[cell]
                    and math.hypot(*(centre - position)) > capture):
                # given up on the way: the cells around it need the same way
                self._dropped[self.coverage.near(centre, GIVE_UP_RADIUS)] = True
        threshold = self._threshold(self.rule.densify_need, self.knobs.densify)
        todo = np.flatnonzero(self._open)
        for i in todo:
            if self.need(i) <= threshold:
                self._open[i] = False
        todo = np.flatnonzero(self._open)
        if not len(todo):
            self._next_cell(position, self._threshold(self.rule.cell_need, self.knobs.densify))
            return
        wps = self.follower.waypoints
        d = wps[todo] - position
        nearest = todo[np.argsort(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])[:DENSIFY_CANDIDATES]]
        start = self._start(position)
        lengths = [self._way_length(start, wps[i]) for i in nearest]
        first = int(nearest[int(np.argmin(lengths))])
        if not np.isfinite(min(lengths)):
            self._open[nearest] = False          # out of reach: nothing to do there
            return
        last = first
        while last + 1 < len(wps) and (self._open[last + 1] or self.follower.blocked[last + 1]):
            last += 1
        run = np.zeros(len(wps), dtype=bool)
        run[first:last + 1] = self._open[first:last + 1]
        self._open[run] = False
        self.revisits.append((first, self._clock))
        self._runner = WaypointFollower.nominal(self.config, wps, ~run, self.planner,
                                                start=first, recovery=True)
        self._via = self._way_to(position, wps[first])

    def _start(self, position: np.ndarray) -> np.ndarray:
        """Where the planner's ways from ``position`` start: ``position``, or where the anchor
        rejoins the field's main region when the planner sees it shut in a pocket."""
        if self.planner.can_start(position, 0.0):
            return position
        return self.planner.main_point(position)

    def _way_to(self, position: np.ndarray, target: np.ndarray) -> WaypointFollower | None:
        """A runner along the inner points of the planner's way to ``target`` (None when the way
        is straight or there is none): sent to a far target alone, the follower cuts corners
        where it sees the target, and at densities 0.5-0.6 ran into the same trap for target
        after target."""
        start = self._start(position)
        if start is not position:
            # the planner sees the anchor shut in a pocket (its dilated obstacles close a gap
            # the anchor came through): straight back to the field's main region first
            return WaypointFollower.nominal(self.config, start[None], recovery=True)
        way = self.planner.path(position, target)
        if way is None or len(way) < 3:
            return None
        return WaypointFollower.nominal(self.config, way[1:-1], planner=self.planner,
                                        recovery=True)

    def _next_cell(self, position: np.ndarray, threshold: float) -> None:
        """Head for the free cell the map still lacks (deficit above ``threshold``, not given
        up) that the planner's way reaches at the least cost; cells it cannot reach are given
        up; done when none is left."""
        cov = self.coverage
        lacking = ~self._dropped & (cov.deficit > max(threshold, 0.0))
        if self.plan is not None:      # the cells the whole spiral would cover, and on a
            lacking &= self.plan.reference     # dense map the others that heard little
            if (self.plan.reference.mean() < self.rule.beyond_below
                    and self._clock < self.rule.beyond_time * self.time_limit):
                beyond = self._threshold(self.rule.beyond_need, self.knobs.densify)
                lacking |= ~self._dropped & ~self.plan.reference & (cov.deficit
                                                                    > max(beyond, 0.0))
        todo = np.flatnonzero(lacking)
        if not len(todo):
            self._done = True
            return
        cost = self.planner.costs(self._start(position), cov.centres[todo])
        self._dropped[todo[~np.isfinite(cost)]] = True      # out of the anchor's reach
        if not np.isfinite(cost).any() or cost.min() > self.rule.cell_hop:
            self._done = True
            return
        near = int(np.argmin(cost))
        self._tries = 0
        self._head_for(position, int(todo[near]), float(cost[near]))

    def _head_for(self, position: np.ndarray, cell: int, cost: float | None = None) -> bool:
        """Head for lacking cell ``cell``: for its beacon site (``cell_sites``, :meth:`_site_of`),
        else for its centre, whose planner's way costs ``cost`` (m); False, heading nowhere,
        when a cell tried before has no site."""
        site = self._site_of(position, cell) if self.rule.cell_sites else None
        if site is None and (self._tries > 0 or cost is None):
            return False
        goal, cost = (self.coverage.centres[cell], cost) if site is None else site
        self._tries += 1
        self._cell, self._site = cell, None if site is None else goal
        # a goal beside an obstacle may be out of the anchor's reach: little time past the
        # travel
        travel = 2.0 * cost / self.config.anchor_nominal_speed
        self._runner = WaypointFollower.nominal(self.config, goal[None, :], planner=self.planner,
                                                recovery=True, stall_time=CELL_STALL_TIME + travel)
        self._via = self._way_to(position, goal)
        self.revisits.append((-1, self._clock))
        return True

    def _site_of(self, position: np.ndarray, cell: int) -> tuple[np.ndarray, float] | None:
        """(point, cost of the planner's way there (m)): the cheapest lattice point
        (:data:`SITE_SPACING`) from which one more beacon completes ``cell``'s Eq. 18 test (its
        third or later, spread at least ``collinearity_tol`` + ``beacon_interval``, since the
        beacon falls up to an interval short of the site), within the cell's guaranteed range
        and in sight, and farther than an interval from the anchor; None when no reachable
        point does (the cell heard fewer than two beacons, or the ones it heard leave no such
        point)."""
        cov = self.coverage
        if cov.heard[cell] < 2:
            return None
        sites = site_radio(self.planner, cov)
        points = sites.nodes[sites.receivers(cov.centres[cell])]
        # the last beacon before the site falls up to one beacon interval short of it, and a
        # site nearer than that to the anchor may get no beacon of its own
        interval = self.config.beacon_interval
        d = points - position
        points = points[(cov.residual_after(cell, points) >= self.config.collinearity_tol
                         + interval) & (d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] > interval ** 2)]
        if not len(points):
            return None
        cost = self.planner.costs(self._start(position), points)
        best = int(np.argmin(cost))
        return (points[best], float(cost[best])) if np.isfinite(cost[best]) else None

    def _cell_done(self, position: np.ndarray) -> bool:
        """Whether the cell the sweep heads for is covered; heading for its centre, also
        whether that is reached: beacons within a few cells of it cover it as well as standing
        on it (a site's runner ends when it reaches the site)."""
        if self.coverage.covered[self._cell]:
            return True
        centre = self.coverage.centres[self._cell]
        return self._site is None and math.hypot(
            *(centre - position)) <= CELL_CAPTURE_CELLS * self.coverage.cell

    def _way_length(self, position: np.ndarray, target: np.ndarray) -> float:
        """Length (m) of the planner's way to ``target`` (inf when there is none)."""
        if self.planner.visible(position, target):
            return float(np.hypot(*(target - position)))
        return float(np.hypot(*(target - position))) + self._detour_excess(position, target)


def site_radio(planner: DetourPlanner, coverage: CoverageMap) -> Radio:
    """The lattice of points a beacon may be sent from (the planner's free cells of its main
    region, thinned to :data:`SITE_SPACING`) as the nodes of a radio with the cells' guaranteed
    range and line of sight: its receivers of a cell's virtual node are the points from which
    a beacon reaches the cell (range and sight are symmetric). Built once per map
    (:meth:`CoverageMap.derived`)."""
    radio = coverage.radio
    step = max(1, round(SITE_SPACING / planner.res))
    return coverage.derived(("sites", planner.radius, planner.res), lambda: Radio(
        planner.main_cells(step), radio.obstacle_map, coverage.reach,
        line_of_sight=radio.line_of_sight))


def coverable(planner: DetourPlanner, coverage: CoverageMap, config: AOASSConfig) -> np.ndarray:
    """(C,) bool: the free cells that beacons sent from every point of :func:`site_radio`'s
    lattice (everywhere the anchor can reach) would cover by Eq. 18 (the cells' own
    :class:`~aoass_env.network.Network` test, ``config.collinearity_tol``). More beacons never
    narrow a cell's spread, so a cell that all of them leave uncovered no sweep covers (up to the
    lattice's spacing). Built once per map."""
    def build() -> np.ndarray:
        network = Network(max(coverage.n_cells, 1), config)
        for point in site_radio(planner, coverage).nodes:
            network.record_beacon(point, coverage.radio.receivers(point))
        able = network.covered[:coverage.n_cells].copy()
        able.flags.writeable = False
        return able
    return coverage.derived(("coverable", planner.radius, planner.res,
                             config.collinearity_tol), build)


def _length(way: np.ndarray) -> float:
    """Length (m) of the polyline ``way`` (K, 2)."""
    return float(np.linalg.norm(np.diff(way, axis=0), axis=1).sum())


def _excess(way: np.ndarray | None, start: np.ndarray, goal: np.ndarray) -> float:
    """How much longer (m) ``way`` is than the straight line (inf for no way)."""
    if way is None:
        return math.inf
    return _length(way) - float(np.hypot(*(goal - start)))


def _side(point: np.ndarray, start: np.ndarray, goal: np.ndarray) -> float:
    """Signed distance (m) of ``point`` from the line start -> goal, positive on its left."""
    d = goal - start
    norm = float(np.hypot(*d))
    if norm == 0.0:
        return 0.0
    return float(d[0] * (point[1] - start[1]) - d[1] * (point[0] - start[0])) / norm


def _widest(way: np.ndarray, start: np.ndarray, goal: np.ndarray) -> int:
    """Index of the inner vertex of ``way`` farthest from the line start -> goal."""
    return 1 + int(np.argmax([abs(_side(p, start, goal)) for p in way[1:-1]]))


def _samples(way: np.ndarray, spacing: float) -> np.ndarray:
    """Points every ``spacing`` metres along ``way`` (K, 2), its ends included."""
    seg = np.linalg.norm(np.diff(way, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    at = np.append(np.arange(0.0, s[-1], spacing), s[-1])
    return np.column_stack([np.interp(at, s, way[:, 0]), np.interp(at, s, way[:, 1])])
