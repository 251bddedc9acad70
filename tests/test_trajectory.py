import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env.trajectory import beacons_along, path_length


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
    assert len(whole) == int(np.floor(path_length(xy) / interval + 1e-9))
    # consecutive beacons are never farther apart along the path than the interval
    if len(whole) > 1:
        assert np.all(np.linalg.norm(np.diff(whole[:, 1:], axis=0), axis=1) <= interval + 1e-7)
