"""The reconstructed baselines: OHM, FDPP, M-ANCHORO, OTPP (docs/baselines.md)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env.config import AOASSConfig
from aoass_env.maps import ObstacleMap, generate_map, load_map
from aoass_env.planning.baselines import BASELINE_METHODS, fdpp, m_anchoro, ohm
from aoass_env.planning.baselines.common import free_region, link_clearances, linked_path
from aoass_env.planning.detour import DetourPlanner
from aoass_env.simulator import Simulator, episode_map

SMALL = AOASSConfig(field_size=40, n_nodes=30, obstacle_density=0.2, n_moving_obstacles=0)


def _episode(name: str, config: AOASSConfig = SMALL, seed: int = 0,
             obstacle_map: ObstacleMap | None = None) -> tuple[Simulator, object]:
    method = BASELINE_METHODS[name]
    rng = np.random.default_rng(seed)
    omap = obstacle_map if obstacle_map is not None else episode_map(config, rng)
    sim = Simulator(config, rng, obstacle_map=omap, path=method.plan(omap, config))
    ctl = method.controller(sim) if method.controller else None
    sim.run(controller=ctl)
    return sim, ctl


def test_registry_labels_and_sources():
    assert set(BASELINE_METHODS) == {"ohm", "fdpp", "m-anchoro", "otpp"}
    for name, m in BASELINE_METHODS.items():
        assert m.name == name and m.reconstructed and "(reconstructed)" in m.label
        assert "doi 10." in m.source
    assert BASELINE_METHODS["m-anchoro"].controller is None
    assert BASELINE_METHODS["otpp"].controller is None


@pytest.mark.parametrize("name", ["ohm", "fdpp", "m-anchoro", "otpp"])
def test_small_episode_completes(name):
    sim, ctl = _episode(name)
    assert ctl is None or ctl.done
    assert math.isfinite(sim.network.distance_travelled) and sim.network.distance_travelled > 0
    assert 0.0 <= sim.network.coverage_ratio <= 1.0 and math.isfinite(sim.network.energy_total)
    assert sim.network.coverage_ratio > 0.5          # every sweep covers the small field
    assert sim.collisions == 0


@pytest.mark.parametrize("name", ["ohm", "fdpp", "m-anchoro", "otpp"])
def test_same_seed_same_path(name):
    a, _ = _episode(name, seed=3)
    b, _ = _episode(name, seed=3)
    np.testing.assert_array_equal(a.recorder.path_points, b.recorder.path_points)


# --- OHM ------------------------------------------------------------------------------------
SQUARE = ObstacleMap(40.0, 40.0, (np.array([[15.0, 5.0], [25.0, 5.0], [25.0, 15.0],
                                            [15.0, 15.0]]),))


def test_ohm_sweep_vertices_spacing_and_errors():
    v = ohm.sweep_vertices(40.0, 40.0, 10.0, 1.5)
    ys = np.unique(v[:, 1])
    assert ys[0] == 1.5 and ys[-1] == 38.5 and np.all(np.diff(ys) <= 10.0 + 1e-9)
    assert v[0, 0] == 1.5 and v[1, 0] == 38.5 and v[2, 0] == 38.5   # boustrophedon
    with pytest.raises(ValueError, match="spacing"):
        ohm.sweep_vertices(40.0, 40.0, 0.0, 1.5)
    with pytest.raises(ValueError, match="margin"):
        ohm.sweep_vertices(40.0, 40.0, 5.0, 25.0)


@pytest.mark.parametrize("side", [120.0, 190.0])
def test_ohm_on_an_empty_field_covers_its_whole_border(side):
    """With the spiral's passes' bound the lines came 23.4 m apart on these fields and the
    corners where a line starts or ends without a link heard only that line (Eq. 18 needs an
    off-line beacon): the bound of those corners keeps them covered."""
    from aoass_env.network import Network
    from aoass_env.planning.baselines import OHM
    config = AOASSConfig(field_size=side, obstacle_density=0.0, n_moving_obstacles=0,
                         n_nodes=10)
    field = ObstacleMap(side, side)
    sim = Simulator(config, np.random.default_rng(0), obstacle_map=field, method="ohm",
                    path=OHM.plan(field, config))
    controller = OHM.controller(sim)
    beacons = [sim.world.position.copy()]
    for _ in range(sim.step_limit()):
        speed, heading = controller.command(sim.world.position, sim.world.heading, config.dt)
        if controller.done:
            break
        beacons += [b[1:] for b in sim.step(speed, heading).beacons]
    edge = np.linspace(0.0, side, int(side * 2) + 1)
    zero, far = np.zeros_like(edge), np.full_like(edge, side)
    border = np.concatenate([np.c_[edge, zero], np.c_[edge, far], np.c_[zero, edge],
                             np.c_[far, edge]])
    net = Network(len(border), config)
    for b in beacons:
        d = border - b
        net.record_beacon(b, np.flatnonzero(d[:, 0]**2 + d[:, 1]**2 <= config.radio_range**2))
    assert controller.done and net.covered.all(), border[~net.covered][:4]


def test_ohm_boundary_route_rejoins_the_line():
    region = free_region(SQUARE, 1.0, 1.0)
    base = shapely.LineString([(1.5, 10.0), (38.5, 10.0), (38.5, 30.0), (1.5, 30.0)])
    hit = ohm.first_exit(np.array([1.5, 10.0]), np.array([38.5, 10.0]), region)
    assert hit == pytest.approx(12.5, abs=1e-6)
    points, leave = ohm.boundary_route(region, base, hit, 100.0)
    assert leave == pytest.approx(26.0 - 1.5, abs=1e-6)      # x = 26: same line, far side
    assert points[-1] == pytest.approx([26.0, 10.0])
    gap = shapely.distance(SQUARE.union, shapely.points(points))
    assert gap.min() >= 1.0 - 1e-6
    assert ohm.boundary_route(region, base, hit, 5.0) is None   # beyond the follow budget


def test_ohm_episode_keeps_clearance_and_rejoins():
    config = AOASSConfig(field_size=40, n_nodes=20, obstacle_density=0.0, n_moving_obstacles=0,
                         spiral_spacing=8.5)
    sim, ctl = _episode("ohm", config, obstacle_map=SQUARE)
    assert ctl.walks >= 1 and ctl.skips == 0 and ctl.done
    path = sim.recorder.path_points
    gap = shapely.distance(SQUARE.union, shapely.points(path))
    assert gap.min() >= config.anchor_radius + ohm.DEFAULT_GAP - 0.35   # turn-rate corner cut
    assert np.linalg.norm(path[-1] - sim.path.waypoints[-1]) < 1.0      # swept to the end
    with pytest.raises(ValueError, match="max_follow"):
        ohm.OHMController(sim, max_follow=-1.0)


# --- FDPP -----------------------------------------------------------------------------------
def test_fdpp_prefers_the_heading_with_more_unlocalized_nodes():
    flc = fdpp.fdpp_rules()
    pos = np.zeros(2)
    nodes = np.array([[15.0, 1.0], [18.0, -1.0], [12.0, 0.0], [20.0, 2.0], [0.0, 15.0]])
    k, step = fdpp.choose_heading(pos, math.pi / 2, nodes, np.full(6, 25.0), 25.0, flc)
    assert k == 0 and 0 < step <= 25.0
    reach = np.array([0.0, 25, 25, 25, 25, 25])          # east blocked: the next best, north
    k, _ = fdpp.choose_heading(pos, 0.0, nodes, reach, 25.0, flc)
    assert k in (1, 2)
    assert fdpp.choose_heading(pos, 0.0, nodes, np.zeros(6), 25.0, flc) is None


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(st.floats(-25, 25), st.floats(-25, 25)), min_size=0, max_size=20))
def test_fdpp_sector_inputs_are_fuzzy_ranges(pts):
    mean, share = fdpp.sector_inputs(np.zeros(2), np.array(pts).reshape(-1, 2), 25.0)
    assert np.all((0 <= mean) & (mean <= 1)) and np.all((0 <= share) & (share <= 1))
    assert share.sum() == pytest.approx(1.0 if pts else 0.0)


def test_fdpp_truncate_and_route():
    path = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])
    cut = fdpp.truncate(path, 15.0)
    assert fdpp.path_length(cut) == pytest.approx(15.0) and cut[-1] == pytest.approx([10, 5])
    assert fdpp.truncate(path, 50.0) is path
    config = AOASSConfig(field_size=40, n_nodes=10, obstacle_density=0.0, n_moving_obstacles=0)
    planner = Simulator(config, np.random.default_rng(0), obstacle_map=SQUARE).planner
    around = fdpp.route(planner, SQUARE, np.array([20.0, 2.0]), np.array([20.0, 20.0]), 1.5)
    assert len(around) > 2 and fdpp.path_length(around) > 18.0          # detours the square
    assert fdpp.route(planner, SQUARE, np.array([20.0, 2.0]), np.array([20.0, 20.0]), 1.5,
                      max_length=18.5) is None
    assert fdpp.route(planner, SQUARE, np.array([5.0, 5.0]), np.array([20.0, 10.0]), 1.5) is None


def test_fdpp_explores_the_nearest_open_cell_when_nobody_answers(monkeypatch):
    config = AOASSConfig(field_size=40, n_nodes=10, obstacle_density=0.0, n_moving_obstacles=0)
    sim = Simulator(config, np.random.default_rng(0), obstacle_map=SQUARE,
                    path=fdpp.plan(SQUARE, config))
    monkeypatch.setattr(sim.radio, "receivers", lambda p: np.zeros(0, dtype=np.int64))
    ctl = fdpp.FDPPController(sim, cell_side=10.0)
    assert ctl.cells.shape == (4, 4) and not ctl.cells.done.any()   # every cell has a free goal
    goal_of_square = ctl.cells.goals[ctl.cells.index(np.array([20.0, 10.0]))[0]]
    assert not SQUARE.inside_obstacle(goal_of_square[None], dilation=0.5).any()
    start = sim.world.position.copy()
    ctl.command(start, sim.world.heading, config.dt)
    assert ctl.explored == 1 and ctl.cells.done.sum() == 2          # the start cell + the goal
    target = ctl._follower.waypoints[-1]
    goals = ctl.cells.goals[~ctl.cells.done]
    assert np.linalg.norm(target - start) <= np.linalg.norm(goals - start, axis=1).min() + 1e-9
    assert ctl.cells.done[ctl.cells.index(target)[0]]


def test_fdpp_respects_its_budget_with_detours():
    rng = np.random.default_rng(1)
    omap = episode_map(SMALL, rng)
    sim = Simulator(SMALL, rng, obstacle_map=omap, path=fdpp.plan(omap, SMALL))
    ctl = fdpp.FDPPController(sim, budget=60.0)
    sim.run(controller=ctl)
    assert ctl.done and sim.network.distance_travelled <= 60.0 + SMALL.anchor_max_speed * SMALL.dt
    for bad in ({"budget": 0.0}, {"cell_side": -1.0}, {"min_cell_side": 100.0}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            fdpp.FDPPController(sim, **bad)


def test_fdpp_ends_when_every_cell_is_visited():
    config = AOASSConfig(field_size=40, n_nodes=30, obstacle_density=0.0, n_moving_obstacles=0)
    sim = Simulator(config, np.random.default_rng(0), obstacle_map=SQUARE,
                    path=fdpp.plan(SQUARE, config))
    ctl = fdpp.FDPPController(sim, budget=2000.0)
    sim.run(controller=ctl)
    assert ctl.done and sim.network.distance_travelled < 1000.0
    assert ctl.cells.side < config.radio_range and ctl.cells.done.all()    # refined, then done
    assert sim.network.coverage_ratio > 0.9


# --- M-ANCHORO ------------------------------------------------------------------------------
def test_m_anchoro_lattice_spacing():
    a = m_anchoro.lattice_side(25.0, 1.5)
    assert a == pytest.approx(25.0 - 1.5 * math.sqrt(2))
    pts, rows = m_anchoro.triangle_lattice(100.0, 100.0, a, 1.5)
    ys = np.unique(pts[:, 1])
    assert np.all(np.diff(ys) <= a * math.sqrt(3) / 2 + 1e-9)
    for k in np.unique(rows):
        assert np.all(np.diff(np.sort(pts[rows == k, 0])) <= a + 1e-9)
    assert pts.min() == pytest.approx(1.5) and pts.max() == pytest.approx(98.5)
    with pytest.raises(ValueError, match="margin"):
        m_anchoro.lattice_side(25.0, 20.0)


def test_m_anchoro_points_avoid_obstacles():
    rng = np.random.default_rng(2)
    omap = episode_map(SMALL, rng)
    pts = m_anchoro.beacon_points(omap, SMALL)
    assert len(pts) >= 3
    assert not omap.inside_obstacle(pts, dilation=SMALL.anchor_radius).any()


@pytest.mark.parametrize("k", range(3))
def test_m_anchoro_links_never_cut_through_an_obstacle(k):
    """Where no straight or detoured link keeps the link clearance, the link falls back to
    narrower passages, and a point the follower cannot reach at all is not planned: the
    planned path (Eq. 19's L_ideal) stays out of every obstacle. (It once joined such points
    straight: 30-100 m of these paths lay inside obstacles.) Fresh maps, seeds used nowhere
    else."""
    config = AOASSConfig(field_size=60, n_nodes=30, obstacle_density=0.4)
    omap = generate_map(60.0, 0.4, np.random.default_rng([560100, k]),
                        clearance=config.map_clearance)
    path = m_anchoro.plan(omap, config)
    line = shapely.LineString(path.waypoints)
    assert shapely.intersection(line, omap.union).length == 0.0
    # every beacon point is reachable: in the main free space at the follower's clearance
    planner = DetourPlanner(omap, min(link_clearances(config)))
    pts = m_anchoro.beacon_points(omap, config)
    assert all(planner.visible(a, b) or planner.path(a, b) is not None
               for a, b in zip(pts[:-1], pts[1:], strict=True))


def test_linked_path_narrows_its_clearance_before_skipping_a_point():
    """Two points either side of a wall with a 2.5 m gap: too narrow for the detour planner at
    the 1.5 m link clearance, wide enough at a narrower one; a third point walled in is
    skipped and the path ends at the last point reached."""
    def rect(x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
        return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])

    wall = [rect(19.0, 0.0, 21.0, 18.75), rect(19.0, 21.25, 21.0, 40.0)]
    pocket = [rect(29.0, 29.0, 39.0, 30.0), rect(29.0, 38.0, 39.0, 39.0),
              rect(29.0, 29.0, 30.0, 39.0), rect(38.0, 29.0, 39.0, 39.0)]
    omap = ObstacleMap(40.0, 40.0, (*wall, *pocket))
    config = AOASSConfig(field_size=40, n_nodes=10, obstacle_density=0.0, n_moving_obstacles=0)
    widest = max(link_clearances(config))
    assert DetourPlanner(omap, widest).path([10.0, 10.0], [25.0, 10.0]) is None
    path = linked_path(omap, np.array([[10.0, 10.0], [25.0, 10.0], [34.0, 34.0]]), config)
    w = path.waypoints
    assert shapely.intersection(shapely.LineString(w), omap.union).length == 0.0
    np.testing.assert_allclose(w[0], [10.0, 10.0])
    np.testing.assert_allclose(w[-1], [25.0, 10.0])       # the walled-in point is skipped
    assert (np.abs(w[:, 1] - 20.0) < 1.25).any()     # through the gap
    # a first point shut in the pocket: the path starts at the next one that reaches the field
    # (it once stayed in the pocket, every later point unreachable: a path of length 0)
    path = linked_path(omap, np.array([[34.0, 34.0], [10.0, 10.0], [25.0, 10.0],
                                       [10.0, 30.0]]), config)
    np.testing.assert_allclose(path.waypoints[0], [10.0, 10.0])
    np.testing.assert_allclose(path.waypoints[-1], [10.0, 30.0])


def test_m_anchoro_pruned_points_still_cover_an_empty_field():
    config = AOASSConfig(field_size=60, n_nodes=10, obstacle_density=0.0, n_moving_obstacles=0)
    empty = ObstacleMap(60.0, 60.0)
    pts = m_anchoro.beacon_points(empty, config)
    full, _ = m_anchoro.triangle_lattice(60.0, 60.0, m_anchoro.lattice_side(25.0, 1.5), 1.5)
    assert len(pts) < len(full)                                       # pruning removed some
    samples = m_anchoro.free_samples(empty, 1.7)                      # not the pruning grid
    heard = m_anchoro.hearing(pts, samples, empty, config)
    assert m_anchoro.triple_covered(pts, heard, config).all()


def test_m_anchoro_keeps_its_points_when_none_covers_a_sample():
    # two points and one sample: nothing is triple covered, so nothing is redundant; before,
    # pruning removed every point and a dense map (test/d0.50_f100_s514) had no path at all
    pts = np.array([[10.0, 10.0], [20.0, 10.0]])
    heard = np.ones((2, 1), dtype=bool)
    assert m_anchoro.prune(pts, heard, SMALL).all()
    assert not m_anchoro.prune(np.vstack([pts, [[10.0, 20.0], [20.0, 20.0]]]),
                               np.ones((4, 1), dtype=bool), SMALL).all()   # 4th is redundant


def test_m_anchoro_restoration_builds_coverage_that_needs_several_points():
    """A sample no point hears needs three new ones: each alone covers nothing, and the
    restoration kept a candidate only when it completed a sample, so it added none (dense
    maps: 1-3 points and no covered sample on fresh 60 m maps at density 0.5)."""
    # one sample at (30, 30), four candidates it hears
    candidates = np.array([[20.0, 30.0], [40.0, 30.0], [30.0, 40.0], [30.0, 20.0]])
    heard_c = np.ones((4, 1), dtype=bool)
    none = np.zeros((0, 2))
    added = m_anchoro.restore_coverage(none, candidates, np.zeros((0, 1), dtype=bool),
                                       heard_c, SMALL)
    assert sorted(added.tolist()) == [0, 1, 2]      # the fourth is not needed
    assert m_anchoro.triple_covered(candidates[added], heard_c[added], SMALL).all()


@pytest.mark.parametrize("k", range(2))
def test_m_anchoro_covers_most_of_a_dense_map(k):
    """On fresh 60 m maps at density 0.5 (seeds used nowhere else) its points triple-cover
    about two thirds of the free samples (0.64-0.66 on three maps; none before the
    restoration built coverage up)."""
    omap = generate_map(60.0, 0.5, np.random.default_rng([580100, 50, k]), clearance=2.5)
    config = AOASSConfig(field_size=60, n_nodes=50, obstacle_density=0.5)
    pts = m_anchoro.beacon_points(omap, config)
    samples = m_anchoro.free_samples(omap)
    covered = m_anchoro.triple_covered(pts, m_anchoro.hearing(pts, samples, omap, config),
                                       config)
    assert covered.mean() > 0.6


def test_m_anchoro_plans_a_path_on_the_densest_test_map():
    omap = load_map("test/d0.50_f100_s514")
    config = AOASSConfig(field_size=100, n_nodes=100, obstacle_density=0.5)
    path = m_anchoro.plan(omap, config)
    assert len(path.waypoints) >= 2 and np.isfinite(path.waypoints).all()
