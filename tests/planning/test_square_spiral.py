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
    assert s_max == pytest.approx(math.sqrt(23**2 - 1.5**2) - 1.5)     # the corner's bound
    assert s_max < math.sqrt(25**2 - 2**2) - 1.5                       # below the passes'
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


def test_max_spacing_by_hand():
    """sqrt((R - Δs)^2 - margin^2) - margin, the bound of the corner where the spiral stops:
    25 and 7 m give exactly 18 m (no margin by default; the passes' bound sqrt(R^2 - Δs^2)
    would give 24 m), 8, 3 and a 3 m margin sqrt(25 - 9) - 3 = 1 m."""
    assert max_spacing(25.0, 7.0) == 18.0
    assert max_spacing(8.0, 3.0, 3.0) == 1.0
    assert max_spacing(5.0, 3.0) == 2.0
    with pytest.raises(ValueError, match="margin=4.0 m leaves no valid spacing"):
        max_spacing(8.0, 3.0, 4.0)


def test_default_spacing_by_hand():
    """h / ceil(h / s_max) with h the farthest clipped border from the origin: centred on a
    100 m field with R = 25, Δs = 7 (s_max = 18), h = 50, 3 rings of 50/3 m; off centre at
    x = 20 with a 1.5 m margin, h = 78.5 and s_max = sqrt(18^2 - 1.5^2) - 1.5 = 16.44: 5 rings
    of 15.7 m."""
    assert default_spacing(100.0, 100.0, 25.0, 7.0) == pytest.approx(50 / 3)
    assert default_spacing(100.0, 100.0, 25.0, 7.0, 1.5, (20.0, 50.0)) == pytest.approx(15.7)
    assert default_spacing(100.0, 100.0, 25.0, 7.0, 1.5, (50.0, 80.0)) == pytest.approx(15.7)
    # wide: the most rings at s_max or more, at least one
    assert default_spacing(100.0, 100.0, 25.0, 7.0, wide=True) == pytest.approx(25.0)
    assert default_spacing(100.0, 100.0, 25.0, 7.0, 1.5, (20.0, 50.0), wide=True) == \
        pytest.approx(78.5 / 4)
    assert default_spacing(30.0, 30.0, 25.0, 7.0, wide=True) == pytest.approx(15.0)


def test_config_spacing_is_the_configs_or_the_fitted_one():
    """A config's spiral_spacing when set, else the fitted (not wide) spacing of its radio
    range, beacon interval and edge margin: 48.5 / ceil(48.5 / (sqrt(23^2 - 1.5^2) - 1.5))."""
    from aoass_env.config import AOASSConfig
    from aoass_env.planning.square_spiral import config_spacing

    config = AOASSConfig(radio_range=25.0, beacon_interval=2.0, edge_margin=1.5)
    fitted = 48.5 / math.ceil(48.5 / (math.sqrt(23**2 - 1.5**2) - 1.5))
    assert config_spacing(config, 100.0, 100.0) == pytest.approx(fitted)
    assert config_spacing(config, 100.0, 100.0, wide=True) == pytest.approx(48.5 / 2)
    fixed = AOASSConfig(radio_range=25.0, beacon_interval=2.0, edge_margin=1.5,
                        spiral_spacing=10.0)
    assert config_spacing(fixed, 100.0, 100.0) == 10.0


def test_legs_corners_and_default_margin():
    """The origin is leg 0 and every later waypoint carries its leg's 1-based index (legs
    numbered in path order); the corners end with the last waypoint; without a margin the
    spiral reaches the field's edges."""
    sp = square_spiral(100.0, 100.0, 10.0, 2.0)
    assert sp.leg[0] == 0 and sp.leg[1] == 1
    assert np.all(np.diff(sp.leg) >= 0) and set(np.diff(sp.leg)) <= {0, 1}
    corners = sp.corners()
    np.testing.assert_array_equal(corners[0], sp.waypoints[0])
    np.testing.assert_array_equal(corners[-1], sp.waypoints[-1])
    assert len(corners) == sp.leg[-1] + 1
    assert sp.waypoints.min() == 0.0 and sp.waypoints.max() == 100.0
    # arc length: 0 at the origin, then the summed distances between waypoints
    gaps = np.linalg.norm(np.diff(sp.waypoints, axis=0), axis=1)
    np.testing.assert_allclose(sp.arc_length, np.r_[0.0, np.cumsum(gaps)], rtol=0, atol=1e-9)


@pytest.mark.parametrize(("width", "height", "origin", "radio_range", "margin"), [
    (100.0, 100.0, None, 25.0, 1.5),
    # corners one ulp short of a clipped border: its pass did not count and the spiral ran a
    # whole extra ring (940 m instead of 592 m; 980 instead of 784; 5 516 instead of 5 122)
    (100.0, 80.0, (30.0, 40.0), 25.0, 1.5), (100.0, 100.0, None, 25.0, 1.0),
    (200.0, 200.0, None, 10.0, 1.5), (80.0, 100.0, None, 25.0, 1.5),
    (100.0, 100.0, (20.0, 50.0), 25.0, 1.5),
    (200.0, 200.0, None, 25.0, 1.5), (60.0, 100.0, (10.0, 90.0), 25.0, 1.5)])
def test_the_spiral_stops_once_all_four_borders_are_run_along(width, height, origin,
                                                              radio_range, margin):
    """Complete once the path has run along all four clipped borders: the last leg is the
    first along the fourth border (one more leg would repeat a border pass)."""
    s = default_spacing(width, height, radio_range, 2.0, margin, origin)
    sp = square_spiral(width, height, s, 2.0, margin=margin, origin=origin)
    lo, hi = np.array([margin, margin]), np.array([width - margin, height - margin])
    corners = sp.corners()
    borders = []            # the borders each leg runs along
    for a, b in zip(corners[:-1], corners[1:], strict=True):
        axis = 0 if a[0] == b[0] else 1             # the leg's constant coordinate
        on = set()
        if math.isclose(a[axis], lo[axis]):
            on.add((axis, "lo"))
        if math.isclose(a[axis], hi[axis]):
            on.add((axis, "hi"))
        borders.append(on)
    assert len(set().union(*borders)) == 4
    assert len(set().union(*borders[:-1])) == 3
    # a corner on a border sits on it exactly (the snap; no ulp short of it)
    for c in corners:
        for k in (0, 1):
            assert not 0 < abs(c[k] - lo[k]) <= 1e-6 and not 0 < abs(c[k] - hi[k]) <= 1e-6


def test_a_field_of_whole_rings_at_max_spacing_gets_max_spacing():
    """h = 36 m from the centre of a 72 m field and s_max = 25 - 7 = 18 m: exactly 2 rings of
    18 m, fitted or wide (not 3 rings of 12 m, nor 1 of 36 m)."""
    assert default_spacing(72.0, 72.0, 25.0, 7.0) == 18.0
    assert default_spacing(72.0, 72.0, 25.0, 7.0, wide=True) == 18.0
