import math

import numpy as np
import pytest

from aoass_env.maps import ObstacleMap
from aoass_env.planning.square_spiral import (
    default_spacing,
    max_spacing,
    square_spiral,
)


def test_legs_follow_eq1_eq2_unclipped():
    """Leg j has length (j//2 + 1)*s along right, up, left, down (Eq. 1-2)."""
    sp = square_spiral(1000, 1000, 10.0, 2.5, margin=0.0)
    corners = sp.corners()[:13]
    legs = np.diff(corners, axis=0)
    dirs = np.array([[1, 0], [0, 1], [-1, 0], [0, -1]])
    for j, leg in enumerate(legs):
        expected = (j // 2 + 1) * 10.0 * dirs[j % 4]
        np.testing.assert_allclose(leg, expected, atol=1e-9)
    np.testing.assert_allclose(sp.waypoints[0], [500, 500])


def test_waypoints_every_step_and_corners_exact():
    sp = square_spiral(100, 100, 7.0, 3.0, margin=1.0)
    gaps = np.linalg.norm(np.diff(sp.waypoints, axis=0), axis=1)
    assert gaps.max() <= 3.0 + 1e-9 and gaps.min() > 0
    # every waypoint lies on an axis-parallel segment from the previous one
    d = np.diff(sp.waypoints, axis=0)
    assert np.all((np.abs(d[:, 0]) < 1e-9) | (np.abs(d[:, 1]) < 1e-9))
    assert sp.length == pytest.approx(gaps.sum())


def test_clipped_spiral_stays_inside_and_runs_along_all_borders():
    sp = square_spiral(100, 80, 12.0, 2.0, margin=1.5, origin=(30.0, 40.0))
    w = sp.waypoints
    assert w[:, 0].min() == pytest.approx(1.5) and w[:, 0].max() == pytest.approx(98.5)
    assert w[:, 1].min() == pytest.approx(1.5) and w[:, 1].max() == pytest.approx(78.5)


def test_passes_are_spacing_apart():
    s = default_spacing(100, 100, 25.0, 2.0, 1.5)
    sp = square_spiral(100, 100, s, 2.0, margin=1.5)
    ys = np.unique(np.round(sp.corners()[:, 1], 9))
    np.testing.assert_allclose(np.diff(ys), s, rtol=1e-9)


@pytest.mark.parametrize("origin", [(20.0, 50.0), (50.0, 20.0), (10.0, 10.0), (90.0, 75.0)])
def test_an_off_centre_spiral_keeps_its_passes_spacing_apart(origin):
    # legs clipped at the near border used to shift every later pass toward it: gaps of 36-39 m
    # at a spacing of 20-22 m by the far border, and parts of an empty field unheard
    s = default_spacing(100, 100, 25.0, 2.0, 1.5, origin)
    corners = square_spiral(100, 100, s, 2.0, margin=1.5, origin=origin).corners()
    for axis in (0, 1):
        passes = np.unique(np.round(corners[:, axis], 9))
        assert passes[0] == pytest.approx(1.5) and passes[-1] == pytest.approx(98.5)
        assert np.diff(passes).max() <= s * (1 + 1e-9)
        # every pass off the borders lies on the origin's lattice, x0 + k s
        inner = passes[(passes > 1.5 + 1e-9) & (passes < 98.5 - 1e-9)]
        k = (inner - origin[axis]) / s
        np.testing.assert_allclose(k, np.round(k), atol=1e-9)


def test_default_spacing_derivation():
    s_max = max_spacing(25.0, 2.0, 1.5)
    assert s_max == pytest.approx(math.sqrt(25**2 - 2**2) - 1.5)
    s100 = default_spacing(100, 100, 25.0, 2.0, 1.5)
    assert s100 <= s_max and s100 == pytest.approx(48.5 / 3)
    assert default_spacing(200, 200, 25.0, 2.0, 1.5) == pytest.approx(98.5 / 5)
    with pytest.raises(ValueError, match="beacon_interval"):
        max_spacing(2.0, 3.0)


def test_nominal_time_and_blocked_marks():
    sp = square_spiral(100, 100, 16.0, 2.0, margin=1.5)
    assert sp.nominal_time(2.0) == pytest.approx(sp.length / 2.0)
    with pytest.raises(ValueError, match="speed"):
        sp.nominal_time(0.0)
    box = ObstacleMap(100, 100, [[(60, 45), (70, 45), (70, 55), (60, 55)]])
    marked = sp.with_obstacles(box, anchor_radius=0.5)
    inside = ((sp.waypoints[:, 0] >= 59.5) & (sp.waypoints[:, 0] <= 70.5)
              & (sp.waypoints[:, 1] >= 44.5) & (sp.waypoints[:, 1] <= 55.5))
    np.testing.assert_array_equal(marked.blocked, inside)
    assert inside.any()


@pytest.mark.parametrize("kw,fragment", [
    (dict(width=-1, height=10, spacing=1, step=1), "width"),
    (dict(width=10, height=10, spacing=0, step=1), "spacing"),
    (dict(width=10, height=10, spacing=1, step=1, origin=(20, 5)), "origin"),
    (dict(width=10, height=10, spacing=1, step=1, margin=6), "margin"),
])
def test_bad_arguments(kw, fragment):
    with pytest.raises(ValueError, match=fragment):
        square_spiral(**kw)


@pytest.mark.parametrize("kwargs, message", [
    ({"margin": -5.0}, r"margin=-5.0 must be a number in \[0.0, inf\) m"),
    ({"margin": math.nan}, r"margin=nan must be a number"),
    ({"margin": "1"}, r"margin='1' must be a number"),
    ({"origin": (math.nan, 50.0)}, r"origin must be a pair of finite numbers"),
    ({"origin": (1.0, 2.0, 3.0)}, r"origin must be a pair of finite numbers"),
    ({"max_legs": 2.5}, r"max_legs=2.5 must be an integer in \[1, inf\)"),
])
def test_a_spiral_names_a_bad_margin_origin_or_leg_limit(kwargs, message):
    """A negative margin used to put waypoints outside the field; a NaN one or a NaN origin
    ran 100 000 legs before "did not close"; others failed deep in numpy."""
    with pytest.raises(ValueError, match=message):
        square_spiral(100.0, 100.0, 20.0, 2.0, **kwargs)


def test_spacing_functions_name_a_bad_argument():
    with pytest.raises(ValueError, match=r"beacon_interval=nan must be a number"):
        max_spacing(25.0, math.nan)
    with pytest.raises(ValueError, match=r"radio_range=-25.0 must be a number"):
        max_spacing(-25.0, -30.0)
    with pytest.raises(ValueError, match=r"origin must be a pair of finite numbers"):
        default_spacing(100.0, 100.0, 25.0, 2.0, origin=(math.nan, 0.0))
    with pytest.raises(ValueError, match=r"width=0.0 must be a number"):
        default_spacing(0.0, 100.0, 25.0, 2.0)
