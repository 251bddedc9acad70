"""Tests of aoass_env.safety.orca: ORCA half-planes and velocities with RVO2's semantics.

Analytic scenes check exact velocities (R: combined radius, tau: horizon). A velocity v is
permitted by a line when det(direction, point - v) <= 0 (RVO2's convention).
"""

from __future__ import annotations

import dataclasses
import math
import re
import sys

import numpy as np
import pytest
import shapely
from hypothesis import example, given, settings
from hypothesis import strategies as st

from aoass_env.safety.orca import (
    OrcaAgent,
    OrcaLines,
    StaticObstacles,
    active_constraints,
    orca_lines,
    orca_velocity,
    solve_velocity,
)
from tests.safety.orca_floats import ReferenceEdges, reference_lines, reference_solve
from tests.safety.orca_floats import _lp2 as reference_lp2

# a long wall 2 m above the origin (a CCW box: solid)
WALL = [(-10.0, 2.0), (10.0, 2.0), (10.0, 3.0), (-10.0, 3.0)]
# an L (CCW) whose inner corner is (1, 1); non-convex vertex there
ELL = [(0.0, 0.0), (4.0, 0.0), (4.0, 1.0), (1.0, 1.0), (1.0, 4.0), (0.0, 4.0)]
BOX = [(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)]
# a field border around the origin (CW: an enclosure)
BORDER = [(-5.0, -5.0), (-5.0, 5.0), (5.0, 5.0), (5.0, -5.0)]


def slack(lines: OrcaLines, v) -> np.ndarray:
    """det(d, p - v) per line: <= 0 where v is permitted."""
    p, d = lines.point, lines.direction
    return d[:, 0] * (p[:, 1] - v[1]) - d[:, 1] * (p[:, 0] - v[0])


def closest_approach(rel_position, rel_velocity, horizon: float) -> float:
    """Smallest distance (m) over [0, horizon] between two discs' centres; the second starts at
    ``rel_position`` relative to the first and moves at ``rel_velocity`` relative to it."""
    p, w = np.asarray(rel_position, float), np.asarray(rel_velocity, float)
    t = 0.0 if w @ w == 0 else float(np.clip(-(p @ w) / (w @ w), 0.0, horizon))
    return float(np.hypot(*(p + t * w)))


# --------------------------------------------------------------------------------------------
# free space
# --------------------------------------------------------------------------------------------

def test_nothing_around_returns_the_preferred_velocity():
    far_box = [(100.0, 100.0), (101.0, 100.0), (101.0, 101.0), (100.0, 101.0)]
    for kwargs in ({}, {"static_obstacles": StaticObstacles.empty()},
                   {"static_obstacles": [far_box]}, {"moving_obstacles": np.zeros((0, 5))}):
        v = orca_velocity((0, 0), (1, 0), (0.3, -0.4), 0.5, 2.0, **kwargs)
        assert v.dtype == np.float64 and v.shape == (2,)
        assert v.tolist() == [0.3, -0.4]
    lines = orca_lines((0, 0), (1, 0), 0.5, 2.0, static_obstacles=[far_box])
    assert len(lines) == 0 and lines.n_static == 0 and lines.point.shape == (0, 2)


def test_preferred_velocity_beyond_max_speed_is_scaled_to_the_circle():
    v = orca_velocity((0, 0), (0, 0), (3.0, 4.0), 0.5, 2.0)
    np.testing.assert_allclose(v, [1.2, 1.6], rtol=0, atol=1e-12)


# --------------------------------------------------------------------------------------------
# moving discs (they do not reciprocate)
# --------------------------------------------------------------------------------------------

def test_head_on_with_a_standing_disc_cuts_to_the_cut_off_circle():
    # R = 1, tau = 2: 3 m to contact -> at most 1.5 m/s straight ahead
    v = orca_velocity((0, 0), (1.8, 0), (1.8, 0), 0.5, 4.0, moving_obstacles=[[4, 0, 0, 0, 0.5]])
    np.testing.assert_allclose(v, [1.5, 0.0], atol=1e-12)


def test_head_on_with_a_standing_disc_projects_on_the_right_leg():
    # inside the cone beyond the cut-off circle: projected on the leg (ties pass on the right)
    v = orca_velocity((0, 0), (3, 0), (3, 0), 0.5, 4.0, moving_obstacles=[[5, 0, 0, 0, 0.5]])
    leg = math.sqrt(24.0)
    np.testing.assert_allclose(v, [72 / 25, -3 * leg / 25], atol=1e-12)
    assert closest_approach((5, 0), -v, 2.0) == pytest.approx(1.0, abs=1e-9)


def test_head_on_with_a_disc_coming_at_the_anchor():
    # closing speed 1 + 1 = 2 m/s, 3.5 m to contact in tau = 2 s -> closing at most 1.75 m/s
    v = orca_velocity((0, 0), (1, 0), (1, 0), 0.5, 4.0, moving_obstacles=[[4.5, 0, -1, 0, 0.5]])
    np.testing.assert_allclose(v, [0.75, 0.0], atol=1e-12)


def test_overtaking_a_slower_disc():
    # 2 m gap, tau = 2.5 s: the anchor may gain at most 0.8 m/s on the 1 m/s disc
    v = orca_velocity((0, 0), (2, 0), (2, 0), 0.5, 4.0, moving_obstacles=[[3, 0, 1, 0, 0.5]],
                      time_horizon=2.5)
    np.testing.assert_allclose(v, [1.8, 0.0], atol=1e-12)


def test_crossing_leaves_the_velocity_obstacle_by_the_smallest_change():
    # both would reach (3, 0) at t = 3 s
    disc = np.array([[3.0, -3.0, 0.0, 1.0, 0.5]])
    v = orca_velocity((0, 0), (1, 0), (1, 0), 0.5, 2.0, moving_obstacles=disc, time_horizon=5.0)
    assert closest_approach(disc[0, :2], disc[0, 2:4] - (1, 0), 5.0) == 0.0
    # v lies on the velocity obstacle's boundary: the discs just touch within the horizon
    gap = closest_approach(disc[0, :2], disc[0, 2:4] - v, 5.0)
    assert gap == pytest.approx(1.0, abs=1e-9)
    assert v[0] < 1.0       # slows down to let the disc pass ahead
    # u is the smallest change: no collision-free velocity is closer to the preferred one
    grid = np.stack(np.meshgrid(np.linspace(-1, 3, 201), np.linspace(-2, 2, 201)), -1)
    w = disc[0, 2:4] - grid.reshape(-1, 2)          # the disc's velocity relative to each
    t = np.clip(-(w @ disc[0, :2]) / np.maximum((w * w).sum(1), 1e-300), 0.0, 5.0)
    gaps = np.hypot(*(disc[0, :2] + t[:, None] * w).T)
    change = np.hypot(*(grid.reshape(-1, 2) - (1, 0)).T)
    assert change[gaps >= 1.0].min() >= np.hypot(*(v - (1, 0))) - 1e-12
    lines = orca_lines((0, 0), (1, 0), 0.5, 2.0, moving_obstacles=disc, time_horizon=5.0)
    assert len(lines) == 1 and slack(lines, v)[0] == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("disc, pref, full", [
    ([4.0, 0.0, 0.0, 0.0, 0.5], (1.8, 0.0), (1.5, 0.0)),      # standing disc ahead
    ([4.5, 0.0, -1.0, 0.0, 0.5], (1.0, 0.0), (0.75, 0.0)),    # disc coming at the anchor
    ([5.0, 0.0, 0.0, 0.0, 0.5], (3.0, 0.0), (72 / 25, -3 * math.sqrt(24) / 25)),  # legs
])
def test_responsibility_scales_the_correction(disc, pref, full):
    corrections = {}
    for share in (1.0, 0.5, 0.25):
        v = orca_velocity((0, 0), pref, pref, 0.5, 4.0, moving_obstacles=[disc],
                          responsibility=share)
        corrections[share] = v - np.array(pref)
    np.testing.assert_allclose(corrections[1.0], np.array(full) - pref, atol=1e-12)
    np.testing.assert_allclose(corrections[0.5], 0.5 * corrections[1.0], atol=1e-12)
    np.testing.assert_allclose(corrections[0.25], 0.25 * corrections[1.0], atol=1e-12)


def test_overlapping_disc_is_left_within_one_time_step():
    # centres 0.5 m apart, R = 1: at rest, leave at 1 m/s to separate within 0.5 s
    v = orca_velocity((0, 0), (0, 0), (0, 0), 0.5, 4.0, moving_obstacles=[[0.5, 0, 0, 0, 0.5]])
    np.testing.assert_allclose(v, [-1.0, 0.0], atol=1e-12)
    # the disc comes at the anchor at 1 m/s: (-3 + 1) m/s opens 0.5 m in 0.25 s
    v = orca_velocity((0, 0), (0, 0), (0, 0), 0.5, 4.0, moving_obstacles=[[0.5, 0, -1, 0, 0.5]],
                      time_step=0.25)
    np.testing.assert_allclose(v, [-3.0, 0.0], atol=1e-12)
    # half the responsibility: half the push
    v = orca_velocity((0, 0), (0, 0), (0, 0), 0.5, 4.0, moving_obstacles=[[0.5, 0, 0, 0, 0.5]],
                      responsibility=0.5)
    np.testing.assert_allclose(v, [-0.5, 0.0], atol=1e-12)
    # pushed out along the outward normal, whatever the preferred velocity
    v = orca_velocity((0, 0), (0, 0), (2, 1), 0.5, 4.0, moving_obstacles=[[0.3, 0.4, 0, 0, 0.5]])
    assert v @ np.array([-0.6, -0.8]) > 0.0


def test_moving_lines_come_nearest_first_after_the_static_ones():
    discs = [[6, 0, 0, 0, 0.5], [0, 3, 0, 0, 0.5], [-4, 0, 0, 0, 0.5]]
    lines = orca_lines((0, 0), (0, 0), 0.5, 2.0, static_obstacles=[WALL],
                       moving_obstacles=discs)
    alone = [orca_lines((0, 0), (0, 0), 0.5, 2.0, moving_obstacles=[d]) for d in discs]
    assert lines.n_static == 1 and len(lines) == 4
    for row, k in zip(range(1, 4), (1, 2, 0), strict=True):
        np.testing.assert_allclose(lines.point[row], alone[k].point[0])
        np.testing.assert_allclose(lines.direction[row], alone[k].direction[0])


# --------------------------------------------------------------------------------------------
# static obstacles
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("pref, expected", [
    ((0.0, 1.0), (0.0, 0.75)),
    ((0.3, 1.2), (0.3, 0.75)),
    ((-1.0, 2.5), (-1.0, 0.75)),
    ((1.5, 0.0), (1.5, 0.0)),      # sliding along: untouched
    ((-2.0, 0.5), (-2.0, 0.5)),    # slower than the limit toward the wall: untouched
    ((0.0, -1.0), (0.0, -1.0)),    # moving away: untouched
])
def test_wall_caps_the_normal_speed_at_distance_over_horizon(pref, expected):
    # 2 m to the wall, radius 0.5: 1.5 m in tau_obst = 2 s -> at most 0.75 m/s toward it
    v = orca_velocity((0, 0), pref, pref, 0.5, 3.0, static_obstacles=[WALL])
    np.testing.assert_allclose(v, expected, atol=1e-12)


def test_wall_line_is_the_shifted_cut_off_line():
    lines = orca_lines((0, 0), (0, 1), 0.5, 3.0, static_obstacles=[WALL])
    assert lines.n_static == len(lines) == 1
    np.testing.assert_allclose(lines.direction[0], [-1.0, 0.0])
    assert lines.point[0, 1] == pytest.approx(0.75)


@pytest.mark.parametrize("pref, expected", [((-1.0, -1.0), (-0.05, -0.05)),
                                            ((-1.0, 0.5), (-0.05, 0.5))])
def test_concave_corner_respects_both_walls(pref, expected):
    # 0.6 m from both walls of the inner corner, radius 0.5: 0.1 m in 2 s on each axis
    for velocity in (pref, (0.0, 0.0)):
        lines = orca_lines((1.6, 1.6), velocity, 0.5, 2.0, static_obstacles=[ELL])
        v = solve_velocity(lines, pref, 2.0)
        assert v[0] >= -0.05 - 1e-12 and v[1] >= -0.05 - 1e-12
        np.testing.assert_allclose(v, expected, atol=1e-12)
        assert (slack(lines, v) <= 1e-12).all()


def test_overlapping_a_static_vertex_forbids_going_deeper():
    # 0.42 m from the box corner (0, 0), radius 0.5: only v . (1, 1) <= 0 is permitted
    so = StaticObstacles.from_loops([BOX])
    lines = orca_lines((-0.3, -0.3), (0, 0), 0.5, 2.0, static_obstacles=so)
    assert len(lines) == 1 and lines.point.tolist() == [[0.0, 0.0]]
    np.testing.assert_allclose(orca_velocity((-0.3, -0.3), (0, 0), (1, 0), 0.5, 2.0,
                                             static_obstacles=so), [0.5, -0.5], atol=1e-12)
    np.testing.assert_allclose(orca_velocity((-0.3, -0.3), (0, 0), (1, 1), 0.5, 2.0,
                                             static_obstacles=so), [0.0, 0.0], atol=1e-12)
    out = orca_velocity((-0.3, -0.3), (0, 0), (-1, -0.5), 0.5, 2.0, static_obstacles=so)
    np.testing.assert_allclose(out, [-1.0, -0.5])
    assert out @ np.array([-1.0, -1.0]) > 0.0


def test_overlapping_a_static_segment_forbids_going_deeper():
    # 0.3 m below the box's bottom edge, radius 0.5: only v_y <= 0 is permitted
    so = StaticObstacles.from_loops([BOX])
    lines = orca_lines((1.0, -0.3), (0, 0), 0.5, 2.0, static_obstacles=so)
    assert len(lines) == 1
    np.testing.assert_allclose(lines.point[0], [0.0, 0.0])
    np.testing.assert_allclose(lines.direction[0], [-1.0, 0.0])
    np.testing.assert_allclose(orca_velocity((1.0, -0.3), (0, 1), (0.5, 1.0), 0.5, 2.0,
                                             static_obstacles=so), [0.5, 0.0], atol=1e-12)
    out = orca_velocity((1.0, -0.3), (0, 1), (0.5, -1.0), 0.5, 2.0, static_obstacles=so)
    np.testing.assert_allclose(out, [0.5, -1.0])
    assert out[1] < 0.0     # pushed out along the outward normal (0, -1)


def test_enclosure_keeps_the_anchor_in():
    # 1 m below the top of a CW border, radius 0.5: at most 0.25 m/s toward it in 2 s
    v = orca_velocity((0, 4), (0, 2), (0, 2), 0.5, 2.0, static_obstacles=[BORDER])
    np.testing.assert_allclose(v, [0.0, 0.25], atol=1e-12)
    so = StaticObstacles.from_loops([BORDER])
    assert not so.convex.any()      # every corner of an enclosure is concave
    inside = shapely.Polygon(BORDER)
    rng = np.random.default_rng(3)
    pos, vel, reached = np.array([0.0, 0.0]), np.zeros(2), 0.0
    for step in range(300):
        heading = 0.8 if step < 150 else rng.uniform(0, 2 * np.pi)
        pref = 2.0 * np.array([math.cos(heading), math.sin(heading)])
        vel = orca_velocity(pos, vel, pref, 0.5, 2.0, static_obstacles=so, time_step=0.1)
        pos = pos + 0.1 * vel
        assert inside.exterior.distance(shapely.Point(pos)) >= 0.5 - 1e-6
        assert inside.contains(shapely.Point(pos))
        reached = max(reached, np.abs(pos).max())
    assert reached > 4.4        # it did press against the walls


def test_infeasible_crowd_falls_back_to_the_3d_program():
    # eight discs closing in from all sides, a wall below: no velocity avoids them all
    angles = np.arange(8) * np.pi / 4 + 0.1
    ring = np.c_[1.5 * np.cos(angles), 1.5 * np.sin(angles)]
    discs = np.c_[ring, -ring / 1.5, np.full(8, 0.4)]
    wall = [(-10.0, -3.0), (10.0, -3.0), (10.0, -1.8), (-10.0, -1.8)]
    assert shapely.Polygon(wall).exterior.is_ccw
    lines = orca_lines((0, 0), (0, 0), 0.5, 1.0, static_obstacles=[wall],
                       moving_obstacles=discs, time_horizon=3.0)
    assert lines.n_static == 1 and len(lines) == 9
    v = solve_velocity(lines, (0.5, 0.5), 1.0)
    assert np.isfinite(v).all() and np.hypot(*v) <= 1.0 + 1e-9
    s = slack(lines, v)
    assert s[:1].max() <= 1e-9          # the static line stays hard
    assert s[1:].max() > 0.0            # the moving ones could not all be met
    # v minimises the largest penetration of a moving line over the permitted velocities
    rng = np.random.default_rng(0)
    radius, angle = np.sqrt(rng.uniform(0, 1, 20000)), rng.uniform(0, 2 * np.pi, 20000)
    candidates = np.c_[radius * np.cos(angle), radius * np.sin(angle)]
    p, d = lines.point, lines.direction
    pen = (d[:, 0][None] * (p[:, 1][None] - candidates[:, 1:2])
           - d[:, 1][None] * (p[:, 0][None] - candidates[:, 0:1]))
    ok = pen[:, 0] <= 0.0
    assert s[1:].max() <= pen[ok, 1:].max(axis=1).min() + 1e-9


# --------------------------------------------------------------------------------------------
# StaticObstacles
# --------------------------------------------------------------------------------------------

def test_from_loops_links_vertices_and_marks_convexity():
    so = StaticObstacles.from_loops([ELL, [(10.0, 10.0), (12.0, 10.0)], BORDER])
    assert len(so) == 6 + 2 + 4
    assert so.next[:6].tolist() == [1, 2, 3, 4, 5, 0]
    assert so.prev[:6].tolist() == [5, 0, 1, 2, 3, 4]
    assert so.next[6:8].tolist() == [7, 6] and so.prev[6:8].tolist() == [7, 6]
    assert so.next[8:].tolist() == [9, 10, 11, 8]
    assert so.convex.tolist() == [True, True, True, False, True, True, True, True,
                                  False, False, False, False]
    np.testing.assert_allclose(so.direction[0], [1.0, 0.0])
    np.testing.assert_allclose(so.direction[6], [1.0, 0.0])
    np.testing.assert_allclose(so.direction[7], [-1.0, 0.0])
    np.testing.assert_allclose(np.hypot(*so.direction.T), 1.0)
    # a closing vertex equal to the first (shapely's rings) is dropped
    closed = StaticObstacles.from_loops([[*BOX, BOX[0]]])
    assert len(closed) == 4
    assert StaticObstacles.from_loops([]).point.shape == (0, 2)
    assert len(StaticObstacles.empty()) == 0



def test_static_obstacles_declare_their_caches_and_rebuild_them():
    """Every attribute is a declared field (the per-call cache too, out of repr and init), and
    a copy with moved points answers from its own cache."""
    so = StaticObstacles.from_loops([ELL, BORDER])
    assert set(vars(so)) == {f.name for f in dataclasses.fields(so)}
    assert "_cache" not in repr(so)
    moved = dataclasses.replace(so, point=so.point + 100.0)
    for p in ([0.5, 2.0], [3.0, 0.5], [-4.0, 4.0]):
        assert moved.edges_near(np.add(p, 100.0), 1.5).tolist() == \
            so.edges_near(p, 1.5).tolist() != []
        assert moved.edges_near(p, 1.5).tolist() == []

def test_segments_near_any_are_the_union_of_the_discs_edges():
    """segments_near_any gives the edges within reach of any of the points, each once, in
    index order, as the union of edges_near over the points; none for no points."""
    from aoass_env.maps import generate_map

    so = StaticObstacles.from_loops(generate_map(60.0, 0.3, np.random.default_rng(7))
                                    .free_space_loops)
    rng = np.random.default_rng(8)
    for k in (0, 1, 2, 5):
        for _ in range(40):
            points, reaches = rng.uniform(-5.0, 65.0, (k, 2)), rng.uniform(0.0, 12.0, k)
            union = sorted({int(i) for p, r in zip(points, reaches, strict=True)
                            for i in so.edges_near(p, float(r))})
            starts, ends = so.segments_near_any(points, reaches)
            assert starts.tobytes() == so.point[union].tobytes()
            assert ends.tobytes() == so.point[so.next[union]].tobytes()
            assert starts.shape == ends.shape == (len(union), 2)
    with pytest.raises(ValueError, match="reaches must hold one distance per position"):
        so.segments_near_any(np.zeros((2, 2)), [1.0])
    with pytest.raises(ValueError, match="reach"):
        so.segments_near_any(np.zeros((1, 2)), [-1.0])


def test_edges_near_sorted_by_distance():
    so = StaticObstacles.from_loops([BOX])
    # from (1, -1): bottom edge 1 m, the two sides sqrt(2) m (their nearest vertices), top 3 m
    assert so.edges_near((1.0, -1.0), 10.0).tolist() == [0, 1, 3, 2]
    assert so.edges_near((1.0, -1.0), 1.5).tolist() == [0, 1, 3]
    assert so.edges_near((1.0, -1.0), 1.0).tolist() == []       # strictly closer than reach
    assert so.edges_near((50.0, 50.0), 3.0).dtype == np.int64
    assert StaticObstacles.empty().edges_near((0, 0), 5.0).tolist() == []


def test_the_compiled_edge_query_answers_as_the_array_code():
    """edges_near's compiled query gives the array code's list, order and ties included, along
    random walks and jumps with several reaches on a generated map, and from beside its
    vertices, where two edges nearest at their shared vertex tie exactly."""
    from aoass_env.maps import generate_map

    so = StaticObstacles.from_loops(generate_map(60.0, 0.4, np.random.default_rng(3))
                                    .free_space_loops)
    cache, reference = so._cache, ReferenceEdges(so)
    rng = np.random.default_rng(4)
    p = np.array([30.0, 30.0])
    answered = beside = 0
    for step in range(3000):
        p = rng.uniform(-5.0, 65.0, 2) if step % 200 == 0 else p + rng.uniform(-1.2, 1.2, 2)
        for reach in (2.7, 3.7, 9.7):
            expected = reference.near_array(float(p[0]), float(p[1]), reach)
            assert cache.near(float(p[0]), float(p[1]), reach) == expected
            answered += len(expected) > 1
    for x, y in so.point[::7].tolist():
        for reach in (2.7, 3.7):
            expected = reference.near_array(x + 0.3, y, reach)
            assert cache.near(x + 0.3, y, reach) == expected
            beside += len(expected) > 1
    assert answered > 1000 and beside > 20


def test_segments_near_are_the_indexed_end_points():
    """segments_near gives point[near] and point[next[near]] of edges_near's list (values,
    dtype, shape, order), shared read-only between the queries that find the same edges, with
    and without edges near, along random walks and jumps with several reaches."""
    from aoass_env.maps import generate_map

    so = StaticObstacles.from_loops(generate_map(60.0, 0.4, np.random.default_rng(5))
                                    .free_space_loops)
    rng = np.random.default_rng(6)
    p = np.array([30.0, 30.0])
    shared = empty = 0
    for step in range(2000):
        p = rng.uniform(-20.0, 80.0, 2) if step % 150 == 0 else p + rng.uniform(-0.6, 0.6, 2)
        for reach in (1.0, 2.7, 3.7):
            near = so.edges_near(p, reach)
            starts, ends = so.segments_near(p, reach)
            for got, want in ((starts, so.point[near]), (ends, so.point[so.next[near]])):
                assert got.dtype == want.dtype and got.shape == want.shape
                assert got.tobytes() == want.tobytes() and got.flags.c_contiguous
                assert not got.flags.writeable
            again = so.segments_near(p, reach)
            assert again[0] is starts and again[1] is ends
            shared += len(near) > 0
            empty += len(near) == 0
    assert shared > 1000 and empty > 100
    with pytest.raises(ValueError, match="reach"):
        so.segments_near(p, -1.0)
    with pytest.raises(ValueError, match="position"):
        so.segments_near([np.nan, 0.0], 1.0)


# --------------------------------------------------------------------------------------------
# bad input
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("kwargs, message", [
    ({"radius": -1}, re.escape("radius=-1 must be a number in (0.0, inf) m")),
    ({"radius": float("nan")}, "radius"),
    ({"max_speed": 0.0}, r"max_speed=0\.0 must be a number in \(0"),
    ({"position": (0.0, float("nan"))}, "position"),
    ({"position": np.zeros(3)}, "position must be a pair of finite numbers"),
    ({"velocity": "fast"}, "velocity"),
    ({"preferred_velocity": (1.0, float("inf"))}, "preferred_velocity"),
    ({"moving_obstacles": np.zeros((3, 4))},
     re.escape("moving_obstacles must have shape (n, 5) [x, y, vx, vy, radius], got (3, 4)")),
    ({"moving_obstacles": [[1, 2, 3, 4, float("nan")]]}, "moving_obstacles"),
    ({"moving_obstacles": [[1, 2, 3, 4, -0.5]]}, "moving_obstacles radii"),
    ({"static_obstacles": [[(0, 0), (1, float("nan")), (0, 1)]]}, r"static_obstacles\[0\]"),
    ({"static_obstacles": [BOX, [(0, 0)]]}, r"static_obstacles\[1\] must be .* k >= 2"),
    ({"static_obstacles": [BOX, [(0, 0), (0, 0), (1, 1)]]}, r"static_obstacles\[1\] repeats"),
    ({"static_obstacles": [np.zeros((3, 3))]}, r"static_obstacles\[0\].*shape \(3, 3\)"),
    ({"static_obstacles": np.zeros((4, 2))}, "sequence of"),
    ({"static_obstacles": 3}, "static_obstacles"),
    ({"time_horizon": 0}, r"time_horizon=0 must be a number in \(0"),
    ({"time_horizon_obst": -2}, r"time_horizon_obst=-2 must be a number in \(0"),
    ({"time_step": float("inf")}, "time_step"),
    ({"responsibility": 1.5}, r"responsibility=1\.5 must be a number in \(0\.0, 1\.0\]"),
    ({"responsibility": 0}, "responsibility"),
])
def test_bad_input_names_the_parameter(kwargs, message):
    args = {"position": (0, 0), "velocity": (0, 0), "preferred_velocity": (1, 0),
            "radius": 0.5, "max_speed": 2.0}
    args.update(kwargs)
    with pytest.raises(ValueError, match=message):
        orca_velocity(**args)


def test_bad_lines_and_reach_name_the_parameter():
    lines = orca_lines((0, 0), (0, 0), 0.5, 2.0, moving_obstacles=[[2, 0, 0, 0, 0.5]])
    with pytest.raises(ValueError, match="lines must be an OrcaLines"):
        solve_velocity(np.zeros((1, 4)), (0, 0), 2.0)
    with pytest.raises(ValueError, match="n_static"):
        solve_velocity(OrcaLines(lines.point, lines.direction, 2), (0, 0), 2.0)
    with pytest.raises(ValueError, match="max_speed"):
        solve_velocity(lines, (0, 0), -1.0)
    with pytest.raises(ValueError, match="preferred_velocity"):
        solve_velocity(lines, (0, 0, 0), 2.0)
    with pytest.raises(ValueError, match="reach"):
        StaticObstacles.from_loops([BOX]).edges_near((0, 0), -1.0)


def test_hand_built_directions_that_are_not_unit_edge_vectors_are_refused():
    """The solver reads directions as unit vectors (of each edge): a wall built with [0, 5]
    instead of [0, 1] gave v* = [-0.06, -1.0] instead of [0.25, 0], and an ORCA line with
    direction [10, 0] a velocity off its own half-plane; both were taken silently."""
    wall = StaticObstacles.from_loops([np.array([[1.0, -5.0], [1.0, 5.0]])])
    with pytest.raises(ValueError, match=r"StaticObstacles.direction must be the unit vector "
                                         r"of each edge"):
        StaticObstacles(wall.point, 5.0 * wall.direction, wall.next, wall.prev, wall.convex)
    again = StaticObstacles(wall.point, wall.direction, wall.next, wall.prev, wall.convex)
    np.testing.assert_array_equal(again.direction, wall.direction)
    with pytest.raises(ValueError, match=r"lines.direction must hold unit vectors"):
        solve_velocity(OrcaLines(np.array([[0.0, 0.5]]), np.array([[10.0, 0.0]]), 0),
                       (1.0, 0.0), 1.0)
    v = solve_velocity(OrcaLines(np.array([[0.0, 0.5]]), np.array([[1.0, 0.0]]), 0),
                       (1.0, 0.0), 1.0)
    assert v[1] >= 0.5 - 1e-12                     # on its half-plane, left of the line


# --------------------------------------------------------------------------------------------
# properties
# --------------------------------------------------------------------------------------------

@st.composite
def scenes(draw):
    """Random star-shaped CCW polygons (maybe overlapping), an optional CW border, moving discs
    and an anchor state."""
    loops = []
    for _ in range(draw(st.integers(0, 4))):
        cx, cy = draw(st.floats(-6, 6)), draw(st.floats(-6, 6))
        k = draw(st.integers(3, 7))
        turns = draw(st.lists(st.floats(0.2, 1.0), min_size=k, max_size=k))
        radii = draw(st.lists(st.floats(0.3, 3.0), min_size=k, max_size=k))
        angles = 2 * np.pi * np.cumsum(turns) / sum(turns)
        loops.append(np.c_[cx + np.array(radii) * np.cos(angles),
                           cy + np.array(radii) * np.sin(angles)])
    border = draw(st.booleans())
    if border:
        loops.append(np.array(BORDER) * 2.0)
    n = draw(st.integers(0, 5))
    discs = np.array([[draw(st.floats(-6, 6)), draw(st.floats(-6, 6)), draw(st.floats(-2, 2)),
                       draw(st.floats(-2, 2)), draw(st.floats(0.1, 1.0))] for _ in range(n)])
    state = {
        "position": (draw(st.floats(-5, 5)), draw(st.floats(-5, 5))),
        "velocity": (draw(st.floats(-3, 3)), draw(st.floats(-3, 3))),
        "radius": draw(st.floats(0.1, 1.0)),
        "max_speed": draw(st.floats(0.2, 3.0)),
        "time_horizon": draw(st.floats(0.5, 5.0)),
        "time_horizon_obst": draw(st.floats(0.5, 5.0)),
        "time_step": draw(st.floats(0.05, 1.0)),
        "responsibility": draw(st.sampled_from([0.5, 1.0])),
    }
    pref = (draw(st.floats(-3, 3)), draw(st.floats(-3, 3)))
    return loops, border, discs.reshape(-1, 5), state, pref


@settings(max_examples=200, deadline=None)
@given(scenes())
def test_orca_lines_own_rows_solve_as_the_checked_arrays(scene):
    """solve_velocity on orca_lines' result (its kept rows, no checks) gives the velocity it
    gives on the same lines as plain arrays (checked and converted), bit for bit; the arrays
    are read-only so the rows cannot go stale."""
    loops, _, discs, state, pref = scene
    lines = orca_lines(static_obstacles=loops, moving_obstacles=discs, **state)
    plain = OrcaLines(lines.point.copy(), lines.direction.copy(), lines.n_static)
    assert plain.table is None and lines.table is not None
    np.testing.assert_array_equal(solve_velocity(lines, pref, state["max_speed"]),
                                  solve_velocity(plain, pref, state["max_speed"]))
    assert not lines.point.flags.writeable and not lines.direction.flags.writeable
    assert active_constraints(lines, pref) == active_constraints(plain, pref)


@pytest.mark.parametrize("kwargs, message", [
    ({"radius": 0.0}, r"radius=0\.0 must be a number in \(0"),
    ({"max_speed": float("nan")}, "max_speed"),
    ({"time_horizon_obst": -1.0}, "time_horizon_obst"),
    ({"time_step": "0.5"}, "time_step"),
    ({"responsibility": 2.0}, r"responsibility=2\.0 must be a number in \(0\.0, 1\.0\]"),
])
def test_an_orca_agent_refuses_bad_settings_naming_them(kwargs, message):
    with pytest.raises(ValueError, match=message):
        OrcaAgent(**{"radius": 0.5, "max_speed": 2.0, **kwargs})


# linearProgram3 on two near-antiparallel lines (0 and 3): the projected line lies far from the
# origin and its chord end overshot the speed circle by 2.4e-6 m/s before the pull-back
_FAR_CHORD = ([], False,
              np.array([[-4.0859375, 0.4140625, 0.5, 0.0, 0.5], [0.0, 2.5625, -1.0, 0.0, 0.9921875],
                        [0.0, 0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 0.0, 1.0]]),
              {"position": (-3.814453125, 0.1015625), "velocity": (0.0, 2.1953125),
               "radius": 0.390625, "max_speed": 2.0, "time_horizon": 2.0,
               "time_horizon_obst": 1.0, "time_step": 0.05, "responsibility": 0.5},
              (0.0, 0.0))


@settings(max_examples=300, deadline=None)
@given(scenes())
@example(_FAR_CHORD)
def test_random_scenes_keep_speed_and_static_lines(scene):
    loops, border, discs, state, pref = scene
    lines = orca_lines(static_obstacles=loops, moving_obstacles=discs, **state)
    v = solve_velocity(lines, pref, state["max_speed"])
    assert np.isfinite(v).all()
    assert np.hypot(*v) <= state["max_speed"] + 1e-9
    ns = lines.n_static
    zero = slack(lines, (0.0, 0.0))[:ns]
    # zero velocity is permitted by every static line when the anchor overlaps no obstacle
    solids = [shapely.Polygon(loop) for loop in (loops[:-1] if border else loops)]
    anchor = shapely.Point(state["position"])
    if all(p.distance(anchor) > state["radius"] + 1e-9 for p in solids):
        assert zero.max(initial=0.0) <= 1e-12
    # when some velocity in the disc (zero) meets every static line, the result does too
    if zero.max(initial=0.0) <= 0.0:
        assert slack(lines, v)[:ns].max(initial=0.0) <= 1e-7
    assert np.array_equal(v, orca_velocity(preferred_velocity=pref, static_obstacles=loops,
                                           moving_obstacles=discs, **state))


PENTAGON = np.c_[5 + 1.5 * np.cos(np.pi + np.arange(5) * 2 * np.pi / 5),
                 1.5 * np.sin(np.pi + np.arange(5) * 2 * np.pi / 5)]
DIAMOND = [(3.5, 0.0), (5.0, -1.5), (6.5, 0.0), (5.0, 1.5)]
TALL_BOX = [(4.0, -1.5), (6.0, -1.5), (6.0, 1.5), (4.0, 1.5)]


@pytest.mark.parametrize("polygon, start_y, goal_y", [
    (PENTAGON, 0.5, 0.8), (PENTAGON, 0.1, 0.0), (PENTAGON, -0.4, -0.2),
    (DIAMOND, 0.2, 2.5), (DIAMOND, -0.3, 0.1), (TALL_BOX, 0.5, 3.0), (TALL_BOX, 0.0, -3.0),
])
def test_agent_gets_around_a_polygon_without_touching_it(polygon, start_y, goal_y):
    radius, max_speed, dt = 0.3, 1.5, 0.1
    so = StaticObstacles.from_loops([polygon])
    solid = shapely.Polygon(polygon)
    pos, vel, goal = np.array([0.0, start_y]), np.zeros(2), np.array([10.0, goal_y])
    for _ in range(200):
        to_goal = goal - pos
        dist = float(np.hypot(*to_goal))
        pref = to_goal / dist * min(max_speed, dist / dt) if dist > 0 else np.zeros(2)
        vel = orca_velocity(pos, vel, pref, radius, max_speed, static_obstacles=so,
                            time_step=dt)
        pos = pos + dt * vel
        assert solid.distance(shapely.Point(pos)) >= radius - 1e-6
    assert np.hypot(*(goal - pos)) < 1e-6


# --------------------------------------------------------------------------------------------
# the compiled lines (issue 20): the float code's lines bit for bit
# --------------------------------------------------------------------------------------------

def _bits(rows) -> list[tuple[int, ...]]:
    return [tuple(np.array(row, dtype=np.float64).view(np.int64).tolist()) for row in rows]


def _both_paths(**kwargs) -> tuple[tuple, tuple]:
    """(compiled, float code) lines of the same arguments: orca_lines' (rows, n_static,
    max_speed) and the oracle's reference_lines (tests/safety/orca_floats.py) on the checked
    floats."""
    from aoass_env.safety import orca
    args = [kwargs[k] for k in ("position", "velocity", "radius", "max_speed",
                                "static_obstacles", "moving_obstacles", "time_horizon",
                                "time_horizon_obst", "time_step", "responsibility")]
    lines = orca_lines(*args[:4], static_obstacles=args[4], moving_obstacles=args[5],
                       time_horizon=args[6], time_horizon_obst=args[7], time_step=args[8],
                       responsibility=args[9])
    compiled = (lines.table, lines.n_static, float(args[3]))
    (px, py), (vx, vy) = map(tuple, np.asarray(args[:2], dtype=np.float64).tolist())
    moving = orca._moving(kwargs["moving_obstacles"])
    floats = reference_lines(orca._static(kwargs["static_obstacles"]), moving, px, py, vx, vy,
                             float(kwargs["radius"]), float(kwargs["max_speed"]),
                             float(kwargs["time_horizon_obst"]), float(kwargs["time_horizon"]),
                             float(kwargs["time_step"]), float(kwargs["responsibility"]))
    return compiled, floats


_CORRECT_HYPOT = sys.version_info >= (3, 11)
_NOT_CORRECT = "math.hypot is correctly rounded since Python 3.11 only"


@pytest.mark.skipif(not _CORRECT_HYPOT, reason=_NOT_CORRECT)
def test_the_compiled_lines_are_the_float_codes():
    """Along random walks on a generated map (near and inside obstacles, with discs near,
    overlapping and concentric), and on the hypothesis-style scenes' shapes, the compiled lines
    equal the float code's, bit for bit and in order, with the same n_static, and so does the
    compiled solver's velocity (linearProgram3 included); every kind of line is met."""
    from aoass_env.maps import generate_map
    static = StaticObstacles.from_loops(generate_map(40.0, 0.5, np.random.default_rng(8))
                                        .free_space_loops)
    rng = np.random.default_rng(9)
    p = np.array([20.0, 20.0])
    from aoass_env.safety import orca
    kinds = {"through origin": 0, "static": 0, "moving": 0, "overlap": 0, "infeasible": 0}
    for step in range(2500):
        p = rng.uniform(0.0, 40.0, 2) if step % 100 == 0 else p + rng.uniform(-0.6, 0.6, 2)
        k = int(rng.integers(0, 4))
        discs = np.column_stack([p + rng.normal(0.0, 2.0, (k, 2)), rng.normal(0.0, 1.0, (k, 2)),
                                 rng.uniform(0.1, 1.0, k)])
        if k and step % 7 == 0:
            discs[0, :2] = p                                # concentric
        velocity = rng.normal(0.0, 1.0, 2)
        if step % 11 == 0:
            velocity[:] = 0.0
        kwargs = dict(position=p.copy(), velocity=velocity, radius=float(rng.uniform(0.3, 1.5)),
                      max_speed=float(rng.uniform(0.5, 2.5)), static_obstacles=static,
                      moving_obstacles=discs if k else None,
                      time_horizon=float(rng.uniform(0.5, 4.0)),
                      time_horizon_obst=float(rng.choice([0.5, 2.0, 4.0])), time_step=0.5,
                      responsibility=float(rng.choice([0.5, 1.0])))
        (array, n_static, max_speed), (want, want_static) = _both_paths(**kwargs)
        assert n_static == want_static and _bits(array.tolist()) == _bits(want), step
        # the compiled linear programs: the float code's velocity, bit for bit
        ox, oy = rng.normal(0.0, 1.5, 2).tolist()
        assert _bits([orca._solve(array, n_static, ox, oy, max_speed)]) == \
            _bits([reference_solve(want, want_static, ox, oy, max_speed)]), step
        kinds["infeasible"] += reference_lp2(want, max_speed, ox, oy, False)[0] < len(want)
        kinds["through origin"] += sum(x == 0.0 and y == 0.0 for x, y, _, _ in want[:n_static])
        kinds["static"] += n_static
        kinds["moving"] += len(want) - n_static
        kinds["overlap"] += int(k > 0 and (np.hypot(*(discs[:, :2] - p).T)
                                          <= discs[:, 4] + kwargs["radius"]).any())
    assert min(kinds.values()) > 50, kinds
    # no static obstacles, no discs, and loops given as a sequence
    for static_obstacles in (None, [ELL, BORDER], [WALL]):
        for moving in (None, np.array([[0.5, 0.5, 0.1, 0.0, 0.3]])):
            kwargs = dict(position=(0.5, 2.0), velocity=(0.3, 0.1), radius=0.4, max_speed=1.0,
                          static_obstacles=static_obstacles, moving_obstacles=moving,
                          time_horizon=2.0, time_horizon_obst=2.0, time_step=0.5,
                          responsibility=1.0)
            (array, n_static, _), (want, want_static) = _both_paths(**kwargs)
            assert n_static == want_static and _bits(array.tolist()) == _bits(want)


def _near_by_full_scan(cache, px, py, reach):
    """The edge query over every edge in NumPy (what the grid's cells must not change)."""
    e = cache.edges
    if len(e) == 0:
        return []
    rx, ry = px - e[:, 0], py - e[:, 1]
    s = np.minimum(np.maximum((rx * e[:, 4] + ry * e[:, 5]) * e[:, 6], 0.0), 1.0)
    gx, gy = rx - s * e[:, 4], ry - s * e[:, 5]
    dist2 = gx * gx + gy * gy
    hits = np.flatnonzero(dist2 < reach * reach)
    if len(hits) > 1:
        end = hits[s[hits] >= 1.0]
        dist2[end] = (px - e[end, 2]) ** 2 + (py - e[end, 3]) ** 2
        hits = hits[np.argsort(dist2[hits], kind="stable")]
    return hits.tolist()


def test_the_edge_grid_finds_what_a_full_scan_finds():
    """The edge query through the grid's cells returns the full scan's edges in its order:
    generated maps of 40 m and 200 m, queries inside, at the border and outside the field,
    on cell boundaries and on vertices, reaches from 0.1 m to past the field."""
    from aoass_env.maps import generate_map
    rng = np.random.default_rng(24)
    for size, density in ((40.0, 0.5), (200.0, 0.3)):
        static = StaticObstacles.from_loops(generate_map(size, density, rng).free_space_loops)
        cache = static._cache
        n_cells = int(cache.grid[3] * cache.grid[4])
        assert cache.cells[n_cells] == len(cache.cells) and len(cache.edges) > 50
        points = np.concatenate([rng.uniform(-10.0, size + 10.0, (400, 2)),
                                 cache.edges[rng.integers(0, len(cache.edges), 100), :2],
                                 4.0 * rng.integers(0, int(size / 4.0) + 1, (100, 2))])
        for px, py in points.tolist():
            reach = float(rng.choice([0.1, 1.9, 3.7, 5.7, 9.7, 25.0, 2.0 * size]))
            assert cache.near(px, py, reach) == _near_by_full_scan(cache, px, py, reach)


def test_the_stable_order_is_numpys_stable_argsort():
    """Random keys with many ties, sorted and reversed runs, one key and none."""
    from aoass_env.safety.orca import _stable_order
    rng = np.random.default_rng(14)
    cases = [np.zeros(0), np.ones(1), np.arange(30.0), np.arange(30.0)[::-1].copy(),
             np.full(17, 2.5)]
    cases += [rng.integers(0, 5, int(rng.integers(2, 80))).astype(float) for _ in range(200)]
    cases += [rng.normal(size=int(rng.integers(2, 300))) for _ in range(50)]
    for keys in cases:
        assert _stable_order(keys).tolist() == np.argsort(keys, kind="stable").tolist()


@pytest.mark.skipif(not _CORRECT_HYPOT, reason=_NOT_CORRECT)
@settings(max_examples=100, deadline=None)
@given(scenes(), scenes())
def test_an_orca_agent_builds_the_float_codes_lines_scene_after_scene(scene, other):
    """OrcaAgent checks its settings once; one agent then builds, for the anchor's state and
    obstacles of scene after scene, the float code's lines (tests/safety/orca_floats.py) bit
    for bit and in order, read-only (the safety stack keeps one per config)."""
    from aoass_env.safety import orca
    loops, _, discs, state, _ = scene
    settings_ = {k: v for k, v in state.items() if k not in ("position", "velocity")}
    agent = OrcaAgent(**settings_)
    for where, obstacles, moving in ((state, loops, discs), (other[3], other[0], other[2]),
                                     (state, loops, discs)):
        got = agent.lines(where["position"], where["velocity"], obstacles, moving)
        (px, py), (vx, vy) = np.asarray([where["position"], where["velocity"]],
                                        dtype=np.float64).tolist()
        want, want_static = reference_lines(
            orca._static(obstacles), orca._moving(moving), px, py, vx, vy,
            *(float(settings_[k]) for k in ("radius", "max_speed", "time_horizon_obst",
                                            "time_horizon", "time_step", "responsibility")))
        assert got.n_static == want_static and _bits(got.table.tolist()) == _bits(want)
        assert not got.table.flags.writeable
        # the lines and the program in one call: the same lines, the float code's velocity
        pref = (where["velocity"][1], -where["velocity"][0])
        lines, v_star = agent.velocity(where["position"], where["velocity"], pref, obstacles,
                                       moving)
        assert lines.n_static == want_static and _bits(lines.table.tolist()) == _bits(want)
        assert not lines.table.flags.writeable
        ox, oy = np.asarray(pref, dtype=np.float64).tolist()
        assert _bits([v_star.tolist()]) == _bits([reference_solve(
            want, want_static, ox, oy, float(settings_["max_speed"]))])
