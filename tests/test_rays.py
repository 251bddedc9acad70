"""Tests of aoass_env.rays: the compiled rays give Chipmunk's segment queries bit for bit."""

from __future__ import annotations

import math

import numpy as np
import pymunk
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from aoass_env import rays as rays_module
from aoass_env import world as world_module
from aoass_env.config import AOASSConfig
from aoass_env.maps import generate_map
from aoass_env.rays import StaticShapes, cast_rays, chipmunk_rays, compiled_rays
from aoass_env.world import World

OFFSETS = 2.0 * math.pi * np.arange(16) / 16


def compiled(space: pymunk.Space, shapes: StaticShapes, discs: np.ndarray, radius: float,
             x: float, y: float, heading: float, reach: float,
             offsets: np.ndarray = OFFSETS) -> np.ndarray:
    return cast_rays(x, y, heading, offsets, reach, shapes.vertices, shapes.normals,
                     shapes.first, shapes.boxes, discs, radius)


def test_the_compiled_rays_are_chipmunks_here():
    """On this platform the probe passes, so the world casts its rays compiled."""
    assert compiled_rays()


@pytest.mark.parametrize("density, seed", [(0.2, 40), (0.5, 41)])
def test_rays_on_generated_maps_are_chipmunks(density, seed):
    """From random points of a generated map (in free space, inside obstacles, on their
    vertices, on the border and outside the field), with random headings and reaches, among
    a world's walls, static parts and 12 moving discs: every distance is the space's query's,
    bit for bit."""
    obstacle_map = generate_map(60.0, density, np.random.default_rng(seed))
    config = AOASSConfig(field_size=60.0, obstacle_density=density, n_moving_obstacles=12)
    start = obstacle_map.sample_free_points(1, np.random.default_rng(seed), clearance=1.0)[0]
    world = World(config, obstacle_map, np.random.default_rng(seed), tuple(start))
    for _ in range(3):
        world.step(1.0, 0.3)
    shapes = world._ray_shapes
    assert shapes is not None and len(shapes.boxes) == len(obstacle_map.convex_parts) + 4
    rng = np.random.default_rng(seed + 100)
    vertices = shapes.vertices[shapes.vertices.max(axis=1) < 60.0]
    starts = np.concatenate([rng.uniform(-0.5, 60.5, (300, 2)), vertices[:100],
                             world.moving_positions + rng.uniform(-0.6, 0.6, (12, 2)),
                             np.column_stack([rng.uniform(0, 60, 20), np.zeros(20)])])
    hits = inside = 0
    for x, y in starts.tolist():
        heading = float(rng.choice([rng.uniform(-40.0, 40.0), math.pi / 4,
                                    rng.uniform(-1e6, 1e6)]))
        reach = float(rng.choice([10.0, rng.uniform(0.0, 30.0)]))
        got = compiled(world._space, shapes, world.moving_positions, world._r_moving, x, y,
                       heading, reach)
        want = chipmunk_rays(world._space, x, y, heading, OFFSETS, reach, world_module._SENSED)
        assert got.tobytes() == want.tobytes(), (x, y, heading, reach)
        hits += int((want < reach).sum())
        inside += int((want == 0.0).all())
    assert hits > 1500 and inside > 50


def _space(polygons: list[np.ndarray], discs: list[tuple[float, float]], radius: float
           ) -> tuple[pymunk.Space, StaticShapes]:
    space = pymunk.Space()
    shapes = []
    for points in polygons:
        shape = pymunk.Poly(space.static_body, [tuple(p) for p in points.tolist()])
        space.add(shape)
        shapes.append(shape)
    for cx, cy in discs:
        body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        body.position = (cx, cy)
        space.add(body, pymunk.Circle(body, radius))
    space.step(0.01)
    return space, StaticShapes.of(shapes)


coordinate = st.one_of(st.integers(0, 20).map(float), st.floats(0.0, 20.0))


@settings(max_examples=150, deadline=None)
@given(polygons=st.lists(st.lists(st.tuples(coordinate, coordinate), min_size=3, max_size=7),
                         max_size=5),
       discs=st.lists(st.tuples(coordinate, coordinate), max_size=3),
       radius=st.floats(0.1, 3.0), start=st.tuples(coordinate, coordinate),
       aim=st.one_of(st.floats(-10.0, 10.0), st.integers(-8, 8).map(lambda k: k * math.pi / 4)),
       reach=st.one_of(st.just(0.0), st.floats(0.0, 30.0), st.integers(1, 30).map(float)),
       from_vertex=st.booleans())
@example(polygons=[[(0.0, 1.0), (0.0, 6.147813711444833e-178), (1.0, 1.0)]], discs=[],
         radius=1.0, start=(0.0, 0.0), aim=0.0, reach=1.0, from_vertex=False)
def test_rays_among_random_shapes_are_chipmunks(polygons, discs, radius, start, aim, reach,
                                                from_vertex):
    """Random polygons (Chipmunk takes their hulls; collinear and repeated points, shared
    vertices and integer corners included), discs, starts (on a vertex too) and headings
    (along the axes and diagonals too), reach 0 included: the same distances, bit for bit.
    (The example: one polygon, the tree's root leaf, visited without its box test; a start
    whose distance to it underflows to 0 reads 0 on every ray.)"""
    points = [np.array(p, dtype=np.float64) for p in polygons
              if np.linalg.matrix_rank(np.array(p) - p[0]) == 2]    # a hull with an area
    space, shapes = _space(points, discs, radius)
    x, y = start
    if from_vertex and len(shapes.vertices):
        x, y = shapes.vertices[int(abs(aim) * 100) % len(shapes.vertices)].tolist()
    centres = np.array(discs, dtype=np.float64).reshape(-1, 2)
    got = compiled(space, shapes, centres, radius, x, y, aim, reach)
    assert got.tobytes() == chipmunk_rays(space, x, y, aim, OFFSETS, reach).tobytes()


def test_static_shapes_hold_chipmunks_hulls_and_planes():
    """The vertices are Chipmunk's hull (an inner point dropped), the normals unit outward
    ones of the edge ending at each vertex, the boxes the hulls' bounds."""
    space, shapes = _space([np.array([(0.0, 0.0), (4.0, 0.0), (1.0, 1.0), (4.0, 3.0),
                                      (0.0, 3.0)])], [], 1.0)
    assert shapes.first.tolist() == [0, 4]
    assert sorted(map(tuple, shapes.vertices.tolist())) == [(0.0, 0.0), (0.0, 3.0), (4.0, 0.0),
                                                           (4.0, 3.0)]
    np.testing.assert_allclose(np.hypot(*shapes.normals.T), 1.0, rtol=1e-15)
    previous = np.roll(shapes.vertices, 1, axis=0)
    centre = shapes.vertices.mean(axis=0)
    midpoints = (previous + shapes.vertices) / 2
    assert (np.einsum("ij,ij->i", shapes.normals, midpoints - centre) > 0).all()
    assert shapes.boxes.tolist() == [[0.0, 0.0, 4.0, 3.0]]
    with pytest.raises(ValueError, match="at least one vertex"):
        StaticShapes([np.zeros((0, 2))])


def test_the_world_falls_back_to_chipmunk_where_the_probe_fails(monkeypatch):
    """Where compiled rays would not be Chipmunk's, the world queries the space ray by ray,
    to the same distances."""
    obstacle_map = generate_map(60.0, 0.3, np.random.default_rng(42))
    config = AOASSConfig(field_size=60.0, obstacle_density=0.3, n_moving_obstacles=5)
    start = tuple(obstacle_map.sample_free_points(1, np.random.default_rng(3), clearance=1.0)[0])
    fast = World(config, obstacle_map, np.random.default_rng(3), start)
    monkeypatch.setattr(world_module, "compiled_rays", lambda: False)
    slow = World(config, obstacle_map, np.random.default_rng(3), start)
    assert fast._ray_shapes is not None and slow._ray_shapes is None
    for k in range(40):
        for w in (fast, slow):
            w.step(1.0, 0.2 * k)
        assert fast.ray_distances().tobytes() == slow.ray_distances().tobytes()


def test_the_probe_fails_where_the_floats_differ(monkeypatch):
    """The probe is a real check: a cast that differs in one plane's normal fails it."""
    compiled_rays.cache_clear()
    normals = rays_module._plane_normals

    def nudged(vertices: np.ndarray, first: np.ndarray) -> np.ndarray:
        out = normals(vertices, first)
        out[::7, 0] = np.nextafter(out[::7, 0], np.inf)
        return out

    monkeypatch.setattr(rays_module, "_plane_normals", nudged)
    try:
        assert not compiled_rays()
    finally:
        compiled_rays.cache_clear()


@pytest.mark.parametrize("x, y", [(7.0, 5.0), (5.0, 3.0), (12.0, 1.0), (10.0, 0.5), (11.0, 0.0)])
def test_a_start_on_a_rim_or_an_edge_reads_zero(x, y):
    """A start exactly on a disc's rim or on a polygon's edge or corner is a hit at 0 for
    every ray (Chipmunk's point query at the start: distance <= 0), compiled as in C."""
    space, shapes = _space([np.array([(10.0, 0.0), (14.0, 0.0), (14.0, 1.0), (10.0, 1.0)])],
                           [(5.0, 5.0)], 2.0)
    discs = np.array([(5.0, 5.0)])
    got = compiled(space, shapes, discs, 2.0, x, y, 0.3, 6.0)
    assert got.tobytes() == chipmunk_rays(space, x, y, 0.3, OFFSETS, 6.0).tobytes()
    assert (got == 0.0).all()


def test_a_ray_grazing_into_a_box_below_chipmunks_guard_misses_as_in_c():
    """Munk2D skips a plane the segment crosses at a slope below its guard (|a.n - b.n| <
    1e-5 m), so a ray that enters a box through that plane alone reads its full reach; the
    compiled cast keeps the quirk, and a steeper ray hits."""
    space, shapes = _space([np.array([(0.0, -5.0), (10.0, -5.0), (10.0, 0.0), (0.0, 0.0)])],
                           [], 1.0)
    offsets = np.zeros(1)
    for slope, hit in [(-2e-7, False), (-2e-5, True)]:
        got = compiled(space, shapes, np.zeros((0, 2)), 1.0, 1.0, 1e-7, slope, 10.0, offsets)
        assert got.tobytes() == chipmunk_rays(space, 1.0, 1e-7, slope, offsets, 10.0).tobytes()
        assert (got[0] < 10.0) == hit
