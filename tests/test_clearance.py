"""Tests of aoass_env.clearance: a certificate never claims clearance that is not there."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env.clearance import MARGIN, ClearanceCertificates
from aoass_env.maps import ObstacleMap, generate_map

THIN = [(10.0, 2.0), (10.05, 2.0), (10.05, 9.0), (10.0, 9.0)]
TRIANGLE = [(3.0, 3.0), (7.5, 4.0), (4.0, 8.3)]


def signed_distance(m: ObstacleMap, x: float, y: float) -> float:
    """Distance (m) to the obstacles and the border; negative inside or outside the field."""
    border = min(x, m.width - x, y, m.height - y)
    if border <= 0:
        return border
    d = shapely.distance(m.union, shapely.Point(x, y)) if m.polygons else math.inf
    if m.polygons and shapely.contains_xy(m.union, x, y):
        return -1.0
    return min(border, d)


def capped(m: ObstacleMap, cap: float):
    calls = []

    def distance(x: float, y: float) -> float:
        calls.append((x, y))
        return min(signed_distance(m, x, y), cap)
    return distance, calls


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.floats(-1.0, 21.0), st.floats(-1.0, 13.0), st.floats(0.0, 3.0)),
                min_size=1, max_size=30),
       st.sampled_from([0.5, 2.0, 4.0]))
def test_a_clear_answer_is_true(queries, cap):
    """Whatever the history of one slot, ``clear`` answers True only when every point within
    reach lies more than MARGIN away from the obstacles and the border."""
    m = ObstacleMap(20.0, 12.0, [THIN, TRIANGLE, [(15, 8), (23, 8), (23, 14), (15, 14)]])
    distance, _ = capped(m, cap)
    certs = ClearanceCertificates(distance, 1)
    for x, y, reach in queries:
        if certs.clear(0, x, y, reach):
            assert signed_distance(m, x, y) > reach + MARGIN


def test_nearby_queries_reuse_the_certificate():
    m = generate_map(60.0, 0.3, np.random.default_rng(0))
    distance, calls = capped(m, 4.0)
    certs = ClearanceCertificates(distance, 2)
    rng = np.random.default_rng(1)
    start = next(p for p in m.sample_free_points(100, rng) if signed_distance(m, *p) > 2.5)
    path = start + np.cumsum(rng.normal(scale=0.05, size=(400, 2)), axis=0)
    answers = [certs.clear(0, x, y, 0.7) for x, y in path.tolist()]
    truth = [signed_distance(m, x, y) > 0.7 + MARGIN for x, y in path.tolist()]
    assert all(t for a, t in zip(answers, truth, strict=True) if a)
    assert len(calls) < 0.5 * len(path)             # most steps reuse a certificate
    assert sum(answers) >= 0.5 * sum(truth)          # and it is useful


def test_slots_are_independent_and_start_empty():
    distance, calls = capped(ObstacleMap(10.0, 8.0), 4.0)
    certs = ClearanceCertificates(distance, 2)
    assert certs.clear(0, 5.0, 4.0, 1.0) and len(calls) == 1       # border 4 m away
    assert certs.clear(0, 5.5, 4.0, 1.0) and len(calls) == 1       # within the certificate
    assert not certs.clear(1, 0.5, 4.0, 1.0) and len(calls) == 2   # own, fresh measurement
    assert not certs.clear(0, 5.0, 4.0, 4.0)                       # reach beyond the clearance


def test_bad_slots():
    with pytest.raises(ValueError, match="slots"):
        ClearanceCertificates(lambda x, y: 0.0, -1)
