import math

import numpy as np
import pytest

from aoass_env.maps import ObstacleMap
from aoass_env.planning.detour import DetourPlanner
from aoass_env.planning.follower import KEEPOUT_RADIUS, WaypointFollower


def _follower(blocked):
    wps = np.array([[0.0, 0.0], [5.0, 0.0], [10.0, 0.0], [10.0, 5.0]])
    return WaypointFollower(wps, np.array(blocked), capture_radius=0.5, cruise_speed=1.0,
                            stall_time=10.0)


def test_heads_to_next_waypoint_and_advances():
    f = _follower([False, False, False, False])
    v, h = f.command(np.array([0.0, 0.0]), 0.0, 0.5)  # origin reached at once
    assert f.index == 1 and v == 1.0 and h == 0.0
    f.command(np.array([4.8, 0.0]), 0.0, 0.5)
    assert f.index == 2


def test_skips_blocked_waypoints_and_resumes():
    f = _follower([False, True, True, False])
    _, h = f.command(np.array([0.0, 0.0]), 0.0, 0.5)
    assert f.index == 3
    assert math.isclose(h, math.atan2(5, 10))


def test_stall_skips_target_and_done_stops():
    f = _follower([False, False, False, False])
    f.command(np.array([0.0, 0.0]), 0.0, 0.5)
    f.command(np.array([0.0, 1.0]), 0.0, 11.0)   # stuck longer than stall_time
    assert f.index == 2
    f.index = 3
    v, _ = f.command(np.array([10.0, 5.0]), 0.0, 0.5)
    assert f.done and v == 0.0 and f.progress() == 1.0


def test_brakes_before_a_sharp_turn_but_not_on_a_straight():
    wps = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [20.0, 10.0]])
    f = WaypointFollower(wps, np.zeros(4, bool), capture_radius=0.5, cruise_speed=1.0,
                         max_accel=1.0)
    f.command(np.array([0.0, 0.0]), 0.0, 0.5)
    v_far, _ = f.command(np.array([2.0, 0.0]), 0.0, 0.5)
    v_near, _ = f.command(np.array([9.2, 0.0]), 0.0, 0.5)   # 0.3 m of braking room left
    assert v_far == 1.0
    assert v_near == pytest.approx(math.sqrt(2 * 1.0 * 0.3))
    straight = WaypointFollower(np.array([[0.0, 0], [10, 0], [20, 0]]), np.zeros(3, bool),
                                capture_radius=0.5, cruise_speed=1.0, max_accel=1.0)
    straight.command(np.array([0.0, 0.0]), 0.0, 0.5)
    assert straight.command(np.array([9.2, 0.0]), 0.0, 0.5)[0] == 1.0


def test_turns_in_place_when_facing_away():
    f = _follower([False, False, False, False])
    v, h = f.command(np.array([0.0, 0.0]), math.pi, 0.5)
    assert v == 0.0 and h == 0.0


def test_detours_around_an_obstacle_between_waypoints():
    wall = ObstacleMap(40, 40, [[(18, 5), (22, 5), (22, 35), (18, 35)]])
    planner = DetourPlanner(wall, radius=0.8)
    wps = np.array([[10.0, 20.0], [30.0, 20.0]])
    f = WaypointFollower(wps, np.zeros(2, bool), capture_radius=0.5, cruise_speed=1.0,
                         planner=planner)
    f.command(np.array([10.0, 20.0]), 0.0, 0.5)
    _, heading = f.command(np.array([10.0, 20.0]), 0.0, 0.5)
    assert f._detour, "an obstructed target gets a detour"
    assert abs(math.sin(heading)) > 0.5          # heads for an end of the wall, not through it


# --- progress watchdog and recovery -----------------------------------------------------------
def _watched(planner=None, **kw):
    wps = np.array([[0.0, 0.0], [20.0, 0.0], [20.0, 10.0]])
    return WaypointFollower(wps, np.zeros(3, dtype=bool), capture_radius=0.5, cruise_speed=1.0,
                            stall_time=1000.0, planner=planner, watchdog_time=8.0,
                            watchdog_progress=1.0, backout_distance=3.0, **kw)


def _drive_to(f, x, dt=0.5):
    """Feed the follower positions along y = 0 from its last x to ``x``, 0.5 m per call."""
    for px in np.arange(0.0, x + 1e-9, 0.5):
        f.command(np.array([px, 0.0]), 0.0, dt)


def _wait(f, position, heading=0.0, calls=40, until=lambda f: False):
    """Feed the follower the same position (it makes no progress); the calls made."""
    for k in range(1, calls + 1):
        f.command(np.asarray(position, dtype=float), heading, 0.5)
        if until(f):
            return k
    return calls


def test_watchdog_backs_out_along_the_track_when_progress_stops():
    f = _watched()
    _drive_to(f, 10.0)
    calls = _wait(f, [10.0, 0.0], until=lambda f: f.recoveries > 0)
    # fires watchdog_time (8 s) after the last metre of progress (at x = 9.5 m, 0.5 s before)
    assert 7.5 <= 0.5 * calls <= 8.5
    assert f.recoveries == 1 and f.index == 1 and not f.skipped
    _, heading = f.command(np.array([10.0, 0.0]), 0.0, 0.5)
    assert math.isclose(abs(heading), math.pi)          # back the way it came
    # the back-out ends 3 m back; then the target is steered to again
    f.command(np.array([7.0, 0.0]), math.pi, 0.5)
    _, heading = f.command(np.array([7.0, 0.0]), math.pi, 0.5)
    assert heading == 0.0 and f.index == 1


def test_slow_but_steady_progress_does_not_fire_the_watchdog():
    f = _watched()
    for px in np.arange(0.0, 19.0, 0.1):     # 0.2 m/s: 1 m every 5 s
        f.command(np.array([px, 0.0]), 0.0, 0.5)
    assert f.recoveries == 0 and f.index == 1


def test_a_target_that_stays_out_of_reach_is_given_up_after_the_tries():
    f = _watched()
    _drive_to(f, 10.0)
    for tries in range(2):                   # two back-outs, each followed by a new try
        _wait(f, [10.0, 0.0], until=lambda f, tries=tries: f.recoveries > tries)
        assert f.index == 1 and not f.skipped
        _drive_to(f, 10.0)
    _wait(f, [10.0, 0.0], until=lambda f: f.index == 2)
    assert f.index == 2 and f.recoveries == 3
    assert [(s.index, s.reason) for s in f.skipped] == [(1, "stuck")]


def test_stuck_beside_the_target_gives_it_up_without_backing_out():
    f = _watched()
    _drive_to(f, 19.0)
    _wait(f, [19.0, 0.0], until=lambda f: f.index == 2)
    assert [(s.index, s.reason) for s in f.skipped] == [(1, "stuck")]
    assert f.recoveries == 0 and f.index == 2


def test_no_watchdog_by_default():
    wps = np.array([[0.0, 0.0], [20.0, 0.0]])
    f = WaypointFollower(wps, np.zeros(2, dtype=bool), capture_radius=0.5, cruise_speed=1.0,
                         stall_time=1000.0)
    _wait(f, [5.0, 0.0], calls=200)
    assert f.recoveries == 0 and not f.skipped and f.index == 0


def test_replan_after_backing_out_goes_round_the_stuck_spot():
    # a wall across the field at x = 10 with two gaps: y 9-11 (straight ahead), y 19-21
    wall = (np.array([[9.5, 0.0], [10.5, 0.0], [10.5, 9.0], [9.5, 9.0]]),
            np.array([[9.5, 11.0], [10.5, 11.0], [10.5, 19.0], [9.5, 19.0]]),
            np.array([[9.5, 21.0], [10.5, 21.0], [10.5, 40.0], [9.5, 40.0]]))
    planner = DetourPlanner(ObstacleMap(40.0, 40.0, wall), 0.6)
    wps = np.array([[2.0, 10.0], [18.0, 10.0]])
    f = WaypointFollower(wps, np.zeros(2, dtype=bool), capture_radius=0.5, cruise_speed=1.0,
                         stall_time=1000.0, planner=planner, watchdog_time=8.0)
    for px in np.arange(2.0, 9.01, 0.5):     # straight at the near gap; held at its mouth
        f.command(np.array([px, 10.0]), 0.0, 0.5)
    assert not f._detour
    _wait(f, [9.0, 10.0], until=lambda f: f.recoveries > 0)
    for px in np.arange(9.0, 5.99, -0.5):                # backs out 3 m along its track
        f.command(np.array([px, 10.0]), math.pi, 0.5)
    assert f._detour, "the re-plan detours round the keep-out"
    assert max(p[1] for p in f._detour) > 18.0           # through the far gap
    assert all(np.hypot(*(p - [9.0, 10.0])) > 1.5 for p in f._detour)
    # a passage reached only through a keep-out is still planned (keep-outs are soft)
    assert planner.path(np.array([6.0, 10.0]), np.array([18.0, 10.0]),
                        np.array([[10.0, 20.0], [10.0, 10.0]]), 1.5) is not None


def _two_gaps(**kw):
    """The wall of the test above (gaps at y 9-11 and y 19-21), a follower stuck at the near
    gap's mouth (9, 10) and backed out to (6, 10); the planner, the follower and its re-plan's
    keep-out path and plain path (6, 10) -> (18, 10)."""
    wall = (np.array([[9.5, 0.0], [10.5, 0.0], [10.5, 9.0], [9.5, 9.0]]),
            np.array([[9.5, 11.0], [10.5, 11.0], [10.5, 19.0], [9.5, 19.0]]),
            np.array([[9.5, 21.0], [10.5, 21.0], [10.5, 40.0], [9.5, 40.0]]))
    planner = DetourPlanner(ObstacleMap(40.0, 40.0, wall), 0.6)
    wps = np.array([[2.0, 10.0], [18.0, 10.0], [18.0, 30.0]])
    f = WaypointFollower(wps, np.zeros(3, dtype=bool), capture_radius=0.5, cruise_speed=1.0,
                         stall_time=1000.0, planner=planner, watchdog_time=8.0, **kw)
    for px in np.arange(2.0, 9.01, 0.5):
        f.command(np.array([px, 10.0]), 0.0, 0.5)
    _wait(f, [9.0, 10.0], until=lambda f: f.recoveries > 0)
    for px in np.arange(9.0, 6.49, -0.5):
        f.command(np.array([px, 10.0]), math.pi, 0.5)
    start, goal = np.array([6.0, 10.0]), wps[1]
    keep = planner.path(start, goal, np.array([[9.0, 10.0]]), KEEPOUT_RADIUS)
    plain = planner.path(start, goal)
    return f, keep, plain


def _length(path):
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())


def test_a_replan_round_the_keepout_much_longer_than_the_plain_way_gives_the_target_up():
    f, keep, plain = _two_gaps(replan_excess=5.0)
    assert 5.0 < _length(keep) - _length(plain) < 20.0    # about 12 m round by the far gap
    f.command(np.array([6.0, 10.0]), math.pi, 0.5)        # back-out ends: re-plan
    assert [(s.index, s.reason) for s in f.skipped] == [(1, "long re-plan")]
    assert f.index == 2 and not f._backout


def test_a_target_not_stuck_on_takes_the_plain_way_past_an_earlier_targets_keepout():
    f, _, plain = _two_gaps(replan_excess=5.0)
    g = WaypointFollower(f.waypoints, f.blocked, capture_radius=0.5, cruise_speed=1.0,
                         stall_time=1000.0, planner=f.planner, watchdog_time=8.0,
                         replan_excess=5.0, index=1)
    g._keepout.append((np.array([9.0, 10.0]), 60.0))      # left by an earlier target
    g.command(np.array([6.0, 10.0]), 0.0, 0.5)
    assert not g.skipped and g.index == 1
    assert np.array_equal(np.array(g._detour).reshape(-1, 2), plain[1:-1].reshape(-1, 2))


def test_a_replan_within_the_excess_is_taken():
    f, keep, plain = _two_gaps(replan_excess=20.0)
    f.command(np.array([6.0, 10.0]), math.pi, 0.5)
    assert not f.skipped and f.index == 1
    assert max(p[1] for p in f._detour) > 18.0             # through the far gap
    # without the cap (the default) the same
    g, _, _ = _two_gaps()
    g.command(np.array([6.0, 10.0]), math.pi, 0.5)
    assert g.replan_excess == math.inf and not g.skipped
    assert np.array_equal(np.array(g._detour), np.array(f._detour))


def _room_planner():
    """A 4 m room (x 20.5-24.5, y 18-22) whose doorway (y 19.5-20.5 in its west wall) is too
    narrow for the planner's disc: its inside is a pocket of the planner's grid, cut off from
    the field."""
    walls = (np.array([[20.0, 17.5], [20.5, 17.5], [20.5, 19.5], [20.0, 19.5]]),
             np.array([[20.0, 20.5], [20.5, 20.5], [20.5, 22.5], [20.0, 22.5]]),
             np.array([[24.5, 17.5], [25.0, 17.5], [25.0, 22.5], [24.5, 22.5]]),
             np.array([[20.0, 17.5], [25.0, 17.5], [25.0, 18.0], [20.0, 18.0]]),
             np.array([[20.0, 22.0], [25.0, 22.0], [25.0, 22.5], [20.0, 22.5]]))
    return DetourPlanner(ObstacleMap(40.0, 40.0, walls), 0.6)


def test_shut_in_a_pocket_it_backs_out_to_the_field_instead_of_giving_up_every_target():
    # the anchor was pushed through the doorway (as an escape from a moving obstacle can): from
    # inside the room the planner reaches no target, but the targets are not to blame
    planner = _room_planner()
    wps = np.array([[30.0, 35.0], [5.0, 35.0], [35.0, 5.0]])
    f = WaypointFollower(wps, np.zeros(3, dtype=bool), capture_radius=0.5, cruise_speed=1.0,
                         stall_time=1000.0, planner=planner, watchdog_time=8.0)
    f._trail.extend(np.array([x, 20.0]) for x in np.arange(10.0, 22.01, 0.5))
    inside = np.array([22.0, 20.0])
    assert planner.path(inside, wps[0]) is None and not planner.can_start(inside, 0.0)
    _, heading = f.command(inside, 0.0, 0.5)
    assert not f.skipped and f.index == 0 and f.recoveries == 1
    assert math.isclose(abs(heading), math.pi)          # back out the way it came in
    # back to the first point of the track in the field (x = 20) and backout_distance on
    for px in np.arange(22.0, 17.49, -0.5):
        f.command(np.array([px, 20.0]), math.pi, 0.5)
    assert not f._backout and not f.skipped and f.index == 0
    assert f._planned and f._detour, "planned afresh from the field"


def test_a_target_shut_in_a_pocket_is_given_up_from_the_field():
    planner = _room_planner()
    wps = np.array([[10.0, 20.0], [22.5, 20.0], [10.0, 30.0]])
    f = WaypointFollower(wps, np.zeros(3, dtype=bool), capture_radius=0.5, cruise_speed=1.0,
                         stall_time=1000.0, planner=planner, watchdog_time=8.0)
    f.command(np.array([10.0, 20.0]), 0.0, 0.5)
    assert [(s.index, s.reason) for s in f.skipped] == [(1, "no path")]
    assert f.index == 2 and f.recoveries == 0


def test_shut_in_with_no_way_back_gives_the_target_up_after_the_tries():
    planner = _room_planner()
    wps = np.array([[30.0, 35.0], [5.0, 35.0]])
    f = WaypointFollower(wps, np.zeros(2, dtype=bool), capture_radius=0.5, cruise_speed=1.0,
                         stall_time=1000.0, planner=planner, watchdog_time=8.0)
    f._trail.extend(np.array([x, 20.0]) for x in np.arange(10.0, 22.01, 0.5))
    inside = np.array([22.0, 20.0])
    _wait(f, inside, heading=math.pi, calls=200, until=lambda f: f.index > 0)
    assert [(s.index, s.reason) for s in f.skipped] == [(0, "no path")]
    # two tries for the first target, then the next one backs out too
    assert f.recoveries == 3 and f.index == 1 and f._backout


def test_float_distance_tests_agree_with_numpy():
    """The follower's plain-float distance tests and path lengths give numpy's answers, ties
    and near-ties included (issue 20: same episodes)."""
    from aoass_env.planning.follower import _polyline_length, _reaches, _within

    rng = np.random.default_rng(7)
    for _ in range(20000):
        dx, dy = rng.uniform(-3.0, 3.0, 2)
        h = float(np.hypot(dx, dy))
        r = h * (1.0 + float(rng.choice([0.0, 1e-16, -1e-16, 3e-16, -3e-16, 1e-10, 1e-3])))
        assert _within(dx, dy, r) == bool(np.hypot(dx, dy) <= r)
        assert _reaches(dx, dy, r) == bool(np.hypot(dx, dy) >= r)
    assert _within(0.0, 0.0, 0.0) and _reaches(0.0, 0.0, 0.0)
    for n in (*range(1, 11), 16, 17, 40, 129, 130, 201, 300):
        for _ in range(2000 if n <= 10 else 100):
            pts = list(rng.uniform(-100.0, 100.0, (n, 2)) * rng.choice([1e-6, 1.0, 1e3]))
            assert _polyline_length(pts) == float(
                np.linalg.norm(np.diff(np.array(pts), axis=0), axis=1).sum())


def test_the_pairwise_sum_is_numpys():
    """_pairwise_sum adds floats as np.sum does (8 accumulators, halves past 128), on every
    length up to 300 and on sums that cancel (issue 20: the follower's path lengths)."""
    from aoass_env.planning.follower import PAIRWISE_SUM, _pairwise_sum

    if not PAIRWISE_SUM:
        pytest.skip("NumPy sums differently on this machine: the follower uses np.sum there")
    rng = np.random.default_rng(8)
    for n in range(0, 301):
        for _ in range(10):
            x = rng.normal(0.0, 1.0, n) * 10.0 ** rng.uniform(-8.0, 8.0, n)
            assert _pairwise_sum(x.tolist(), 0, n) == float(x.sum())


@pytest.mark.parametrize("changes, message", [
    ({"waypoints": [[0.0, 0.0], [5.0, 0.0]]}, r"waypoints must be a finite \(W, 2\) array"),
    ({"waypoints": np.array([[0.0, np.nan], [5.0, 0.0]])}, r"waypoints must be a finite"),
    ({"blocked": np.zeros(3, bool)}, r"blocked must be a \(W,\) mask, one flag per waypoint "
                                     r"\(W=2\), got shape \(3,\)"),
    ({"capture_radius": -1.0}, r"capture_radius=-1.0 must be a number in \[0.0, inf\) m"),
    ({"cruise_speed": -1.0}, r"cruise_speed=-1.0 must be a number in \(0.0, inf\) m/s"),
    ({"cruise_speed": math.nan}, r"cruise_speed=nan must be a number"),
    ({"max_accel": -1.0}, r"max_accel=-1.0 must be a number > 0 m/s\^2 \(inf: none\)"),
    ({"stall_time": -1.0}, r"stall_time=-1.0 must be a number > 0 s"),
    ({"watchdog_time": math.nan}, r"watchdog_time=nan must be a number > 0 s"),
    ({"backout_distance": -3.0}, r"backout_distance=-3.0 must be a number in \[0.0, inf\) m"),
    ({"replan_excess": math.nan}, r"replan_excess=nan must be a number >= 0 m"),
])
def test_a_follower_names_a_bad_setting(changes, message):
    """The follower used to take these as they were: a negative cruise speed drove backwards,
    a negative stall time gave up every waypoint, a NaN speed commanded NaN."""
    settings = {"waypoints": np.array([[0.0, 0.0], [5.0, 0.0]]), "blocked": np.zeros(2, bool),
                "capture_radius": 0.5, "cruise_speed": 1.0, **changes}
    with pytest.raises(ValueError, match=message):
        WaypointFollower(**settings)
