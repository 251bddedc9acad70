import math

import numpy as np
import pytest

from aoass_env.maps import ObstacleMap
from aoass_env.planning.detour import DetourPlanner
from aoass_env.planning.follower import WaypointFollower


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
