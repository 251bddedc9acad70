"""Tests of aoass_env.clearance: the grid's bounds never exceed the true clearance."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env.clearance import ClearanceGrid, _edge_samples
from aoass_env.maps import ObstacleMap, generate_map

THIN = [(10.0, 2.0), (10.05, 2.0), (10.05, 9.0), (10.0, 9.0)]     # thinner than a cell
TRIANGLE = [(3.0, 3.0), (7.5, 4.0), (4.0, 8.3)]


def true_clearance(m: ObstacleMap, x: float, y: float) -> float:
    """Distance (m) to obstacles and border; 0 inside an obstacle or outside the field."""
    border = min(x, m.width - x, y, m.height - y)
    if border <= 0 or (m.polygons and m.inside_obstacle([(x, y)])[0]):
        return 0.0
    if not m.polygons:
        return border
    return min(border, shapely.distance(m.union, shapely.Point(x, y)))


@settings(max_examples=200, deadline=None)
@given(st.floats(-1.0, 21.0), st.floats(-1.0, 13.0), st.sampled_from([0.25, 0.7, 1.0, 2.0]))
def test_bound_is_a_lower_bound_of_the_clearance(x, y, cell):
    m = ObstacleMap(20.0, 12.0, [THIN, TRIANGLE, [(15, 8), (23, 8), (23, 14), (15, 14)]])
    bound = ClearanceGrid(m, cell).lower_bound(x, y)
    assert 0.0 <= bound <= true_clearance(m, x, y)


@pytest.mark.parametrize("seed", range(3))
def test_bounds_on_a_generated_map_are_safe_and_useful(seed):
    m = generate_map(60.0, 0.3, np.random.default_rng(seed))
    grid = ClearanceGrid(m)
    pts = np.random.default_rng(seed).uniform(0.0, 60.0, size=(3000, 2))
    bound = np.array([grid.lower_bound(x, y) for x, y in pts.tolist()])
    true = np.array([true_clearance(m, x, y) for x, y in pts.tolist()])
    assert np.all(bound <= true)
    assert np.mean(true - bound) < 2.0          # slack: about one cell diagonal and a half


def test_empty_field_bound_is_the_border_distance():
    grid = ClearanceGrid(ObstacleMap(10.0, 8.0))
    assert grid.lower_bound(3.0, 5.0) == 3.0
    assert grid.lower_bound(0.5, 5.0) == 0.0        # within half a cell diagonal: no claim
    assert grid.lower_bound(-1.0, 5.0) == 0.0


def test_edge_samples_are_close_enough():
    edges = np.array([[[0.0, 0.0], [3.0, 4.0]], [[1.0, 1.0], [1.0, 1.2]]])
    pts = _edge_samples(edges, 0.5)
    assert len(pts) == 10 + 1 + 1 + 1
    np.testing.assert_allclose(pts[[0, 10, 11, 12]], [[0, 0], [3, 4], [1, 1], [1, 1.2]])
    gaps = np.hypot(*np.diff(pts[:11], axis=0).T)
    assert gaps.max() <= 0.5 + 1e-12


def test_bad_cell():
    with pytest.raises(ValueError, match="cell"):
        ClearanceGrid(ObstacleMap(10.0, 10.0), cell=0.0)
    assert math.isinf(ClearanceGrid(ObstacleMap(10.0, 10.0, [[(20, 20), (25, 20), (25, 25)]]))
                      ._bound[0])
