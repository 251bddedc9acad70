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


def test_a_certificate_keeps_the_margin():
    """A wall along x = 5 (clearance 5 - x). After a certificate at the origin (clearance 5),
    a query 1 m wide centred just short of 4 m out has a true clearance of only 0.5 * MARGIN
    beyond its reach: it is not clear, reused certificate or not."""
    calls = []

    def distance(x: float, y: float) -> float:
        calls.append((x, y))
        return 5.0 - x

    certs = ClearanceCertificates(distance, 1)
    assert certs.clear(0, 0.0, 0.0, 1.0)
    x = 4.0 - 0.5 * MARGIN
    assert 5.0 - x - 1.0 <= MARGIN                    # the query's true slack
    assert not certs.clear(0, x, 0.0, 1.0)
    assert len(calls) == 2                            # it had to be measured anew
    # with a freshly measured clearance the margin holds too
    assert not ClearanceCertificates(distance, 1).clear(0, x, 0.0, 1.0)
    # and a query 2 * MARGIN further in is clear from the first certificate alone
    fresh = ClearanceCertificates(distance, 1)
    assert fresh.clear(0, 0.0, 0.0, 1.0)
    assert fresh.clear(0, 4.0 - 3 * MARGIN, 0.0, 1.0) and len(calls) == 4


def test_no_slots_is_allowed():
    """A world without tracked bodies keeps no certificate (slots=0 is valid)."""
    ClearanceCertificates(lambda x, y: 0.0, 0)


@pytest.mark.parametrize(("reach", "dx", "dy"), [
    (1.0, 0.0, 4.2), (1.0, 4.2, 0.0), (1.0, 2.97, 2.97), (1.0, -2.97, -2.97),
    (4.5, 0.8, 0.0), (4.5, 0.0, -0.8)])
def test_a_certificate_does_not_reach_beyond_its_radius_in_any_direction(reach, dx, dy):
    """Inside a ring of radius 5 m around the origin (clearance 5 - |p|): the origin's
    certificate covers moves up to 5 - reach - MARGIN. A query moved further, in any direction
    (1 m reach 4.2 m off centre, 4.5 m reach 0.8 m off), reaches within 0.3 m of the ring: not
    provably clear, so it is measured anew (and found too close)."""
    calls = []

    def distance(x: float, y: float) -> float:
        calls.append((x, y))
        return 5.0 - math.hypot(x, y)

    certs = ClearanceCertificates(distance, 1)
    assert certs.clear(0, 0.0, 0.0, reach)
    assert not certs.clear(0, dx, dy, reach)
    assert len(calls) == 2


def test_a_certificate_with_little_room_is_still_reused():
    """Clearance 5 m, reach 4.5 m: the certificate covers moves up to 0.5 m - MARGIN, and a
    0.1 m move is answered from it without a new measurement."""
    calls = []

    def distance(x: float, y: float) -> float:
        calls.append((x, y))
        return 5.0

    certs = ClearanceCertificates(distance, 1)
    assert certs.clear(0, 0.0, 0.0, 4.5)
    assert certs.clear(0, 0.1, 0.0, 4.5) and certs.clear(0, 0.0, -0.1, 4.5)
    assert len(calls) == 1


def test_a_fresh_measurement_with_under_a_metre_to_spare_is_clear():
    """Measured clearance 1.5 m, reach 1 m: 0.5 m to spare, far above MARGIN: clear."""
    assert ClearanceCertificates(lambda x, y: 1.5, 1).clear(0, 3.0, 4.0, 1.0)
    assert not ClearanceCertificates(lambda x, y: 1.5, 1).clear(0, 3.0, 4.0, 1.5)
    # exactly MARGIN to spare is not "more than MARGIN away"
    assert not ClearanceCertificates(lambda x, y: MARGIN, 1).clear(0, 3.0, 4.0, 0.0)
