import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env import trajectory
from aoass_env.trajectory import beacons_along


def test_beacons_at_exact_distances_and_times():
    p = np.array([[0, 0, 0], [1, 1.5, 0], [2, 1.5, 0], [3, 1.5, 2.5]], float)
    b, end = beacons_along(p, 0.5, 1.0)
    assert end == pytest.approx(4.5)
    np.testing.assert_allclose(b, [[1 / 3, 0.5, 0], [1.0, 1.5, 0], [2.4, 1.5, 1.0],
                                   [2.8, 1.5, 2.0]])


def test_rejects_bad_interval():
    with pytest.raises(ValueError, match="interval"):
        beacons_along(np.zeros((2, 3)), 0.0, 0.0)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(-50, 50), st.floats(-50, 50)), min_size=2, max_size=12),
       st.integers(1, 5), st.floats(0.3, 5.0))
def test_split_path_gives_same_beacons_as_whole(points, cut, interval):
    """Feeding the path piece by piece (as the simulator does) changes nothing."""
    xy = np.array(points)
    path = np.c_[np.arange(len(xy), dtype=float), xy]
    whole, end = beacons_along(path, 0.0, interval)
    cut = min(cut, len(xy) - 1)
    a, mid = beacons_along(path[:cut + 1], 0.0, interval)
    b, end2 = beacons_along(path[cut:], mid, interval)
    assert end2 == pytest.approx(end)
    np.testing.assert_allclose(np.r_[a, b], whole, atol=1e-7)
    length = np.linalg.norm(np.diff(xy, axis=0), axis=1).sum()
    assert len(whole) == int(np.floor(length / interval + 1e-9))
    # consecutive beacons are never farther apart along the path than the interval
    if len(whole) > 1:
        assert np.all(np.linalg.norm(np.diff(whole[:, 1:], axis=0), axis=1) <= interval + 1e-7)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.floats(-50, 50), st.floats(-50, 50)), min_size=1, max_size=12),
       st.floats(0.0, 30.0), st.floats(0.3, 5.0))
def test_fast_paths_match_numpy(points, start, interval):
    """beacons_along's plain-float short-path exit changes no bit."""
    xy = np.array(points)
    seg = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    path = np.c_[np.arange(len(xy), dtype=float), xy]
    fast, fast_end = beacons_along(path, start, interval)
    long = np.repeat(path, 70 // len(path) + 1, axis=0)      # beyond the short-path limit
    slow, slow_end = beacons_along(long, start, interval)     # repeated samples: same path
    assert fast_end == slow_end == start + float(np.r_[0.0, np.cumsum(seg)][-1])
    np.testing.assert_array_equal(fast, slow)


COORD = st.one_of(st.integers(-6, 6).map(float), st.floats(-50, 50))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(COORD, COORD), min_size=1, max_size=12),
       st.one_of(st.integers(0, 9).map(float), st.floats(0.0, 30.0)),
       st.one_of(st.sampled_from([0.5, 1.0, 2.0]), st.floats(0.3, 5.0)))
def test_short_path_beacons_are_numpys_bit_for_bit(points, start, interval):
    """The plain-float beacons of a short path (whole-metre points and intervals put marks on
    samples and repeat points) against the NumPy code on the same path."""
    xy = np.array(points)
    path = np.c_[np.arange(len(xy), dtype=float) * 0.1, xy]
    fast, fast_end = beacons_along(path, start, interval)
    with pytest.MonkeyPatch.context() as m:
        m.setattr(trajectory, "_SHORT_PATH", 0)
        slow, slow_end = beacons_along(path, start, interval)
    assert fast_end == slow_end and fast.shape == slow.shape and fast.dtype == slow.dtype
    assert fast.tobytes() == slow.tobytes()


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(COORD, COORD), min_size=1, max_size=12),
       st.one_of(st.integers(0, 9).map(float), st.floats(0.0, 30.0)),
       st.one_of(st.sampled_from([0.5, 1.0, 2.0]), st.floats(0.3, 5.0)),
       st.booleans())
def test_beacons_of_rows_are_beacons_along_bit_for_bit(points, start, interval, long):
    """The simulator's rows of plain floats give beacons_along's beacons and odometer float,
    on short paths (with no mark passed: the shared empty array) and, with the short-path
    bound at 0, through the array code."""
    rows = [(0.1 * k, x, y) for k, (x, y) in enumerate(points)]
    with pytest.MonkeyPatch.context() as m:
        if long:
            m.setattr(trajectory, "_SHORT_PATH", 0)
        got, got_end = trajectory.beacons_of_rows(rows, start, interval)
        want, want_end = beacons_along(np.array(rows), start, interval)
    assert got_end == want_end and got.shape == want.shape and got.dtype == want.dtype
    assert got.tobytes() == want.tobytes()
    if not len(got) and not long:
        assert got is trajectory.NO_BEACONS and not got.flags.writeable


@pytest.mark.parametrize("interval", [0.0, -1.0, math.nan])
def test_beacons_of_rows_refuse_a_bad_interval_in_one_line(interval):
    rows = [(0.0, 0.0, 0.0), (0.1, 3.0, 0.0)]
    with pytest.raises(ValueError, match="^interval=") as refused:
        trajectory.beacons_of_rows(rows, 0.0, interval)
    assert "\n" not in str(refused.value)


@pytest.mark.parametrize("path, start, message", [
    # a (3, 2) x-y path used to be reshaped to (2, 3) rows: 4 beacons off the path
    ([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]], 0.0, r"path must be an array of shape \(n, 3\)"),
    ([[0.0, 0.0, 0.0], [1.0, np.nan, 0.0]], 0.0, "path must be finite"),
    ([[0.0, 0.0, 0.0], [1.0, 1.0, 0.0]], float("nan"), "start_distance=nan must be a number"),
    ([[0.0, 0.0, 0.0], [1.0, 1.0, 0.0]], float("inf"), "start_distance=inf must be a number"),
])
def test_beacons_along_names_a_bad_path_or_odometer(path, start, message):
    with pytest.raises(ValueError, match=message):
        beacons_along(np.array(path), start, 0.5)
