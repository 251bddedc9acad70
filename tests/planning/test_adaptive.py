"""The adaptive sweep (aoass_env.planning.adaptive) and its action type in the environment."""

from __future__ import annotations

import numpy as np
import pytest

from aoass_env.action import AdaptiveAction, ResidualAction
from aoass_env.config import AOASSConfig, ConfigError
from aoass_env.env import AOASSEnv
from aoass_env.maps import ObstacleMap
from aoass_env.planning import AdaptiveConfig, SweepKnobs, default_spacing
from aoass_env.planning.adaptive import AdaptiveSweep, coverable, site_radio
from aoass_env.planning.coverage import CoverageMap
from aoass_env.planning.detour import DetourPlanner
from aoass_env.planning.follower import WaypointFollower
from aoass_env.simulator import Simulator
from aoass_env.wrappers import make_safe_env

OPEN = dict(field_size=60.0, n_nodes=120, obstacle_density=0.0, n_moving_obstacles=0)
#: The online skips of the rule before the defaults left them to the plan (the rule without a
#: plan, and the shipped adaptive policy's).
ONLINE = dict(skip_need=0.0, detour_need=0.0, detour_excess=20.0)
#: a wall across most of the field: the spiral's passes detour round its end
WALL = ObstacleMap(60.0, 60.0, [np.array([[20.0, 29.0], [60.0, 29.0], [60.0, 31.0],
                                          [20.0, 31.0]])])


def _sweep(config: AOASSConfig, seed: int, rule: AdaptiveConfig | None,
           obstacle_map: ObstacleMap | None = None,
           knobs: SweepKnobs | None = None) -> tuple[Simulator, object]:
    sim = Simulator(config, np.random.default_rng(seed), obstacle_map=obstacle_map)
    ctl = sim.adaptive_sweep(rule) if rule is not None else sim.follower(recovery=True)
    if knobs is not None:
        ctl.knobs = knobs
    sim.run(controller=ctl)
    return sim, ctl


def test_on_an_open_field_the_rule_covers_everything_with_a_shorter_path():
    config = AOASSConfig(**OPEN)
    spiral, done = _sweep(config, 0, None)
    adaptive, ctl = _sweep(config, 0, AdaptiveConfig())
    assert done.done and ctl.done
    assert adaptive.network.coverage_ratio == spiral.network.coverage_ratio == 1.0
    assert adaptive.coverage_map.ratio >= AdaptiveConfig().end_coverage
    assert adaptive.network.distance_travelled < 0.9 * spiral.network.distance_travelled
    assert not ctl.passed          # the plan left out what is covered; no online skips


@pytest.mark.parametrize("sites", [False, True])
def test_the_skip_knob_at_minus_one_passes_nothing_over_as_covered(sites):
    config = AOASSConfig(**OPEN)
    strict, ctl = _sweep(config, 0, AdaptiveConfig(sites=sites, **ONLINE),
                         knobs=SweepKnobs(skip=-1.0))
    assert ctl.done and not [p for p in ctl.passed if p.reason == "covered"]
    rule, ctl = _sweep(config, 0, AdaptiveConfig(sites=sites, **ONLINE))
    assert {p.reason for p in ctl.passed} == {"covered"}
    if not sites:      # on the pruned spiral the skips shorten the sweep (not on a site tour)
        assert strict.network.distance_travelled > rule.network.distance_travelled


def test_by_default_only_the_skip_knob_passes_covered_targets_over():
    """The defaults leave skipping to the plan; the agent's knob at +1 still reaches it."""
    config = AOASSConfig(**OPEN)
    _, ctl = _sweep(config, 0, AdaptiveConfig())
    assert ctl.done and not ctl.passed
    _, ctl = _sweep(config, 0, AdaptiveConfig(), knobs=SweepKnobs(skip=1.0))
    assert ctl.done and {p.reason for p in ctl.passed} == {"covered"}


def test_a_knob_short_of_its_bound_reaches_its_full_shift_at_knob_full():
    """A tanh actor's +1 is 0.98 or so: at the default knob_full (0.9) that is the full shift
    (skip_need from -0.25 to 0: covered targets passed over), where with knob_full 1 only an
    exact +1 got there and 0.98 passed nothing over."""
    config = AOASSConfig(**OPEN)
    full, ctl_full = _sweep(config, 0, AdaptiveConfig(), knobs=SweepKnobs(skip=1.0))
    near, ctl_near = _sweep(config, 0, AdaptiveConfig(), knobs=SweepKnobs(skip=0.98))
    assert ctl_near.passed and ctl_near.passed == ctl_full.passed
    assert near.network.distance_travelled == full.network.distance_travelled
    _, cliff = _sweep(config, 0, AdaptiveConfig(knob_full=1.0), knobs=SweepKnobs(skip=0.98))
    assert cliff.done and not cliff.passed
    # below knob_full the shift is linear in the knob: 0.45 at 0.9 is 0.5 at 1
    scaled, ctl_scaled = _sweep(config, 0, AdaptiveConfig(**ONLINE),
                                knobs=SweepKnobs(skip=0.45, detour=-0.45))
    plain, ctl_plain = _sweep(config, 0, AdaptiveConfig(**ONLINE, knob_full=1.0),
                              knobs=SweepKnobs(skip=0.5, detour=-0.5))
    assert ctl_scaled.passed == ctl_plain.passed
    assert scaled.network.distance_travelled == plain.network.distance_travelled
    with pytest.raises(ConfigError, match="knob_full=0.0 must be a number in \\(0.0, 1.0\\]"):
        AdaptiveConfig(knob_full=0.0)


def test_the_skip_knob_passes_over_no_point_the_plans_class_limit_needs():
    """A site tour's points that keep its classes narrow (``PrunedPlan.localizing``) lie where
    the coverage map may already read covered: the skip knob passes over other covered
    points, never these, unless ``skip_localizing`` lets it."""
    config = AOASSConfig(**OPEN)
    kept, ctl = _sweep(config, 0, AdaptiveConfig(), knobs=SweepKnobs(skip=1.0))
    localizing = set(np.flatnonzero(ctl.plan.localizing).tolist())
    passed = {p.index for p in ctl.passed if p.reason.startswith("covered")}
    assert localizing and passed and not passed & localizing
    free, loose = _sweep(config, 0, AdaptiveConfig(skip_localizing=True),
                         knobs=SweepKnobs(skip=1.0))
    assert np.array_equal(loose.plan.localizing, ctl.plan.localizing)
    loose_passed = {p.index for p in loose.passed if p.reason.startswith("covered")}
    assert loose_passed & localizing and passed < loose_passed
    assert free.network.distance_travelled < kept.network.distance_travelled
    # the rule's zero knobs pass nothing over either way: the same sweep
    rule, _ = _sweep(config, 0, AdaptiveConfig())
    same, _ = _sweep(config, 0, AdaptiveConfig(skip_localizing=True))
    assert rule.network.distance_travelled == same.network.distance_travelled


def test_on_a_map_denser_than_dense_above_the_dense_thresholds_skip_online():
    config = AOASSConfig(**{**OPEN, "map_clearance": 2.0})
    sparse = AdaptiveConfig(dense_above=0.5)          # WALL's density is about 0.02
    dense = AdaptiveConfig(dense_above=0.01)
    _, ctl = _sweep(config, 1, sparse, obstacle_map=WALL)
    assert ctl.online_thresholds() == (sparse.skip_need, sparse.detour_need,
                                       sparse.detour_excess)
    assert ctl.done and not ctl.passed
    sim, ctl = _sweep(config, 1, dense, obstacle_map=WALL)
    assert ctl.density == pytest.approx(WALL.density)
    assert ctl.online_thresholds() == (0.0, 0.0, 20.0)
    assert ctl.done and "covered" in {p.reason for p in ctl.passed}
    # the same as naming the thresholds themselves
    same, twin = _sweep(config, 1, AdaptiveConfig(dense_above=1.0, **ONLINE), obstacle_map=WALL)
    assert twin.passed == ctl.passed
    assert same.network.distance_travelled == sim.network.distance_travelled


def test_a_long_detour_is_left_open_and_revisited_after_the_spiral():
    config = AOASSConfig(**{**OPEN, "map_clearance": 2.0})
    sim, ctl = _sweep(config, 1, AdaptiveConfig(detour_excess=5.0, end_coverage=1.0,
                                                sites=False), obstacle_map=WALL)
    assert ctl.done
    long = [p for p in ctl.passed if p.reason == "long detour"]
    assert long and ctl.revisits
    assert sim.network.coverage_ratio >= 0.98
    assert sim.world.static_contacts == 0


def test_need_is_the_mean_deficit_of_the_cells_a_waypoint_sees():
    config = AOASSConfig(**OPEN)
    sim = Simulator(config, np.random.default_rng(0))
    ctl = sim.adaptive_sweep()
    i = ctl.follower.index
    cells = sim.coverage_map.visible_near(ctl.follower.waypoints[i], ctl.rule.skip_radius)
    assert ctl.need(i) == pytest.approx(sim.coverage_map.deficit[cells].mean())
    assert 0.0 < ctl.need(i) <= 1.0


def test_a_run_s_recoveries_count_once_when_the_sweep_ends_on_it():
    """The last cell run's back-outs were added when the run ended and again while it stayed
    the runner (nothing followed it): twice in info["recoveries"]."""
    config = AOASSConfig(**OPEN)
    field = ObstacleMap(60.0, 60.0)
    planner = DetourPlanner(field, config.anchor_radius + 0.5)
    start = np.array([30.0, 30.0])
    follower = WaypointFollower.nominal(config, start[None, :], planner=planner, recovery=True)
    sweep = AdaptiveSweep(follower, CoverageMap(field, config), planner, config,
                          AdaptiveConfig(prune=False))
    for _ in range(2):           # the one waypoint reached: the sweep heads for a cell
        sweep.command(start, 0.0, config.dt)
    assert sweep.densifying and sweep.cell >= 0
    cell_run = sweep._runner
    cell_run.recoveries = 2                     # it backed out twice on its way
    sweep._dropped[:] = True                    # and nothing is left after that cell
    sweep._dropped[sweep.cell] = False
    sweep.command(sweep.coverage.centres[sweep.cell], 0.0, config.dt)
    assert sweep.done and sweep._runner is cell_run
    assert sweep.recoveries == 2


def test_the_rule_config_is_validated_with_did_you_mean():
    with pytest.raises(ConfigError, match="skip_radius"):
        AdaptiveConfig(skip_radius=0.0)
    # shorter than half a cell's diagonal, a waypoint's surroundings held no cell centre: need
    # 0, and waypoints in unheard open field were passed over as covered
    with pytest.raises(ConfigError, match=r"adaptive skip_radius=1 m must be at least half a "
                                          r"coverage cell's diagonal, coverage_cell / sqrt 2 = "
                                          r"1\.77 m \(coverage_cell=2\.5 m\)"):
        AOASSEnv(**OPEN, action_type="adaptive", adaptive={"skip_radius": 1.0})
    sim = Simulator(AOASSConfig(**OPEN), np.random.default_rng(0))
    with pytest.raises(ConfigError, match="adaptive skip_radius=1 m"):
        sim.adaptive_sweep(AdaptiveConfig(skip_radius=1.0))
    with pytest.raises(ConfigError, match="did you mean 'skip_need'"):
        AdaptiveConfig.from_kwargs(skip_needs=0.1)
    with pytest.raises(ConfigError, match=r"skip_radius=-1.0 must be a number in \(0.0, 1000.0\]"):
        AOASSEnv(**OPEN, action_type="adaptive", adaptive={"skip_radius": -1.0})


def test_a_rule_without_the_adaptive_action_type_is_refused_not_ignored():
    with pytest.raises(ValueError, match="adaptive= configures the adaptive sweep"):
        AOASSEnv(**OPEN, adaptive={"skip_radius": 4.0})
    with pytest.raises(ValueError, match="action_type='adaptive'"):
        make_safe_env(**OPEN, adaptive={"skip_radius": 4.0})


def test_the_zero_adaptive_action_reproduces_the_rule_in_the_simulator():
    env = AOASSEnv(**OPEN, action_type="adaptive", adaptive=ONLINE)
    assert isinstance(env.action_type, AdaptiveAction) and env.action_space.shape == (5,)
    env.reset(seed=4)
    terminated = truncated = False
    while not (terminated or truncated):
        _, _, terminated, truncated, info = env.step(np.zeros(5, np.float32))
    assert terminated
    ref, _ = _sweep(env.config, 4, AdaptiveConfig(**ONLINE))
    np.testing.assert_array_equal(env.beacon_log.anchor_path, ref.finish().anchor_path)
    assert info["episode_metrics"]["passed_waypoints"] > 0
    assert info["area_coverage"] == ref.coverage_map.ratio


def test_the_safety_stack_passes_the_agents_knobs_to_the_sweep():
    env = make_safe_env(**OPEN, action_type="adaptive", obs_coverage_sectors=8)
    obs, _ = env.reset(seed=0)
    base = env.unwrapped
    assert isinstance(base.action_type, AdaptiveAction) and base.action_type.reaches_every_command
    assert env.action_space.shape == (5,)
    lay = base.obs_layout
    assert lay["coverage_sectors"] == slice(57, 65) and lay["area_coverage"] == slice(65, 66)
    env.step(np.array([0.0, 0.0, 1.0, -1.0, 0.5], np.float32))
    assert base.follower.knobs == SweepKnobs(1.0, -1.0, 0.5)
    with pytest.raises(ValueError, match=r"shape \(5,\) = \[dv, dtheta, skip, detour, densify\]"):
        env.step(np.zeros(2, np.float32))


def test_the_residual_type_keeps_the_spiral_follower_and_its_observation():
    env = AOASSEnv(**OPEN)
    env.reset(seed=0)
    assert isinstance(env.action_type, ResidualAction)
    assert env.action_type.knobs(np.zeros(2)) is None
    assert env.observation_space.shape == (57,) and "coverage_sectors" not in env.obs_layout
    for _ in range(120):     # past the first corner: beacons off one line
        _, _, _, _, info = env.step(np.zeros(2, np.float32))
    assert 0.0 < info["area_coverage"] < 1.0 and info["passed_waypoints"] == 0


def test_wide_passes_round_the_ring_count_down_and_keep_the_spirals_time_limit():
    assert default_spacing(100.0, 100.0, 25.0, 2.0, 1.5) == pytest.approx(48.5 / 3)
    assert default_spacing(100.0, 100.0, 25.0, 2.0, 1.5, wide=True) == pytest.approx(48.5 / 2)
    assert default_spacing(30.0, 30.0, 25.0, 2.0, 1.5, wide=True) == pytest.approx(13.5)
    residual = AOASSEnv()
    wide = {"wide_passes": True, "prune": False}
    adaptive = AOASSEnv(action_type="adaptive", adaptive=wide)
    assert residual.config.spiral_spacing is None
    assert adaptive.config.spiral_spacing == pytest.approx(24.25)
    assert adaptive.max_episode_steps == residual.max_episode_steps     # the same time allowed
    assert AOASSEnv(action_type="adaptive", adaptive=wide,
                    spiral_spacing=10.0).config.spiral_spacing == 10.0
    narrow = AOASSEnv(action_type="adaptive")     # the default rule prunes Eq. 5's spiral
    assert narrow.config.spiral_spacing is None
    adaptive.reset(seed=0, options={"map": ObstacleMap(200.0, 200.0)})
    assert adaptive.episode_config.spiral_spacing == pytest.approx(
        default_spacing(200.0, 200.0, 25.0, 2.0, 1.5, wide=True))
    assert adaptive.max_episode_steps == AOASSEnv(field_size=200.0).max_episode_steps


def test_the_rules_beacon_interval_sets_the_anchors_broadcasts_not_the_spirals_waypoints():
    base = AOASSEnv(action_type="adaptive", field_size=60.0, obstacle_density=0.0, n_nodes=20,
                    n_moving_obstacles=0)
    dense = AOASSEnv(action_type="adaptive", adaptive={"beacon_interval": 1.0},
                     field_size=60.0, obstacle_density=0.0, n_nodes=20, n_moving_obstacles=0)
    assert base.config.beacon_interval == 2.0 and dense.config.beacon_interval == 1.0
    assert dense.config.path_step == base.config.path_step == 2.0
    assert dense.max_episode_steps == base.max_episode_steps
    counts = []
    for env in (base, dense):
        env.reset(seed=3)
        np.testing.assert_array_equal(env.sim.path.waypoints, base.sim.path.waypoints)
        for _ in range(60):
            env.step(np.zeros(env.action_space.shape, np.float32))
        counts.append(env.sim.network.beacons_sent / env.sim.network.distance_travelled)
    assert counts[0] == pytest.approx(0.5, abs=0.05) and counts[1] == pytest.approx(1.0, abs=0.05)
    with pytest.raises(ConfigError, match="beacon_interval"):
        AdaptiveConfig(beacon_interval=0.0)


@pytest.mark.parametrize(("side_rate", "round_below"), [(0.5, True), (1000.0, False)])
def test_a_detour_goes_round_the_side_where_coverage_is_missing(side_rate, round_below):
    """The shortest way round the block passes above it, where beacons already covered the
    field; below it nothing is covered, for a few metres more."""
    block = ObstacleMap(120.0, 60.0, [np.array([[50.0, 15.0], [70.0, 15.0], [70.0, 40.0],
                                                [50.0, 40.0]])])
    config = AOASSConfig(field_size=120.0, n_nodes=10, obstacle_density=0.0,
                         n_moving_obstacles=0)
    coverage = CoverageMap(block, config)
    for y in (44.0, 50.0):
        for x in np.arange(50.0, 71.0, 2.0):
            coverage.add_beacon(np.array([x, y]))
    planner = DetourPlanner(block, config.anchor_radius + 0.5)
    start, goal = np.array([20.0, 30.0]), np.array([100.0, 30.0])
    shortest = planner.path(start, goal)
    assert np.max(shortest[:, 1]) > 40.0                     # above the block
    follower = WaypointFollower.nominal(config, np.array([start, goal]), planner=planner,
                                        start=1, recovery=True)
    sweep = AdaptiveSweep(follower, coverage, planner, config,
                          AdaptiveConfig(side_rate=side_rate, prune=False))
    sweep.command(start, 0.0, config.dt)
    if round_below:
        assert sweep.sides == [(1, config.dt)]
        assert sweep.target[1] < 15.0                         # the way's widest point, below
    else:
        assert sweep.sides == []
        np.testing.assert_array_equal(sweep.target, goal)


def _covered_below_the_wall() -> tuple[AOASSConfig, CoverageMap, DetourPlanner, np.ndarray]:
    """WALL's field covered below the wall by a grid of beacons; the anchor below it."""
    config = AOASSConfig(**{**OPEN, "map_clearance": 2.0})
    coverage = CoverageMap(WALL, config)
    for x in np.arange(2.0, 60.0, 4.0):
        for y in np.arange(2.0, 28.0, 4.0):
            coverage.add_beacon(np.array([x, y]))
    planner = DetourPlanner(WALL, config.anchor_radius + 0.5)
    start = np.array([40.0, 20.0])
    return config, coverage, planner, start


def test_a_cell_behind_a_wall_is_reached_along_the_planners_way_not_by_cutting_toward_it():
    """Below the wall everything is covered; the cells it lacks lie above, reached round the
    wall's open end: the sweep steers for the planner's inner points first."""
    config, coverage, planner, start = _covered_below_the_wall()
    follower = WaypointFollower.nominal(config, start[None, :], planner=planner, recovery=True)
    sweep = AdaptiveSweep(follower, coverage, planner, config,
                          AdaptiveConfig(prune=False, **ONLINE))
    sweep.command(start, 0.0, config.dt)
    assert sweep.densifying and not sweep.done and sweep.revisits == [(-1, config.dt)]
    # the way's first corner at the wall's open end (x < 20), not the cell above the wall
    assert sweep.target[0] < 21.0 and sweep.target[1] < 29.0
    assert planner.visible(start, sweep.target)


def test_cells_farther_than_the_hop_end_the_cells_phase():
    config, coverage, planner, start = _covered_below_the_wall()
    for hop, done in ((10.0, True), (1e4, False)):     # the lacking cells lie round the wall
        follower = WaypointFollower.nominal(config, start[None, :], planner=planner,
                                            recovery=True)
        sweep = AdaptiveSweep(follower, coverage, planner, config,
                              AdaptiveConfig(cell_hop=hop, prune=False, **ONLINE))
        speed, _ = sweep.command(start, 0.0, config.dt)
        assert sweep.done is done and (sweep.target is None) is done
        assert (speed == 0.0) if done else sweep.densifying


def test_the_site_radio_hears_a_cell_from_exactly_the_points_whose_beacon_the_cell_hears():
    """Range and sight are symmetric: the sites the site radio finds around a cell's virtual
    node are the lattice points from which the cells' own radio reaches that cell."""
    config = AOASSConfig(**{**OPEN, "map_clearance": 2.0})
    coverage = CoverageMap(WALL, config)
    planner = DetourPlanner(WALL, config.anchor_radius + 0.5)
    sites = site_radio(planner, coverage)
    assert site_radio(planner, coverage) is sites                  # once per map
    np.testing.assert_array_equal(sites.nodes, planner.main_cells(2))
    heard_from = [set(coverage.radio.receivers(p).tolist()) for p in sites.nodes]
    rng = np.random.default_rng(0)
    for cell in rng.choice(coverage.n_cells, 25, replace=False):
        found = set(sites.receivers(coverage.centres[cell]).tolist())
        assert found == {k for k, cells in enumerate(heard_from) if cell in cells}


def _beacons_on_a_line() -> tuple[AOASSConfig, CoverageMap, DetourPlanner, np.ndarray]:
    """An open 60 m field whose cells heard only beacons on the line y = 30: none is covered
    (collinear); the anchor on that line."""
    config = AOASSConfig(**{**OPEN, "map_clearance": 2.0})
    field = ObstacleMap(60.0, 60.0, [])
    coverage = CoverageMap(field, config)
    for x in np.arange(1.0, 60.0, config.beacon_interval):
        coverage.add_beacon(np.array([x, 30.0]))
    assert not coverage.covered.any()
    return config, coverage, DetourPlanner(field, config.anchor_radius + 0.5), np.array([30.0,
                                                                                        30.0])


@pytest.mark.parametrize("cell_sites", [True, False])
def test_a_cell_with_collinear_beacons_is_headed_for_at_a_site_off_their_line(cell_sites):
    """With ``cell_sites`` the cells phase heads for the cheapest point whose one beacon would
    complete the nearest lacking cell (spread >= tol + one beacon interval, more than an
    interval from the anchor), where a beacon does cover it; without, for a cell's centre, and
    the cells within two cells of the anchor are given up at once (reached)."""
    config, coverage, planner, start = _beacons_on_a_line()
    follower = WaypointFollower.nominal(config, start[None, :], planner=planner, recovery=True)
    sweep = AdaptiveSweep(follower, coverage, planner, config,
                          AdaptiveConfig(prune=False, cell_sites=cell_sites, **ONLINE))
    sweep.command(start, 0.0, config.dt)          # reaches its one waypoint: the spiral is done
    sweep.command(start, 0.0, config.dt)
    cell = sweep._cell
    centre = coverage.centres[cell]
    target = sweep.target
    if not cell_sites:     # the nearest cell beyond the two cells round the anchor it drops
        np.testing.assert_array_equal(target, centre)
        assert 2 * coverage.cell < np.hypot(*(centre - start)) <= 3 * coverage.cell
        return
    assert np.hypot(*(centre - start)) <= coverage.cell               # the nearest lacking cell
    need = config.collinearity_tol + config.beacon_interval
    assert coverage.residual_after(cell, target[None])[0] >= need
    assert np.hypot(*(target - start)) > config.beacon_interval
    # the cheapest such point of the lattice (on an open field: the nearest)
    sites = site_radio(planner, coverage).nodes
    spread = coverage.residual_after(cell, sites)
    ok = (spread >= need) & (np.hypot(*(sites - start).T) > config.beacon_interval) & (
        np.hypot(*(sites - centre).T) <= coverage.reach)
    costs = planner.costs(start, sites[ok])
    assert planner.costs(start, target[None])[0] == pytest.approx(costs.min())
    coverage.add_beacon(target)
    assert coverage.covered[cell]


def test_a_cell_is_coverable_when_beacons_from_every_reachable_point_would_cover_it():
    """Oracle, cell by cell: the lattice points within the cell's range and sight (the site
    radio's receivers of its virtual node), at least three, their root-sum-square distance to
    their best line (the scatter's least eigenvalue, by numpy's eigvalsh) at least
    collinearity_tol; a pocket behind a gap the anchor cannot pass holds cells that no
    reachable beacon covers."""
    pocket = ObstacleMap(60.0, 60.0, [
        np.array([[20.0, 29.0], [60.0, 29.0], [60.0, 31.0], [20.0, 31.0]]),
        np.array([[40.0, 44.0], [41.0, 44.0], [41.0, 60.0], [40.0, 60.0]]),
        np.array([[40.0, 44.0], [60.0, 44.0], [60.0, 45.0], [40.0, 45.0]])])
    for obstacle_map in (WALL, pocket):
        config = AOASSConfig(**{**OPEN, "map_clearance": 2.0})
        coverage = CoverageMap(obstacle_map, config)
        planner = DetourPlanner(obstacle_map, config.anchor_radius + 0.5)
        sites = site_radio(planner, coverage)
        expected = np.zeros(coverage.n_cells, dtype=bool)
        for cell, centre in enumerate(coverage.centres):
            points = sites.nodes[sites.receivers(centre)]
            if len(points) >= 3:
                d = points - points.mean(axis=0)
                expected[cell] = np.linalg.eigvalsh(d.T @ d)[0] >= config.collinearity_tol ** 2
        able = coverable(planner, coverage, config)
        np.testing.assert_array_equal(able, expected)
        assert coverable(planner, coverage, config) is able   # once per map
        if obstacle_map is pocket:
            assert not able.all() and able.mean() > 0.5


@pytest.mark.parametrize("rule", [dict(ONLINE), dict(ONLINE, sites=True, prune=False)],
                         ids=["online-skips", "sites"])
def test_the_needs_kept_between_beacons_are_the_needs_computed_anew(rule, monkeypatch):
    """need() keeps each waypoint's value until the coverage map records a beacon: the sweeps
    (their path, beacons and every pass-over) equal those that compute it on every call."""
    def computed_anew(self, index):
        cells = self._near.get(index)
        if cells is None:
            cells = self.coverage.visible_near(self.follower.waypoints[index],
                                               self.rule.skip_radius)
            self._near[index] = cells
        return float(self.coverage.deficit_at(cells).mean()) if len(cells) else 0.0

    config = AOASSConfig(field_size=60.0, n_nodes=120, obstacle_density=0.0,
                         n_moving_obstacles=2)
    runs = []
    for patch in (False, True):
        if patch:
            monkeypatch.setattr(AdaptiveSweep, "need", computed_anew)
        sim, ctl = _sweep(config, 3, AdaptiveConfig(**rule), obstacle_map=WALL)
        log = sim.finish()
        runs.append((log.beacons.tobytes(), sim.network.distance_travelled,
                     list(ctl.passed), sim.world.time))
    assert runs[0] == runs[1]
    assert runs[0][2]             # the online skips were taken: need() decided something


def test_the_sites_and_plans_of_a_map_go_with_it():
    """Beacon sites, coverable cells and plans are kept with their map: a cache weakly keyed
    by the coverage radio, whose value held that radio's map, kept every map alive with
    cell_sites on (and its planner grid, raster and plans)."""
    import gc
    import weakref

    from aoass_env.maps import generate_map
    from aoass_env.maps.generator import clear_cache

    config = AOASSConfig(field_size=40.0, n_nodes=20, n_moving_obstacles=0)
    field = generate_map(40.0, 0.2, np.random.default_rng([510210, 0]))
    sim = Simulator(config, np.random.default_rng(0), obstacle_map=field)
    sweep = sim.adaptive_sweep(AdaptiveConfig(cell_sites=True))
    sites = site_radio(sweep.planner, sim.coverage_map)
    assert site_radio(sweep.planner, sim.coverage_map) is sites          # built once
    assert coverable(sweep.planner, sim.coverage_map, config).any()
    gone = weakref.ref(field)
    del field, sim, sweep, sites
    clear_cache()                      # the generator's own few
    gc.collect()
    assert gone() is None


@pytest.mark.parametrize("rule", [AdaptiveConfig(beacon_interval=6.0, prune=False),
                                  AdaptiveConfig(wide_passes=True, prune=False)])
def test_a_sweep_on_a_config_without_the_rules_interval_or_passes_is_refused(rule):
    """Simulator.adaptive_sweep(rule) on a simulator built without sweep_config ran with the
    environment's beacon interval and Eq. 5's passes: the rule's were ignored, silently."""
    from aoass_env.planning.adaptive import sweep_config
    config = AOASSConfig(field_size=60.0, obstacle_density=0.0, n_nodes=50)
    field = ObstacleMap(60.0, 60.0)
    sim = Simulator(config, np.random.default_rng(0), obstacle_map=field)
    with pytest.raises(ConfigError, match=r"not in the simulator's config; build the Simulator "
                                          r"with sweep_config"):
        sim.adaptive_sweep(rule)
    fitted = Simulator(sweep_config(config, rule, 60.0), np.random.default_rng(0),
                       obstacle_map=field)
    sweep = fitted.adaptive_sweep(rule)
    assert sweep.config.beacon_interval == (rule.beacon_interval or config.beacon_interval)
