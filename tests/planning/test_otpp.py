"""OTPP (reconstructed, docs/baselines.md): basic-square geometry, the Z on an empty field, the
obstacle-tolerance claim with one obstacle on c0, dense maps and bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env.config import AOASSConfig
from aoass_env.maps import ObstacleMap, load_map
from aoass_env.planning.baselines import BASELINE_METHODS, m_anchoro, otpp
from aoass_env.planning.detour import DETOUR_MARGIN
from aoass_env.radio import LineOfSight
from aoass_env.simulator import Simulator, episode_map

EMPTY_CONFIG = AOASSConfig(field_size=60, n_nodes=10, obstacle_density=0.0,
                           n_moving_obstacles=0)


def _sub_squares(width: float, height: float, side: float, margin: float):
    """(its three default points (3, 2), its sides (sx, sy), its rectangle extended to the
    field's border where it touches the shrunk border) for every sub-square of the field."""
    hx, hy = otpp.half_lines(width, side, margin), otpp.half_lines(height, side, margin)
    points, nodes = otpp.z_defaults(hx, hy)
    at = {tuple(n): p for n, p in zip(nodes.tolist(), points, strict=True)}
    for i in range(len(hx) - 1):
        for j in range(len(hy) - 1):
            x0, x1 = (0.0 if i == 0 else hx[i]), (width if i == len(hx) - 2 else hx[i + 1])
            y0, y1 = (0.0 if j == 0 else hy[j]), (height if j == len(hy) - 2 else hy[j + 1])
            slots = otpp.sub_square_slots((i, j))
            sides = (hx[i + 1] - hx[i], hy[j + 1] - hy[j])
            yield np.array([at[s] for s in slots]), sides, (x0, y0, x1, y1)


@settings(max_examples=40, deadline=None)
@given(st.floats(5.0, 100.0), st.floats(0.0, 0.6), st.floats(1.0, 6.0), st.floats(1.0, 6.0))
def test_every_field_point_is_within_range_of_its_sub_squares_three_points(r, margin_frac,
                                                                           wf, hf):
    margin = margin_frac * r / math.sqrt(2)
    side = otpp.basic_square_side(r, margin)
    assert side == pytest.approx(math.sqrt(2) * (r - math.sqrt(2) * margin))
    width, height = max(wf * r, 2.5 * margin + 1.0), max(hf * r, 2.5 * margin + 1.0)
    for defaults, (sx, sy), (x0, y0, x1, y1) in _sub_squares(width, height, side, margin):
        assert len(defaults) == 3
        corners = np.array([[x0, y0], [x1, y0], [x0, y1], [x1, y1]])   # farthest points
        far = np.linalg.norm(corners[:, None] - defaults[None], axis=2)
        assert far.max() <= r * (1 + 1e-9)
        u, v = defaults[1] - defaults[0], defaults[2] - defaults[0]
        area = abs(u[0] * v[1] - u[1] * v[0]) / 2
        assert area == pytest.approx(sx * sy / 2)          # three corners: a right triangle


def test_sub_square_slots_are_three_corners_in_z_order():
    assert otpp.sub_square_slots((0, 0)) == [(0, 0), (1, 0), (1, 1)]   # BL, BM, c0
    assert otpp.sub_square_slots((1, 0)) == [(1, 0), (2, 0), (1, 1)]   # BM, BR, c0
    assert otpp.sub_square_slots((2, 1)) == [(3, 1), (2, 2), (3, 2)]   # c0, TL, TM
    assert otpp.sub_square_slots((3, 3)) == [(3, 3), (3, 4), (4, 4)]   # c0, TM, TR


def test_empty_field_gets_the_z_defaults_in_morton_order():
    empty = ObstacleMap(60.0, 60.0)
    pts = otpp.beacon_points(empty, EMPTY_CONFIG)
    side = otpp.basic_square_side(25.0, 1.5)
    hx = otpp.half_lines(60.0, side, 1.5)
    np.testing.assert_allclose(hx, [1.5, 15.75, 30.0, 44.25, 58.5])       # 2 x 2 basic squares
    defaults, _ = otpp.z_defaults(hx, hx)
    assert len(defaults) == 4 * 7
    _, first = np.unique(defaults, axis=0, return_index=True)
    np.testing.assert_array_equal(pts, defaults[np.sort(first)])          # repeats dropped
    assert len(pts) == 19                                                 # 5 x 5 minus 6 mids
    np.testing.assert_allclose(pts[:7], [[1.5, 1.5], [15.75, 1.5], [30.0, 1.5], [15.75, 15.75],
                                         [1.5, 30.0], [15.75, 30.0], [30.0, 30.0]])
    np.testing.assert_allclose(pts[7], [44.25, 1.5])                      # next square, Morton
    path = otpp.plan(empty, EMPTY_CONFIG)
    assert empty.bounds_contain(path.waypoints, 1.5 - 1e-9).all()
    samples = m_anchoro.free_samples(empty, 1.7)
    heard = m_anchoro.hearing(pts, samples, empty, EMPTY_CONFIG)
    assert m_anchoro.triple_covered(pts, heard, EMPTY_CONFIG).all()


@settings(max_examples=12, deadline=None)
@given(st.floats(1.0, 7.0), st.sampled_from([(15.75, 15.75), (44.25, 15.75), (44.25, 44.25)]))
def test_one_obstacle_on_c0_is_tolerated(half, c0):
    square = np.array(c0) + half * np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    omap = ObstacleMap(60.0, 60.0, (square,))
    pts = otpp.beacon_points(omap, EMPTY_CONFIG)
    clearance = EMPTY_CONFIG.anchor_radius + DETOUR_MARGIN + otpp.LINK_MARGIN
    assert not omap.inside_obstacle(pts, dilation=clearance - 1e-6).any()
    assert omap.bounds_contain(pts, 1.5 - 1e-9).all()
    samples = m_anchoro.free_samples(omap)
    heard = m_anchoro.hearing(pts, samples, omap, EMPTY_CONFIG)
    assert m_anchoro.triple_covered(pts, heard, EMPTY_CONFIG).all()       # Lemma 2's promise
    assert len(pts) > 19                                                  # c0 moved several ways


def test_served_sub_squares_counts_where_lemma_2s_premise_holds():
    """An empty field and one obstacle on a c0 (the paper's assumption): every sub-square has a
    point that every one of its samples hears. A 1 m wall across the field at y = 22 m splits
    the samples of the four sub-squares of that row (y in 15.75-30 m) into two sides that no
    point sees both of."""
    assert otpp.served_sub_squares(ObstacleMap(60.0, 60.0), EMPTY_CONFIG) == (16, 16)
    square = np.array([15.75, 44.25]) + 7.0 * np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0],
                                                         [-1.0, 1.0]])
    assert otpp.served_sub_squares(ObstacleMap(60.0, 60.0, (square,)), EMPTY_CONFIG) == (16, 16)
    wall = np.array([[3.0, 21.5], [57.0, 21.5], [57.0, 22.5], [3.0, 22.5]])
    assert otpp.served_sub_squares(ObstacleMap(60.0, 60.0, (wall,)), EMPTY_CONFIG) == (12, 16)


def test_vectorised_hearing_matches_the_radio():
    omap = load_map("test/d0.30_f100_s506")
    samples = m_anchoro.free_samples(omap, 3.0)
    points = np.random.default_rng(0).uniform(0, 100, (40, 2))
    config = AOASSConfig(field_size=100)
    np.testing.assert_array_equal(
        otpp.hearing_pairs(points, samples, LineOfSight(omap), config.radio_range),
        m_anchoro.hearing(points, samples, omap, config))


def test_spread_measures_collinearity():
    chosen = np.array([[0.0, 0.0], [10.0, 0.0]])
    s = otpp.spread(chosen, np.array([[5.0, 0.0], [20.0, 0.0], [5.0, 6.0]]))
    assert s[0] == pytest.approx(0.0, abs=1e-9) and s[1] == pytest.approx(0.0, abs=1e-9)
    assert s[2] > 2.0
    assert otpp.spread(chosen[:1], np.array([[3.0, 4.0]]))[0] == pytest.approx(2.5)
    assert np.isinf(otpp.spread(np.zeros((0, 2)), np.ones((2, 2)))).all()


def test_dense_map_still_gives_a_finite_path_and_episode():
    omap = load_map("test/d0.60_f100_s515")
    config = AOASSConfig(field_size=100)
    path = otpp.plan(omap, config)
    assert np.isfinite(path.waypoints).all() and len(path.waypoints) > 10
    assert omap.bounds_contain(path.waypoints).all()
    small = AOASSConfig(field_size=40, n_nodes=30, obstacle_density=0.5, n_moving_obstacles=0)
    rng = np.random.default_rng(4)
    omap = episode_map(small, rng)
    sim = Simulator(small, rng, obstacle_map=omap, path=BASELINE_METHODS["otpp"].plan(omap, small))
    sim.run()
    assert math.isfinite(sim.network.distance_travelled) and sim.network.distance_travelled > 0
    assert 0.0 < sim.network.coverage_ratio <= 1.0


def test_bad_input_names_the_parameter():
    with pytest.raises(ValueError, match="margin"):
        otpp.basic_square_side(25.0, 20.0)
    with pytest.raises(ValueError, match="radio_range"):
        otpp.basic_square_side(0.0, 1.0)
    with pytest.raises(ValueError, match="margin"):
        otpp.plan(ObstacleMap(40.0, 40.0), AOASSConfig(field_size=40, radio_range=2.0,
                                                       edge_margin=1.5, beacon_interval=0.5,
                                                       coverage_cell=0.3))
    with pytest.raises(ValueError, match="side"):
        otpp.half_lines(40.0, -1.0, 1.5)
    with pytest.raises(ValueError, match="extent"):
        otpp.half_lines(0.0, 10.0, 1.5)
