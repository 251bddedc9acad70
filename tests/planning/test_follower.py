import math

import numpy as np

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
