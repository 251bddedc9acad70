"""The spiral pruned ahead on the static map (aoass_env.planning.pruning)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env.config import AOASSConfig
from aoass_env.env import AOASSEnv
from aoass_env.maps import ObstacleMap, generate_map
from aoass_env.network import Network
from aoass_env.planning import AdaptiveConfig, pruning
from aoass_env.planning.coverage import CoverageMap
from aoass_env.planning.pruning import (
    SNAP,
    _covered,
    beacon_weight,
    class_error,
    plan_sites,
    prune_spiral,
)
from aoass_env.simulator import Simulator

CONFIG = AOASSConfig(field_size=60.0, n_nodes=120, obstacle_density=0.0, n_moving_obstacles=0)
#: two blocks the spiral's passes detour round
BLOCKS = ObstacleMap(60.0, 60.0, [
    np.array([[12.0, 12.0], [24.0, 12.0], [24.0, 22.0], [12.0, 22.0]]),
    np.array([[36.0, 34.0], [47.0, 34.0], [47.0, 48.0], [36.0, 48.0]])])


def _plan(obstacle_map: ObstacleMap, margin=(3, 1.0), **options):
    sim = Simulator(CONFIG, np.random.default_rng(0), obstacle_map=obstacle_map)
    cov = sim.coverage_map
    plan = prune_spiral(sim.path.waypoints, sim.path.blocked, sim.start_index, sim.planner,
                        cov.radio, cov.n_cells, CONFIG.beacon_interval,
                        CONFIG.collinearity_tol, margin, **options)
    return sim, plan


def _planned_beacons(sim: Simulator, stops: np.ndarray, points: np.ndarray | None = None
                     ) -> np.ndarray:
    """The plan's beacons, laid again from scratch: every beacon_interval metres along the
    planner's way between consecutive stops of ``points`` (default the spiral's waypoints;
    from the lower index to the higher, whichever is visited first), snapped to the
    lattice."""
    points = sim.path.waypoints if points is None else points
    out = []
    for a, b in zip(stops[:-1], stops[1:], strict=True):
        way = sim.planner.path(points[min(a, b)], points[max(a, b)])
        along = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(way, axis=0), axis=1))]
        for s in np.arange(CONFIG.beacon_interval, along[-1] + 1e-9, CONFIG.beacon_interval):
            p = np.array([np.interp(s, along, way[:, 0]), np.interp(s, along, way[:, 1])])
            out.append(np.round(p / SNAP) * SNAP)
    return np.array(out)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(0, 60), st.floats(0, 60)), min_size=0, max_size=8))
def test_the_statistics_test_is_the_networks_eq18_test(points):
    """Oracle: Eq. 18 from the summed statistics agrees with the network's incremental test."""
    net = Network(1, CONFIG)
    stats = np.zeros((1, 6))
    for x, y in points:
        net.record_beacon(np.array([x, y]), np.array([0]))
        stats[0] += (1.0, x, y, x * x, x * y, y * y)
    lam = net.line_residual[0] ** 2
    if abs(lam - CONFIG.collinearity_tol ** 2) > 1e-6:    # away from the threshold's rounding
        assert bool(_covered(stats, CONFIG.collinearity_tol)[0]) == bool(net.covered[0])


def test_the_pruned_plan_is_shorter_and_its_beacons_cover_every_reference_cell():
    sim, plan = _plan(BLOCKS)
    free = ~sim.path.blocked & (np.arange(len(sim.path.blocked)) >= sim.start_index)
    assert plan.kept[sim.start_index] and not np.any(plan.kept & ~free)
    assert plan.length < 0.9 * plan.full_length
    assert plan.reference.mean() > 0.95
    # oracle: the coverage map fed the kept plan's beacons one by one, from scratch
    cov = CoverageMap(BLOCKS, CONFIG)
    for p in _planned_beacons(sim, np.flatnonzero(plan.kept)):
        cov.add_beacon(p)
    assert np.all(cov.covered[plan.reference])


def test_reordering_keeps_every_reference_cell_covered_and_shortens_the_plan():
    sim, plan = _plan(BLOCKS, margin=(6, 2.0))
    cov = sim.coverage_map
    again = prune_spiral(sim.path.waypoints, sim.path.blocked, sim.start_index, sim.planner,
                         cov.radio, cov.n_cells, CONFIG.beacon_interval, CONFIG.collinearity_tol,
                         (6, 2.0), reorder=True)
    assert again.length <= plan.length
    assert again.order[0] == sim.start_index
    fresh = CoverageMap(BLOCKS, CONFIG)
    for p in _planned_beacons(sim, again.order):
        fresh.add_beacon(p)
    assert np.all(fresh.covered[again.reference])


@settings(max_examples=60, deadline=None)
@given(st.lists(st.lists(st.tuples(st.integers(-3, 3), st.integers(0, 3)), max_size=5),
                min_size=1, max_size=12),
       st.integers(0, 2**32 - 1))
def test_class_error_groups_the_cells_that_hear_the_same_beacons(heard, seed):
    """Oracle: cells grouped by their heard multisets of beacon keys, means taken directly."""
    centres = np.random.default_rng(seed).uniform(0.0, 50.0, (len(heard), 2))
    signature = np.array([sum(beacon_weight(k) for k in keys) & (2**64 - 1) for keys in heard],
                         dtype=np.uint64)
    groups: dict[tuple, list[int]] = {}
    for i, keys in enumerate(heard):
        groups.setdefault(tuple(sorted(keys)), []).append(i)
    expected = np.empty(len(heard))
    for members in groups.values():
        mean = centres[members].mean(axis=0)
        expected[members] = ((centres[members] - mean) ** 2).sum(axis=1)
    np.testing.assert_allclose(class_error(signature, centres), expected, atol=1e-9)


def _oracle_class_error(sim: Simulator, stops: np.ndarray, points: np.ndarray | None = None
                        ) -> np.ndarray:
    """Every cell's class error under the plan through ``stops`` (of ``points``, default the
    spiral's waypoints), from its beacons laid again and grouped by the cells' heard multisets
    of beacon points."""
    cov = sim.coverage_map
    heard: list[list[tuple[float, float]]] = [[] for _ in range(cov.n_cells)]
    for p in _planned_beacons(sim, stops, points):
        for cell in cov.radio.receivers(p):
            heard[cell].append((p[0], p[1]))
    groups: dict[tuple, list[int]] = {}
    for i, points in enumerate(heard):
        groups.setdefault(tuple(sorted(points)), []).append(i)
    centres, error = cov.radio.nodes, np.empty(cov.n_cells)
    for members in groups.values():
        mean = centres[members].mean(axis=0)
        error[members] = ((centres[members] - mean) ** 2).sum(axis=1)
    return error


def test_an_error_limit_keeps_every_reference_cells_class_error_under_its_cap():
    limit = 1.5
    sim, full = _plan(BLOCKS, margin=(6, 2.0), min_gain=1e9)       # nothing removed
    _, free = _plan(BLOCKS, margin=(6, 2.0))
    _, plan = _plan(BLOCKS, margin=(6, 2.0), error_limit=limit)
    cap = np.maximum(_oracle_class_error(sim, full.order), limit**2)[full.reference]
    assert np.any(_oracle_class_error(sim, free.order)[full.reference] > cap + 1e-9)
    assert np.all(_oracle_class_error(sim, plan.order)[full.reference] <= cap + 1e-9)
    assert free.length < plan.length < 0.95 * full.length


def _oracle_cover(sim: Simulator, stops: np.ndarray, margin: tuple[float, float]
                  ) -> tuple[np.ndarray, np.ndarray]:
    """(Eq. 18 covered, covered with the margin's beacons and spread) of every cell under the
    plan through ``stops``, from its beacons laid again and recorded by a network."""
    cov = sim.coverage_map
    net = Network(cov.n_cells, CONFIG)
    for p in _planned_beacons(sim, stops):
        net.record_beacon(p, cov.radio.receivers(p))
    spread = (margin[1] * CONFIG.collinearity_tol) ** 2 * (1.0 - 1e-9)
    return net.covered.copy(), (net.heard >= margin[0]) & (net.line_residual ** 2 >= spread)


def test_the_localizing_points_are_those_whose_removal_breaks_a_class_cap():
    """Oracle: leaving out a point the plan marks ``localizing`` (its neighbours joined by the
    planner's way) puts a reference cell's class error, from the beacons laid again, above the
    cap the error limit keeps; leaving out an unmarked one either keeps every class under its
    cap or loses a reference cell's cover or margin. The start never is one, and without a
    limit none is."""
    limit, margin = 1.5, (6, 2.0)
    sim, full = _plan(BLOCKS, margin=margin, min_gain=1e9)
    _, plan = _plan(BLOCKS, margin=margin, error_limit=limit)
    _, free = _plan(BLOCKS, margin=margin)
    assert plan.localizing.shape == plan.order.shape and not plan.localizing[0]
    assert plan.localizing.any() and not plan.localizing.all()
    assert not free.localizing.any()
    ref = full.reference
    cap = np.maximum(_oracle_class_error(sim, full.order), limit**2)[ref]
    robust = _oracle_cover(sim, full.order, margin)[1]
    for i in range(1, len(plan.order)):
        without = np.delete(plan.order, i)
        widens = np.any(_oracle_class_error(sim, without)[ref] > cap + 1e-9)
        covered, kept_margin = _oracle_cover(sim, without, margin)
        loses = np.any(ref & ~covered) or np.any(robust & ~kept_margin)
        assert plan.localizing[i] == (widens and not loses), i


def _pruner(points: list[list[float]], order: list[int]):
    from aoass_env.planning.detour import DetourPlanner
    from aoass_env.planning.pruning import _Pruner, _Ways

    field = ObstacleMap(60.0, 60.0, [])
    cov = CoverageMap(field, CONFIG)
    ways = _Ways(np.array(points), DetourPlanner.for_map(field, 1.0), cov.radio, cov.n_cells,
                 CONFIG.beacon_interval)
    return _Pruner(ways, order, CONFIG.collinearity_tol, (3, 1.0))


def test_two_opt_untangles_a_back_and_forth_order():
    pruner = _pruner([[10.0, 30.0], [20.0, 30.0], [30.0, 30.0], [40.0, 30.0]], [0, 2, 1, 3])
    assert pruner.length() == 50.0
    assert pruner.reorder(0.3)
    assert pruner.order() == [0, 1, 2, 3] and pruner.length() == 30.0


def test_two_opt_keeps_a_crossing_that_covers_what_the_square_would_not():
    # a square's corners visited crosswise (0 -> 2 -> 1 -> 3): the straight order is 33 m
    # shorter, but it leaves the undriven side's cells with collinear beacons
    pruner = _pruner([[10.0, 10.0], [50.0, 10.0], [50.0, 50.0], [10.0, 50.0]], [0, 2, 1, 3])
    assert not pruner.reorder(0.3)
    assert pruner.order() == [0, 2, 1, 3]


def test_a_margin_keeps_more_of_the_spiral():
    _, bare = _plan(BLOCKS)
    _, kept = _plan(BLOCKS, margin=(8, 3.0))
    assert bare.length < kept.length <= kept.full_length
    assert np.array_equal(bare.reference, kept.reference)


def test_plans_are_cached_per_map_and_settings():
    sim, _ = _plan(BLOCKS)
    again = Simulator(CONFIG, np.random.default_rng(1), obstacle_map=BLOCKS)
    assert again.coverage_map.radio is sim.coverage_map.radio      # the episodes share it
    made = []

    def make():
        made.append(1)
        return object()

    first = sim.coverage_map.derived(("k", 1), make)
    assert again.coverage_map.derived(("k", 1), make) is first and len(made) == 1
    sim.coverage_map.derived(("k", 2), make)
    assert len(made) == 2
    # another raster of the same map (other cells) keeps its own
    other = CoverageMap(BLOCKS, CONFIG.replace(coverage_cell=2 * CONFIG.coverage_cell))
    other.derived(("k", 1), make)
    assert len(made) == 3


def _planning(density: float) -> tuple[Simulator, tuple]:
    """A simulator on BLOCKS (density 0) or a generated 80 m map, and the planners' arguments
    of its spiral (margin 6 beacons, 2x the spread)."""
    if density == 0.0:
        obstacle_map, config = BLOCKS, CONFIG
    else:
        config = CONFIG.replace(field_size=80.0, obstacle_density=density)
        obstacle_map = generate_map(80.0, density, np.random.default_rng([8801, 3]))
    sim = Simulator(config, np.random.default_rng(0), obstacle_map=obstacle_map)
    cov = sim.coverage_map
    return sim, (sim.path.waypoints, sim.path.blocked, sim.start_index, sim.planner, cov.radio,
                 cov.n_cells, config.beacon_interval, config.collinearity_tol, (6, 2.0))


@pytest.mark.parametrize("density", [0.0, 0.3])
def test_a_site_tour_starts_at_the_spiral_start_and_its_beacons_cover_the_reference(density):
    """Oracle: the site tour's beacons laid again from scratch along the planner's ways cover
    (nearly) every cell the whole spiral covers, with a shorter way than the pruned spiral's."""
    sim, args = _planning(density)
    config, obstacle_map = sim.config, sim.map
    plan = plan_sites(*args)
    spiral = prune_spiral(*args, reorder=True)
    assert np.array_equal(plan.reference, spiral.reference)
    assert plan.order[0] == 0 and np.array_equal(plan.points[0],
                                                 sim.path.waypoints[sim.start_index])
    assert np.array_equal(np.sort(plan.order), np.flatnonzero(plan.kept))
    assert plan.full_length == pytest.approx(spiral.full_length)
    fresh = CoverageMap(obstacle_map, config)
    beacons = _planned_beacons(sim, plan.order, plan.points)
    assert len(beacons) == pytest.approx(plan.length / config.beacon_interval, abs=len(plan.order))
    for p in beacons:
        fresh.add_beacon(p)
    assert fresh.covered[plan.reference].mean() >= 0.98
    assert plan.length < spiral.length


def test_a_site_tour_with_an_error_limit_splits_the_wide_classes():
    """Oracle: with ``error_limit`` the site tour's reference cells lie in narrower classes
    (class errors from the plan's beacons laid again) above the cap the split aims at (the
    larger of the limit squared and the whole spiral's), for a longer tour."""
    limit = 2.0
    sim, args = _planning(0.3)
    bare = plan_sites(*args)
    split = plan_sites(*args, error_limit=limit)
    whole = prune_spiral(*args, min_gain=1e9)          # nothing removed: the whole spiral
    assert np.array_equal(split.reference, bare.reference)
    cap = np.maximum(_oracle_class_error(sim, whole.order), limit**2)[split.reference]

    def excess(plan) -> float:
        error = _oracle_class_error(sim, plan.order, plan.points)[plan.reference]
        return np.maximum(error - cap, 0.0).sum()

    assert excess(split) < 0.8 * excess(bare)
    assert bare.length < split.length < whole.length


def test_an_insertion_adds_its_ways_beacons_and_length():
    """Oracle: after :meth:`_Pruner.insert`, the statistics and length are those of a pruner
    built afresh on the new order, and :meth:`_Pruner.insertion` said how much longer."""
    sim = Simulator(CONFIG, np.random.default_rng(0), obstacle_map=BLOCKS)
    cov = sim.coverage_map
    points = sim.planner.main_cells(8)
    ways = pruning._Ways(points, sim.planner, cov.radio, cov.n_cells, CONFIG.beacon_interval)
    order = [0, 20, 40, 60]
    pruner = pruning._Pruner(ways, order, CONFIG.collinearity_tol, (3, 1.0))
    before = pruner.length()
    target = ~pruner.reference
    for site, after in ((30, 20), (70, 60), (10, 0)):
        tried = pruner.insertion(site, after, target)
        assert tried is not None
        extra, gained = tried
        assert np.all(target[gained]) and not np.any(pruner.reference[gained])
        pruner.insert(site, after)
        assert np.all(pruner.reference[gained])
        assert pruner.length() == pytest.approx(before + extra)
        before = pruner.length()
    assert pruner.order() == [0, 10, 20, 30, 40, 60, 70]
    fresh = pruning._Pruner(ways, pruner.order(), CONFIG.collinearity_tol, (3, 1.0))
    np.testing.assert_allclose(pruner.total, fresh.total, atol=1e-6)
    assert np.array_equal(pruner.reference, fresh.reference)
    assert np.array_equal(pruner.signature, fresh.signature)


def test_a_split_removes_the_class_error_it_says():
    """Oracle: :meth:`_Pruner.excess` now and :meth:`_Pruner.split`'s excess then are the
    cells' class errors above the cap, summed, each from the plan's beacons laid again and
    grouped by heard multisets."""
    sim = Simulator(CONFIG, np.random.default_rng(0), obstacle_map=BLOCKS)
    cov = sim.coverage_map
    points = sim.planner.main_cells(8)
    ways = pruning._Ways(points, sim.planner, cov.radio, cov.n_cells, CONFIG.beacon_interval)
    pruner = pruning._Pruner(ways, [0, 20, 40, 60], CONFIG.collinearity_tol, (3, 1.0))
    cap = np.full(cov.n_cells, 4.0)

    def excess() -> float:
        return np.maximum(_oracle_class_error(sim, pruner.order(), points) - cap, 0.0).sum()

    before = excess()
    assert before > 0.0 and pruner.excess(cap).sum() == pytest.approx(before, abs=1e-6)
    removed = []
    for site, after in ((30, 20), (70, 60), (10, 0)):
        length = pruner.length()
        extra, then = pruner.split(site, after, cap)
        pruner.insert(site, after)
        assert pruner.length() == pytest.approx(length + extra)
        assert excess() == pytest.approx(then, abs=1e-6) == pruner.excess(cap).sum()
        removed.append(before - then)
        before = then
    assert max(removed) > 0.0


@pytest.mark.parametrize("sites", [False, True])
def test_the_sweep_walks_the_plan_without_touching_the_spiral(sites):
    config = CONFIG
    rule = AdaptiveConfig(prune=True, wide_passes=False, sites=sites)
    sim = Simulator(config, np.random.default_rng(0), obstacle_map=BLOCKS)
    spiral_blocked = sim.path.blocked.copy()
    sweep = sim.adaptive_sweep(rule)
    again = Simulator(config, np.random.default_rng(1), obstacle_map=BLOCKS)
    assert again.adaptive_sweep(rule).plan is sweep.plan
    assert sim.adaptive_sweep(dataclasses.replace(rule, sites=not sites)).plan is not sweep.plan
    assert np.array_equal(sim.path.blocked, spiral_blocked)
    assert np.array_equal(sweep.follower.waypoints, sweep.plan.points[sweep.plan.order])
    if not sites:
        assert np.array_equal(sweep.plan.points, sim.path.waypoints)
    assert sweep.follower.stall_travel and not sweep.follower.blocked.any()
    assert np.array_equal(np.sort(sweep.plan.order), np.flatnonzero(sweep.plan.kept))
    sim.run(controller=sweep)
    assert sweep.done
    spiral = Simulator(config, np.random.default_rng(0), obstacle_map=BLOCKS)
    spiral.run(controller=spiral.follower(recovery=True))
    assert sim.network.distance_travelled < 0.9 * spiral.network.distance_travelled
    assert sim.network.coverage_ratio >= spiral.network.coverage_ratio


def test_the_observed_waypoints_are_the_ones_the_pruned_sweep_heads_for():
    env = AOASSEnv(field_size=60.0, n_nodes=120, obstacle_density=0.0, n_moving_obstacles=0,
                   action_type="adaptive", adaptive=AdaptiveConfig(prune=True, wide_passes=False))
    obs, _ = env.reset(seed=0, options={"map": BLOCKS})
    sweep = env._follower
    k = env.config.obs_waypoints
    ahead = sweep.follower.waypoints[sweep.index:]
    upcoming = ahead[np.minimum(np.arange(k), len(ahead) - 1)]
    scale = k * env.config.path_step
    expected = np.clip((upcoming - env.sim.world.position) / scale, -1.0, 1.0)
    assert np.allclose(obs[env.obs_layout["waypoints"]], expected.ravel(), atol=1e-6)
    free = env.sim.spiral.waypoints[~env.sim.spiral.blocked]
    spiral = np.clip((free[:k] - env.sim.world.position) / scale, -1.0, 1.0)
    assert not np.allclose(spiral.ravel(), expected.ravel())   # the spiral's next ones differ


@pytest.mark.parametrize(("below", "late", "beyond"), [(0.0, False, False), (1.0, False, True),
                                                      (1.0, True, False)])
def test_only_on_a_dense_map_the_cells_phase_goes_beyond_the_reference(below, late, beyond):
    """The cells the whole spiral would not cover are visited only when the reference is a
    smaller share of the free cells than beyond_below (a dense map), and only until
    beyond_time of the episode's time limit."""
    sim = Simulator(CONFIG, np.random.default_rng(0), obstacle_map=BLOCKS)
    sweep = sim.adaptive_sweep(AdaptiveConfig(beyond_below=below))
    assert sweep.time_limit == sim.step_limit() * CONFIG.dt
    if late:
        sweep._clock = 0.81 * sweep.time_limit
    # a reference without the east half of the field, as on a dense map
    east = sim.coverage_map.centres[:, 0] > 30.0
    sweep.plan = dataclasses.replace(sweep.plan, reference=sweep.plan.reference & ~east)
    sweep._dropped[sweep.plan.reference] = True       # every reference cell done with
    sweep._next_cell(sim.world.position, 0.0)
    if not beyond:
        assert sweep.done and sweep._cell < 0
    else:
        assert not sweep.done and not sweep.plan.reference[sweep._cell]


class _OneByOne(pruning._Ways):
    """The ways before the batched measure (the oracle): every beacon's receivers asked of the
    radio alone and its statistics added to the cells one beacon after the other."""

    def receivers(self, point: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.uint64]:
        key = (round(point[0] / SNAP), round(point[1] / SNAP))
        snapped = np.array(key, dtype=np.float64) * SNAP
        if key not in self._heard:
            self._heard[key] = (self.radio.receivers(snapped), np.uint64(beacon_weight(key)))
        cells, weight = self._heard[key]
        return cells, snapped, weight

    def _measure(self, way: np.ndarray) -> pruning._Way:
        steps = np.linalg.norm(np.diff(way, axis=0), axis=1)
        along = np.r_[0.0, np.cumsum(steps)]
        length = float(along[-1])
        marks = np.arange(self.interval, length + 1e-9, self.interval)
        stats = np.zeros((self.n_cells, 6))
        signature = np.zeros(self.n_cells, dtype=np.uint64)
        for s in marks:
            cells, (x, y), weight = self.receivers(np.array([np.interp(s, along, way[:, 0]),
                                                             np.interp(s, along, way[:, 1])]))
            stats[cells] += (1.0, x, y, x * x, x * y, y * y)
            signature[cells] += weight
        touched = np.flatnonzero(stats[:, 0])
        return pruning._Way(length, touched, stats[touched], signature[touched])


@pytest.mark.parametrize("density", [0.2, 0.5])
def test_batched_ways_and_plans_are_those_of_measuring_beacon_by_beacon(density, monkeypatch):
    """The batched measure (one line-of-sight call per way's new lattice points, statistics
    summed by ``np.bincount``) gives every way's statistics and signatures bit for bit, and so
    the same plan, as adding the beacons one by one."""
    config = AOASSConfig(field_size=60.0, n_nodes=50, n_moving_obstacles=0)
    obstacle_map = generate_map(60.0, density, np.random.default_rng([7, round(100 * density)]))
    sim = Simulator(config, np.random.default_rng(0), obstacle_map=obstacle_map)
    cov, wps = sim.coverage_map, sim.path.waypoints
    args = (wps, sim.planner, cov.radio, cov.n_cells, config.beacon_interval)
    new, old = pruning._Ways(*args), _OneByOne(*args)
    rng = np.random.default_rng(1)
    pairs = [(i, i + 1) for i in range(len(wps) - 1)] + [
        tuple(rng.choice(len(wps), 2, replace=False)) for _ in range(20)]
    for a, b in pairs:
        got, want = new.get(a, b), old.get(a, b)
        assert (got is None) == (want is None)
        if got is not None:
            assert got.length == want.length
            for field in ("cells", "stats", "signature"):
                g, w = getattr(got, field), getattr(want, field)
                assert g.dtype == w.dtype
                np.testing.assert_array_equal(g, w)
    assert new._heard.keys() == old._heard.keys()
    plan = prune_spiral(wps, sim.path.blocked, sim.start_index, sim.planner, cov.radio,
                        cov.n_cells, config.beacon_interval, config.collinearity_tol, (6, 2.0),
                        error_limit=1.5)
    monkeypatch.setattr(pruning, "_Ways", _OneByOne)
    oracle = prune_spiral(wps, sim.path.blocked, sim.start_index, sim.planner, cov.radio,
                          cov.n_cells, config.beacon_interval, config.collinearity_tol, (6, 2.0),
                          error_limit=1.5)
    for field in ("kept", "order", "reference"):
        np.testing.assert_array_equal(getattr(plan, field), getattr(oracle, field))
    assert (plan.length, plan.full_length) == (oracle.length, oracle.full_length)
