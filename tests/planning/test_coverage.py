"""The anchor's own coverage map (aoass_env.planning.coverage)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env.config import AOASSConfig, ConfigError
from aoass_env.maps import ObstacleMap, generate_map
from aoass_env.network import Network
from aoass_env.planning.coverage import PARTIAL_CELL_SHARE, CoverageMap, _free_points
from aoass_env.radio import Radio

EMPTY = ObstacleMap(40.0, 40.0)
CONFIG = AOASSConfig(field_size=40.0, radio_range=10.0, coverage_cell=2.0)


def _brute_force(centres: np.ndarray, beacons: np.ndarray, reach: float,
                 tol: float) -> np.ndarray:
    """Eq. 18 per cell centre from the whole beacon list (no obstacles): >= 3 beacons within
    ``reach``, root-sum-square distance from their best-fit line >= ``tol``."""
    out = np.zeros(len(centres), dtype=bool)
    for k, c in enumerate(centres):
        heard = beacons[np.hypot(*(beacons - c).T) <= reach]
        if len(heard) >= 3:
            centred = heard - heard.mean(axis=0)
            lam = np.linalg.eigvalsh(centred.T @ centred)[0]
            out[k] = math.sqrt(max(lam, 0.0)) >= tol
    return out


def test_cell_range_is_the_guaranteed_range_less_half_a_diagonal():
    assert CONFIG.cell_range == pytest.approx(10.0 - 2.0 / math.sqrt(2.0))
    assert CONFIG.replace(doi=0.2).cell_range == pytest.approx(8.0 - 2.0 / math.sqrt(2.0))
    # refused when the config is made (it used to validate, then fail at every reset)
    with pytest.raises(ConfigError, match="coverage_cell=8 m is too large"):
        CONFIG.replace(coverage_cell=8.0)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(st.floats(0, 40), st.floats(0, 40)), min_size=1, max_size=30))
def test_cells_are_covered_exactly_when_eq18_holds_at_their_centre(points):
    beacons = np.array(points, dtype=float)
    cov = CoverageMap(EMPTY, CONFIG)
    newly = sum(cov.add_beacon(b) for b in beacons)
    expected = _brute_force(cov.centres, beacons, cov.reach, CONFIG.collinearity_tol)
    np.testing.assert_array_equal(cov.covered, expected)
    assert newly == expected.sum()
    assert cov.ratio == pytest.approx(expected.mean())


def test_deficit_is_zero_exactly_on_covered_cells_and_one_where_nothing_was_heard():
    cov = CoverageMap(EMPTY, CONFIG)
    assert np.all(cov.deficit == 1.0)
    for b in ([10.0, 10.0], [12.0, 10.0], [11.0, 13.0], [30.0, 30.0]):
        cov.add_beacon(np.array(b))
    d = cov.deficit
    assert np.all((d == 0.0) == cov.covered) and cov.covered.any()
    assert np.all((d >= 0.0) & (d <= 1.0))
    assert np.all(d[cov.heard == 0] == 1.0)
    one = (cov.heard == 1)
    assert np.all(d[one] == 0.75)        # two beacons and the spread missing
    np.testing.assert_array_equal(cov.deficit_at(np.flatnonzero(one)), d[one])


@pytest.mark.parametrize("doi", [0.0, 0.2])
def test_a_node_in_a_covered_cell_is_covered_on_an_open_field(doi):
    """What the map calls covered, the nodes in it are (no obstacles: the range is the
    guaranteed one less half a cell diagonal)."""
    rng = np.random.default_rng(3)
    config = CONFIG.replace(doi=doi)
    nodes = EMPTY.sample_free_points(400, rng)
    radio = Radio.from_config(nodes, EMPTY, config, rng)
    net = Network(len(nodes), config)
    cov = CoverageMap(EMPTY, config)
    for b in rng.uniform(0.0, 40.0, (60, 2)):
        net.record_beacon(b, radio.receivers(b))
        cov.add_beacon(b)
    cell_of = {tuple(ij): k for k, ij in enumerate(cov.index)}
    in_covered = np.array([cov.covered[cell_of[(min(int(x // 2), 19), min(int(y // 2), 19))]]
                           for x, y in nodes])
    assert in_covered.sum() > 100
    assert np.all(net.covered[in_covered])


def test_cells_inside_obstacles_are_left_out_and_walls_block_beacons():
    wall = ObstacleMap(40.0, 40.0, [np.array([[17.9, 0.0], [22.1, 0.0], [22.1, 40.0],
                                              [17.9, 40.0]])])
    cov = CoverageMap(wall, CONFIG)
    assert cov.n_cells == 400 - 40          # the columns centred at x = 19 and 21 are inside
    assert not np.any((cov.centres[:, 0] > 18.5) & (cov.centres[:, 0] < 21.5))
    for b in ([10.0, 10.0], [14.0, 10.0], [12.0, 14.0]):
        cov.add_beacon(np.array(b))
    assert cov.covered.any()
    assert not np.any(cov.heard[cov.centres[:, 0] > 21.5])     # behind the wall: nothing
    seen = cov.visible_near(np.array([17.5, 10.0]), 5.0)
    assert len(seen) and np.all(cov.centres[seen, 0] < 18.5)
    assert np.all(np.hypot(*(cov.centres[seen] - [17.5, 10.0]).T) <= 5.0)
    raster = cov.raster()
    assert raster.shape == (20, 20) and np.all(np.isnan(raster[9:11]))


@pytest.mark.parametrize(("left", "kept"), [(18.8, True), (18.4, False)])
def test_a_cell_along_an_obstacle_edge_keeps_a_virtual_node_in_its_free_part(left, kept):
    # the cells [18, 20] x [y, y + 2] have their centre inside the wall; with x in [18, 18.8]
    # free (40 % of the cell, PARTIAL_CELL_SHARE 30 %) they are kept, with [18, 18.4] free
    # (20 %) left out
    wall = ObstacleMap(40.0, 40.0, [np.array([[left, 0.0], [21.5, 0.0], [21.5, 40.0],
                                              [left, 40.0]])])
    assert 0.2 < PARTIAL_CELL_SHARE < 0.4
    cov = CoverageMap(wall, CONFIG)
    column = cov.index[:, 0] == 9
    assert column.sum() == (20 if kept else 0)
    points = cov.centres[column]
    assert np.all((points[:, 0] >= 18.0) & (points[:, 0] <= left))
    assert not wall.inside_obstacle(points).any()
    if kept:        # a beacon on its side covers it; one behind the wall is not heard
        for b in ([12.0, 8.0], [14.0, 12.0], [12.0, 14.0]):
            cov.add_beacon(np.array(b))
        cell = np.flatnonzero(column & (cov.index[:, 1] == 5))[0]
        assert cov.covered[cell]
        behind = CoverageMap(wall, CONFIG)
        for b in ([28.0, 8.0], [26.0, 12.0], [28.0, 14.0]):
            behind.add_beacon(np.array(b))
        assert behind.heard[cell] == 0


def test_sector_deficits_read_by_bearing_from_the_heading():
    cov = CoverageMap(EMPTY, CONFIG)
    for b in ([4.0, 20.0], [8.0, 16.0], [8.0, 24.0], [2.0, 14.0], [2.0, 26.0]):
        cov.add_beacon(np.array(b))     # covers the west of the field near the centre line
    east = cov.sector_deficits(np.array([20.0, 20.0]), 0.0, 4, 15.0)
    west = cov.sector_deficits(np.array([20.0, 20.0]), math.pi, 4, 15.0)
    assert east.shape == (4,) and np.all((east >= 0) & (east <= 1))
    # sector 0 is straight ahead: east of the anchor (nothing heard) or west (some covered)
    assert east[0] == 1.0 and west[0] < east[0]
    np.testing.assert_allclose(west, np.roll(east, 2))
    assert np.all(cov.sector_deficits(np.array([-100.0, -100.0]), 0.0, 4, 5.0) == 0.0)
    # a NaN heading used to read as "all covered" (its sector index out of bounds), no sector
    # or a negative radius as something
    for position, heading in (([20.0, 20.0], math.nan), ([math.inf, 20.0], 0.0)):
        with pytest.raises(ValueError, match="must be finite"):
            cov.sector_deficits(np.array(position), heading, 4, 15.0)
    for n_sectors, radius in ((0, 15.0), (2.5, 15.0), (4, -5.0)):
        with pytest.raises(ValueError, match=r"n_sectors=.* must be an integer >= 1 and radius"):
            cov.sector_deficits(np.array([20.0, 20.0]), 0.0, n_sectors, radius)
    with pytest.raises(ValueError, match=r"radius=-5 must be a number >= 0 m"):
        cov.near(np.array([20.0, 20.0]), -5)


def test_maps_of_one_obstacle_map_share_its_raster_but_not_their_coverage():
    wall = ObstacleMap(40.0, 40.0, [np.array([[17.9, 0.0], [22.1, 0.0], [22.1, 30.0],
                                              [17.9, 30.0]])])
    first, second = CoverageMap(wall, CONFIG), CoverageMap(wall, CONFIG)
    assert first.centres is second.centres and first.index is second.index
    assert not first.centres.flags.writeable
    for b in ([10.0, 10.0], [14.0, 10.0], [12.0, 14.0]):
        first.add_beacon(np.array(b))
    assert first.covered.any() and not second.covered.any() and second.heard.sum() == 0
    other = CoverageMap(wall, AOASSConfig(coverage_cell=2.5))
    assert other.n_cells != first.n_cells               # another cell size, its own raster


def test_free_points_of_cells_inside_obstacles_follow_their_definition():
    """Each cell whose centre lies in an obstacle keeps the point on the surface of its free
    part exactly when at least PARTIAL_CELL_SHARE of it is free (issue 20: cells the obstacles
    cover skip the overlay, with the same virtual nodes)."""
    obstacle_map = generate_map(60.0, 0.5, np.random.default_rng(4))
    cell = 2.5
    n = math.ceil(60.0 / cell)
    index = np.stack(np.meshgrid(np.arange(n), np.arange(n), indexing="ij"), axis=-1)
    index = index.reshape(-1, 2)
    index = index[obstacle_map.inside_obstacle((index + 0.5) * cell)]
    expected = np.full((len(index), 2), np.nan)
    for k, (i, j) in enumerate(index):
        free = shapely.difference(shapely.box(i * cell, j * cell, (i + 1) * cell,
                                              (j + 1) * cell), obstacle_map.union)
        if free.area >= PARTIAL_CELL_SHARE * cell * cell:
            expected[k] = shapely.get_coordinates(shapely.point_on_surface(free))[0]
    got = _free_points(obstacle_map, index, cell)
    assert np.isnan(got).any() and np.isfinite(got).any()
    np.testing.assert_array_equal(got, expected)


def _sector_array_form(cov: CoverageMap, position: np.ndarray, heading: float, n_sectors: int,
                       radius: float) -> np.ndarray:
    """The NumPy array form of ``sector_deficits`` before its sums were compiled (kept as the
    reference)."""
    d = cov.centres - np.asarray(position, dtype=np.float64)
    inside = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] <= radius * radius
    bearing = np.arctan2(d[inside, 1], d[inside, 0]) - heading
    sector = np.floor(np.mod(bearing, 2.0 * math.pi) / (2.0 * math.pi) * n_sectors)
    sector = np.minimum(sector.astype(np.int64), n_sectors - 1)
    total = np.bincount(sector, weights=cov.deficit[inside], minlength=n_sectors)
    count = np.bincount(sector, minlength=n_sectors)
    return np.divide(total, count, out=np.zeros(n_sectors), where=count > 0)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_sectors=st.sampled_from([1, 3, 4, 8, 16]))
def test_sector_deficits_are_the_array_forms_bit_for_bit(seed, n_sectors):
    """On a generated map with beacons laid, at random points, on cell centres and on the
    radius, headings along the axes and the diagonals (bearings on sector borders) and random
    ones: the same floats as the array form, by their bytes."""
    rng = np.random.default_rng(seed)
    obstacle_map = generate_map(40.0, 0.3, rng)
    cov = CoverageMap(obstacle_map, CONFIG)
    for b in obstacle_map.sample_free_points(int(rng.integers(0, 30)), rng):
        cov.add_beacon(b)
    points = [rng.uniform(-5, 45, 2) for _ in range(6)] + [cov.centres[0].copy()]
    headings = [0.0, math.pi / 2, -math.pi, math.pi / 4, 2 * math.pi, float(rng.uniform(-9, 9))]
    for p in points:
        for heading in headings:
            for radius in (3.0, float(np.hypot(*(cov.centres[-1] - p))), 60.0):
                got = cov.sector_deficits(p, heading, n_sectors, radius)
                want = _sector_array_form(cov, p, heading, n_sectors, radius)
                assert got.dtype == want.dtype and got.shape == want.shape
                assert got.tobytes() == want.tobytes()


def test_deficits_of_some_cells_are_those_of_all_cells_picked():
    """deficit_at of a subset (its cells' residuals alone) equals, by its bytes, the deficit of
    every cell (the network's line residual of all of them) at those cells, in any order."""
    rng = np.random.default_rng(5)
    obstacle_map = generate_map(40.0, 0.3, rng)
    cov = CoverageMap(obstacle_map, CONFIG)
    for b in obstacle_map.sample_free_points(25, rng):
        cov.add_beacon(b)
        every = cov.deficit
        net = cov._network
        reference = np.where(net.covered[:cov.n_cells], 0.0, (np.maximum(
            0, 3 - net.heard[:cov.n_cells]) + 1.0 - np.minimum(
                1.0, net.line_residual[:cov.n_cells] / CONFIG.collinearity_tol)) / 4.0)
        assert every.tobytes() == reference.tobytes()
        pick = rng.permutation(cov.n_cells)[:40]
        assert cov.deficit_at(pick).tobytes() == reference[pick].tobytes()
    assert 0.0 < cov.deficit.mean() < 1.0
