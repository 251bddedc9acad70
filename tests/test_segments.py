"""Tests of aoass_env.segments: the edge grid and the exact segment test."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env.segments import (
    CLEAR,
    CONTACT,
    CROSSES,
    GRID_SLACK,
    MAX_BUCKETS,
    EdgeGrid,
    meets_interior,
)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(0, 40))
def test_the_edge_grid_buckets_each_edge_where_its_widened_box_lies(seed, n):
    """Bucket (i, j) holds exactly the edges whose bounding box, GRID_SLACK wider, overlaps
    the cell [x0 + i cell, x0 + (i + 1) cell] x [y0 + j cell, ...], each once; every edge's
    box lies in the grid."""
    rng = np.random.default_rng(seed)
    edges = rng.uniform(-30, 90, (n, 2, 2))
    edges[: n // 3] = np.round(edges[: n // 3] / 4.0) * 4.0     # ends on bucket borders
    _, _, _, _, x0, y0, cell, nx, ny, first, members = EdgeGrid(edges).args
    assert len(first) == nx * ny + 1 and first[0] == 0 and first[-1] == len(members)
    lo, hi = edges.min(axis=1) - GRID_SLACK, edges.max(axis=1) + GRID_SLACK
    if n:
        assert lo[:, 0].min() >= x0 and lo[:, 1].min() >= y0
        assert hi[:, 0].max() < x0 + nx * cell and hi[:, 1].max() < y0 + ny * cell
    for j in range(ny):
        for i in range(nx):
            k = j * nx + i
            held = members[first[k]:first[k + 1]].tolist()
            def spans(e: int, axis: int, k: int, start: float) -> bool:
                return (math.floor((lo[e, axis] - start) / cell) <= k
                        <= math.floor((hi[e, axis] - start) / cell))
            want = [e for e in range(n) if spans(e, 0, i, x0) and spans(e, 1, j, y0)]
            assert held == want


def test_a_segment_crosses_clears_or_contacts_the_edges_it_meets():
    """A square's edges: through it (crosses), beside it (clear), along an edge or ending on
    one or at a vertex (contact); one and many segments alike, repeated queries independent."""
    square = np.array([[(0, 0), (2, 0)], [(2, 0), (2, 2)], [(2, 2), (0, 2)], [(0, 2), (0, 0)]],
                      dtype=float)
    grid = EdgeGrid(square)
    cases = [((-1, 1), (3, 1), CROSSES), ((-1, 3), (3, 3), CLEAR), ((0.5, 1), (1.5, 1), CLEAR),
             ((-1, 0), (3, 0), CONTACT), ((1, -1), (1, 0), CONTACT), ((-1, -1), (0, 0), CONTACT),
             ((5, 5), (5, 5), CLEAR), ((1, 0), (1, 0), CONTACT)]
    for _ in range(2):
        for a, b, want in cases:
            assert grid.status(*a, *b) == want, (a, b)
    a = np.array([c[0] for c in cases], dtype=float)
    b = np.array([c[1] for c in cases], dtype=float)
    np.testing.assert_array_equal(grid.statuses(a, b), [c[2] for c in cases])
    empty = EdgeGrid(np.zeros((0, 2, 2)))
    assert empty.status(0.0, 0.0, 1.0, 1.0) == CLEAR
    assert len(empty.statuses(np.zeros((0, 2)), np.zeros((0, 2)))) == 0


def test_meets_interior_exactly_on_degenerate_contacts():
    def rings(*loops):
        return [[(Fraction(x), Fraction(y)) for x, y in (*loop, loop[0])] for loop in loops]

    square = rings([(0, 0), (2, 0), (2, 2), (0, 2)])
    assert meets_interior((0, 0), (2, 2), square)            # the diagonal, vertex to vertex
    assert not meets_interior((0, 0), (2, 0), square)        # along an edge
    assert not meets_interior((-1, 0), (3, 0), square)       # overlapping an edge, past both ends
    assert not meets_interior((1, 3), (3, 1), square)        # touching the corner (2, 2)
    assert meets_interior((1, 1), (1, 1), square)            # a point inside
    assert not meets_interior((2, 1), (2, 1), square)        # a point on the boundary
    assert not meets_interior((2, 1), (5, 1), square)        # leaving from the boundary outward
    assert meets_interior((2, 1), (1.5, 1), square)          # entering from the boundary
    holed = rings([(0, 0), (4, 0), (4, 4), (0, 4)], [(1, 1), (1, 3), (3, 3), (3, 1)])
    assert not meets_interior((1.5, 1.5), (2.5, 2.5), holed)  # wholly in the hole
    assert meets_interior((2, 2), (2, 3.5), holed)           # from the hole into the solid
    # past the apex (2, 2) of a triangle by 2**-50 m: below it crosses the interior, at it or
    # above it does not (what GEOS, which rounds, could call a touch)
    triangle = rings([(0, 0), (4, 0), (2, 2)])
    assert meets_interior((0, 2 - 2.0**-50), (4, 2 - 2.0**-50), triangle)
    assert not meets_interior((0, 2), (4, 2), triangle)
    assert not meets_interior((0, 2 + 2.0**-50), (4, 2 + 2.0**-50), triangle)


def test_far_segments_still_find_their_buckets():
    # a wall 50..52 m high; segments reaching past 3.7e19 m used to wrap around to bucket 0 in
    # the integer conversion and miss it (CLEAR)
    wall = [(0.0, 50.0), (60.0, 50.0), (60.0, 52.0), (0.0, 52.0)]
    grid = EdgeGrid(np.array([[wall[k], wall[(k + 1) % 4]] for k in range(4)]))
    for end in (3e19, 1e20, 1e300):
        assert grid.status(3.0, 30.0, 3.0, end) == CROSSES
        assert grid.status(3.0, -end, 3.0, end) == CROSSES
        assert grid.status(-end, 51.0, end, 51.0) == CROSSES


def test_a_grid_of_too_many_buckets_is_refused_by_name():
    far_apart = np.array([[(0.0, 0.0), (1.0, 0.0)], [(2e5, 2e5), (2e5 + 1, 2e5)]])
    with pytest.raises(ValueError, match=rf"the edges span 2e\+05 x 2e\+05 m: more than "
                                         rf"MAX_BUCKETS={MAX_BUCKETS}"):
        EdgeGrid(far_apart)
