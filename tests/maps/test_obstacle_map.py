"""Tests of aoass_env.maps.obstacle_map: room checks, free-point sampling, geometry views."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from aoass_env.maps import MapError, ObstacleMap
from tests.maps.conftest import CLEARANCE, box, rng


def test_empty_map_is_traversable():
    ObstacleMap(20, 20).check_traversable(CLEARANCE)


def test_enclosed_pocket_is_rejected():
    ring = [box(4, 4, 16, 5), box(4, 15, 16, 16), box(4, 5, 5, 15), box(15, 5, 16, 15)]
    with pytest.raises(MapError, match=r"enclose part of the free space; 2 separate regions"):
        ObstacleMap(20, 20, ring, "ring").check_traversable(0.0)


def test_wall_across_the_field_disconnects_it():
    with pytest.raises(MapError, match="enclose"):
        ObstacleMap(20, 20, [box(0, 9, 20, 10)]).check_traversable(CLEARANCE)


@pytest.mark.parametrize("wall", [
    [box(0, 9, 9, 10), box(10, 9, 20, 10)],  # 1 m door between two obstacles
    [box(1, 9, 20, 10)],                      # 1 m gap between an obstacle and the border
])
def test_narrow_passage_depends_on_clearance(wall):
    m = ObstacleMap(20, 20, wall, "door")
    m.check_traversable(0.0)
    m.check_traversable(0.9)
    with pytest.raises(MapError, match=r"map 'door': passages narrower than clearance=1\.5 m"):
        m.check_traversable(1.5)


def test_no_room_errors():
    with pytest.raises(MapError, match="no free space"):
        ObstacleMap(10, 10, [box(0, 0, 10, 10)]).check_traversable(0.0)
    with pytest.raises(MapError, match="cannot move"):
        ObstacleMap(10, 10).check_traversable(12.0)
    with pytest.raises(MapError, match="clearance=-1"):
        ObstacleMap(10, 10).check_traversable(-1)


@pytest.mark.parametrize("clearance", [0.0, 1.0, 2.5])
def test_sampled_points_lie_in_free_space_with_clearance(dense_map, clearance):
    pts = dense_map.sample_free_points(400, rng(1), clearance=clearance)
    assert pts.shape == (400, 2) and pts.dtype == np.float64
    assert np.all(dense_map.bounds_contain(pts, margin=clearance))
    if clearance == 0:
        assert not shapely.contains_xy(dense_map.union, pts[:, 0], pts[:, 1]).any()
    else:
        assert shapely.distance(dense_map.union, shapely.points(pts)).min() >= clearance
    np.testing.assert_array_equal(pts, dense_map.sample_free_points(400, rng(1), clearance))


def test_sampling_is_uniform_over_free_space():
    m = ObstacleMap(100, 100, [box(0, 0, 50, 100)])
    pts = m.sample_free_points(4000, rng(2))
    assert pts[:, 0].min() >= 50
    # Uniform on [50, 100] x [0, 100]: each quarter holds 1000 +- 5 sigma (sigma ~ 27).
    quarters = np.histogram2d(pts[:, 0], pts[:, 1], bins=2, range=[[50, 100], [0, 100]])[0]
    assert np.all(np.abs(quarters - 1000) < 140)


def test_sampling_errors():
    m = ObstacleMap(10, 10)
    assert m.sample_free_points(0, rng()).shape == (0, 2)
    for n in (-1, 2.5, True):
        with pytest.raises(MapError, match=f"n={n!r}"):
            m.sample_free_points(n, rng())
    with pytest.raises(MapError, match="clearance=5 m leaves no room"):
        m.sample_free_points(3, rng(), clearance=5)
    with pytest.raises(TypeError, match="rng"):
        m.sample_free_points(3, None)
    full = ObstacleMap(10, 10, [box(0, 0, 10, 10)], "full")
    with pytest.raises(MapError, match="cannot place 5 points in map 'full'"):
        full.sample_free_points(5, rng())
    walled = ObstacleMap(10, 10, [box(0, 0, 10, 4.5), box(0, 5.5, 10, 10)])
    with pytest.raises(MapError, match="free area too small"):
        walled.sample_free_points(5, rng(), clearance=1.0)


def test_inside_obstacle_uses_exact_distance():
    m = ObstacleMap(10, 10, [box(2, 2, 4, 4)])
    pts = np.array([[3, 3], [4.99, 3], [5.01, 3], [4 + 0.7, 4 + 0.7], [1, 1]])
    np.testing.assert_array_equal(m.inside_obstacle(pts), [True, False, False, False, False])
    # corner point (4.7, 4.7) is 0.99 m from the corner (4, 4)
    np.testing.assert_array_equal(m.inside_obstacle(pts, 1.0), [True, True, False, True, False])


def test_convex_parts_reproduce_each_obstacle_exactly(dense_map):
    u_shape = np.array([[0, 0], [6, 0], [6, 5], [4, 5], [4, 2], [2, 2], [2, 5], [0, 5]])
    for m in (dense_map, ObstacleMap(10, 10, [u_shape])):
        parts = [shapely.Polygon(p) for p in m.convex_parts]
        for p in parts:
            assert p.is_valid and p.equals(shapely.convex_hull(p))
            assert p.exterior.is_ccw
        assert sum(p.area for p in parts) == pytest.approx(sum(s.area for s in m.shapes),
                                                           rel=1e-12)
        assert shapely.symmetric_difference(shapely.union_all(parts), m.union).area < 1e-9


@pytest.mark.parametrize("vertices", [
    np.array([[10.0, 30.0, 20.0], [10.0, 12.0, 40.0]]),   # (2, k): xs and ys, not vertices
    np.zeros((3, 3)), [10.0, 10.0, 30.0, 12.0, 20.0, 40.0], np.zeros((2, 3, 2))])
def test_a_polygon_must_be_k_by_2_vertices(vertices):
    """A (2, k) array of [xs, ys] used to be reshaped into other vertices, a different
    polygon without a word; other shapes failed deep in numpy."""
    with pytest.raises(MapError, match=r"obstacle 0: a polygon must be a \(k, 2\) array of "
                                       r"\(x, y\) vertices \(m\), got shape"):
        ObstacleMap(100.0, 100.0, [vertices])


def test_repeated_vertices_are_dropped_and_the_stored_vertices_are_read_only():
    ell = [(0, 0), (4, 0), (4, 1), (1, 1), (1, 4), (0, 4)]
    # a repeated vertex used to be kept, and pymunk's convex decomposition of the obstacle
    # (at the env's reset) crashed the process
    for noisy in (ell[:3] + [ell[2]] + ell[3:], ell + [ell[0], ell[0]], [ell[0]] + ell):
        m = ObstacleMap(10, 10, [noisy])
        assert m.polygons[0].tolist() == ObstacleMap(10, 10, [ell]).polygons[0].tolist()
        parts = m.convex_parts                       # where pymunk crashed
        assert sum(shapely.Polygon(p).area for p in parts) == pytest.approx(7.0)
    # maps are shared from caches: an in-place edit would change every later draw
    with pytest.raises(ValueError, match="read-only"):
        m.polygons[0][:] += 1.0


def test_derived_values_are_built_once_and_die_with_their_map():
    """``derived`` builds a value once per key; a value that refers back to its map (a Radio
    does) does not keep the map alive, and pickling leaves the derived values out."""
    import gc
    import pickle
    import weakref

    from aoass_env.radio import Radio

    m = ObstacleMap(20, 20, [box(4, 4, 8, 8)], "one")
    built = []
    first = m.derived(("test", 1), lambda: built.append(1) or [1])
    assert m.derived(("test", 1), lambda: built.append(2) or [2]) is first and built == [1]
    assert m.derived(("test", 2), lambda: [2]) == [2]
    radio = m.derived(("radio",), lambda m=m: Radio(np.array([[1.0, 1.0]]), m, 5.0))
    assert radio.obstacle_map is m
    copy = pickle.loads(pickle.dumps(m))
    assert "_derived" not in vars(copy) and copy.name == "one"
    assert copy.derived(("test", 1), lambda: [3]) == [3]
    ref = weakref.ref(m)
    del m, radio, first
    gc.collect()
    assert ref() is None


def test_the_convex_decomposition_is_pymunks_and_frees_what_chipmunk_returns():
    """The obstacles' convex parts are pymunk's decomposition, piece for piece; pymunk 7 never
    frees the polyline set Chipmunk returns (about 0.6 KB per call, every concave obstacle of
    every fresh map), the project's call does."""
    import os

    from pymunk import autogeometry

    from aoass_env.maps.generator import generate_map
    from aoass_env.maps.obstacle_map import _convex_decomposition

    def pieces(parts):
        return [[(q.x, q.y) for q in part] for part in parts]

    m = generate_map(60, 0.4, np.random.default_rng([510200, 1]))
    concave = [p for p in m.polygons
               if not shapely.Polygon(p).equals(shapely.convex_hull(shapely.Polygon(p)))]
    assert concave
    for p in concave:
        closed = [tuple(v) for v in p] + [tuple(p[0])]
        assert pieces(_convex_decomposition(closed)) == pieces(
            autogeometry.convex_decomposition(closed, 0.0))

    def resident_mb() -> float:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20

    if not os.path.exists("/proc/self/statm"):
        return                          # the resident size is read from Linux's /proc
    l_shape = [(0, 0), (4, 0), (4, 1), (1, 1), (1, 4), (0, 4), (0, 0)]
    before = resident_mb()
    for _ in range(30000):              # pymunk 7.3.1's own call: about 18 MB more here
        _convex_decomposition(l_shape)
    assert resident_mb() - before < 2.0
