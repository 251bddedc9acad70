"""Tests of aoass_env.segments: the edge grid and the exact segment test."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env.segments import CLEAR, CONTACT, CROSSES, GRID_SLACK, EdgeGrid


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
