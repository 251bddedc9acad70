"""Executing ORCA's velocity on the unicycle: turn headings and the safe speed along them."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env.safety.orca import orca_lines
from aoass_env.safety.unicycle import (
    BrakingEnvelope,
    braking_speed,
    clearance,
    free_travel,
    speed_bounds,
    turn_headings,
    unicycle_command,
)


def det(d, v):
    return d[0] * v[1] - d[1] * v[0]


def safe_speed(points, dirs, headings, limit):
    """Largest speed up to ``limit`` that is safe on every heading."""
    return float(min(limit, speed_bounds(points, dirs, np.asarray(headings)).min()))


def test_turn_headings_take_the_short_way_and_respect_the_limit():
    h = turn_headings(0.1, 0.1 + 3.0, max_turn=0.5)
    assert h[0] == 0.1 and h[-1] == pytest.approx(0.6) and np.all(np.diff(h) > 0)
    h = turn_headings(3.0, -3.0, max_turn=1.0)          # across +-pi: counter-clockwise
    assert h[-1] == pytest.approx(3.0 + (2 * math.pi - 6.0))
    np.testing.assert_allclose(turn_headings(1.0, 1.2, max_turn=1.0)[[0, -1]], [1.0, 1.2])


def test_a_wall_ahead_caps_the_speed_and_a_wall_behind_does_not():
    # half-plane v_x <= 0.5 (a wall to the +x side): line through (0.5, 0) pointing +y
    points, dirs = np.array([[0.5, 0.0]]), np.array([[0.0, 1.0]])
    assert safe_speed(points, dirs, np.array([0.0]), 2.0) == pytest.approx(0.5)
    assert safe_speed(points, dirs, np.array([math.pi / 3]), 2.0) == pytest.approx(1.0)
    assert safe_speed(points, dirs, np.array([math.pi]), 2.0) == 2.0
    assert safe_speed(points, dirs, np.array([math.pi, 0.0]), 2.0) == pytest.approx(0.5)


def test_a_violated_line_is_never_deepened():
    # v_x >= 0.5 required (an obstacle coming from -x): line through (0.5, 0) pointing -y
    points, dirs = np.array([[0.5, 0.0]]), np.array([[0.0, -1.0]])
    assert safe_speed(points, dirs, np.array([math.pi]), 2.0) == 0.0       # toward it: stay
    assert safe_speed(points, dirs, np.array([0.0]), 2.0) == 2.0           # away: go


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.floats(-2, 2), st.floats(-2, 2), st.floats(0, 2 * math.pi)),
                min_size=1, max_size=6),
       st.floats(-math.pi, math.pi), st.floats(-math.pi, math.pi), st.floats(0.0, 2.0))
def test_the_safe_speed_satisfies_every_line_zero_satisfies(lines, heading, target, limit):
    points = np.array([(x, y) for x, y, _ in lines])
    dirs = np.array([(math.cos(a), math.sin(a)) for _, _, a in lines])
    headings = turn_headings(heading, target, max_turn=math.pi / 4)
    s = safe_speed(points, dirs, headings, limit)
    assert 0.0 <= s <= limit
    for p, d in zip(points, dirs, strict=True):
        zero_ok = det(d, p) <= 0.0
        for h in headings:
            v = s * np.array([math.cos(h), math.sin(h)])
            after = det(d, p - v)
            if zero_ok:
                assert after <= 1e-9
            else:
                assert after <= det(d, p) + 1e-9


def test_unicycle_command_heads_for_v_star_and_slows_while_facing_a_wall():
    lines = orca_lines(np.array([0.0, 0.0]), np.zeros(2), 0.5, 2.0,
                       static_obstacles=[np.array([[1.0, -5.0], [3.0, -5.0], [3.0, 5.0],
                                                   [1.0, 5.0]])],
                       time_horizon_obst=2.0)
    # ORCA would slide along the wall (+y); the anchor still faces the wall (+x)
    speed, heading = unicycle_command(np.array([0.0, 1.0]), 0.0, 0.0, math.pi / 4, 0.5,
                                      lines.point, lines.direction, fallback_heading=0.0)
    assert heading == pytest.approx(math.pi / 2)
    assert speed == pytest.approx(0.25)        # 0.5 m gap over 2 s: 0.25 m/s along +x
    speed, heading = unicycle_command(np.zeros(2), 0.3, 0.0, math.pi / 4, 0.5, lines.point,
                                      lines.direction, fallback_heading=1.0)
    assert speed == 0.0 and heading == 1.0


def test_a_fast_anchor_does_not_turn_into_a_wall_it_cannot_stop_for():
    # wall to the +x side, 0.5 m gap over 2 s: v_x <= 0.25 m/s. The anchor runs along it (+y)
    # at 1.5 m/s and can shed only 0.5 m/s per period; ORCA asks for a heading toward the wall.
    lines = orca_lines(np.array([0.0, 0.0]), np.array([0.0, 1.5]), 0.5, 2.0,
                       static_obstacles=[np.array([[1.0, -50.0], [3.0, -50.0], [3.0, 50.0],
                                                   [1.0, 50.0]])],
                       time_horizon_obst=2.0)
    v_star = np.array([0.25, 0.3])
    speed, heading = unicycle_command(v_star, math.pi / 2, 1.5, math.pi / 4, 0.5, lines.point,
                                      lines.direction, fallback_heading=0.0)
    # at 1.0 m/s a heading h is safe while cos(h) <= 0.25: the turn stops there
    assert math.cos(heading) * 1.0 <= 0.25 + 1e-9
    assert heading < math.pi / 2 and speed <= math.hypot(*v_star) + 1e-12


# --- the braking envelope ------------------------------------------------------------------
def _touch_distance(start, end, position, heading, radius, step=1e-3, limit=20.0):
    """Reference for free_travel: march along the heading until the disc touches the segment
    (shapely distance), or ``limit``."""
    from shapely.geometry import LineString, Point
    segment = LineString([start, end])
    u = np.array([math.cos(heading), math.sin(heading)])
    for t in np.arange(0.0, limit, step):
        if segment.distance(Point(*(position + t * u))) <= radius:
            return t
    return math.inf


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-4.0, 4.0), min_size=4, max_size=4),
       st.floats(-math.pi, math.pi), st.floats(0.1, 1.0))
def test_free_travel_matches_a_marching_disc(coords, heading, radius):
    start, end = np.array(coords[:2]), np.array(coords[2:])
    if np.hypot(*(end - start)) < 0.1:
        return
    position = np.zeros(2)
    from shapely.geometry import LineString, Point
    if LineString([start, end]).distance(Point(0, 0)) <= radius + 1e-3:
        return                                   # touching at the start: tested below
    ray = LineString([position, 20.0 * np.array([math.cos(heading), math.sin(heading)])])
    if abs(LineString([start, end]).distance(ray) - radius) < 1e-9:
        return          # grazing: the disc touches the segment tangentially, both answers hold
    got = free_travel(start[None], end[None], position, np.array([heading]), radius)[0]
    want = _touch_distance(start, end, position, heading, radius)
    if math.isinf(want):
        assert math.isinf(got) or got >= 20.0 - 1e-3
    else:
        assert got == pytest.approx(want, abs=2e-3)


def test_free_travel_of_a_touching_disc_blocks_only_the_headings_that_go_closer():
    # a wall along x = 1 (segment from (1, -5) to (1, 5)); disc of radius 1 touches it
    got = free_travel(np.array([[1.0, -5.0]]), np.array([[1.0, 5.0]]), np.zeros(2),
                      np.array([0.0, math.pi / 4, math.pi / 2, math.pi]), 1.0)
    assert got[0] == 0.0 and got[1] == 0.0
    assert got[2] == pytest.approx(5.0) and math.isinf(got[3])    # slides along to the end
    assert free_travel(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(2), np.zeros(3), 1.0).tolist() \
        == [math.inf] * 3


def test_braking_speed_stops_within_the_distance():
    d = np.array([-1.0, 0.0, 0.5, 2.0, math.inf])
    s = braking_speed(d, 1.0, 0.5)
    assert s[0] == 0.0 and s[1] == 0.0 and math.isinf(s[4])
    # s dt + s^2 / (2 a) equals the distance
    assert s[2:4] * 0.5 + s[2:4] ** 2 / 2.0 == pytest.approx(d[2:4])


def test_the_envelope_slows_a_fast_anchor_before_an_obstacle_corner():
    # a corner 1.5 m ahead and 0.45 m to the side: ORCA with no lines would let the anchor
    # run on at 2 m/s, brushing the corner; the envelope caps the speed so that it can stop
    corner = np.array([[1.5, 0.45], [1.5, 3.0]])
    envelope = BrakingEnvelope(corner[:1], corner[1:], np.zeros(2), 0.7, 1.0, 0.5)
    speed, heading = unicycle_command(np.array([2.0, 0.0]), 0.0, 2.0, math.pi / 4, 0.5,
                                      np.zeros((0, 2)), np.zeros((0, 2)), 0.0, envelope)
    travel = free_travel(corner[:1], corner[1:], np.zeros(2), np.array([0.0]), 0.7)[0]
    assert speed * 0.5 + speed ** 2 / 2.0 <= travel + 1e-9
    assert speed < 2.0 and heading == 0.0
    # without an edge nearby nothing changes
    free = BrakingEnvelope(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(2), 0.7, 1.0, 0.5)
    assert unicycle_command(np.array([2.0, 0.0]), 0.0, 2.0, math.pi / 4, 0.5, np.zeros((0, 2)),
                            np.zeros((0, 2)), 0.0, free) == (2.0, 0.0)


def test_a_braking_anchor_does_not_turn_toward_a_wall_it_cannot_stop_for():
    # an obstacle closes in (two violated lines): only headings within 0.37 rad of -2.52
    # (toward the wall at x = 0) keep from deepening them. The anchor, 0.9 m from the wall,
    # runs south-east of south at 1.6 m/s and sheds only 0.5 m/s in the period.
    lines = []
    for offset in (1.2, -1.2):
        n = np.array([math.cos(-2.52 + offset), math.sin(-2.52 + offset)])
        # permitted: v . n >= 0.5 (zero velocity violates it); RVO2 line: point 0.5 n,
        # direction n rotated by -90 deg (permitted side on its left)
        lines.append((0.5 * n, np.array([n[1], -n[0]])))
    points = np.array([p for p, _ in lines])
    dirs = np.array([d for _, d in lines])
    wall = (np.array([[0.0, -10.0]]), np.array([[0.0, 10.0]]))
    position, heading, speed, max_dv = np.array([0.9, 0.0]), -math.pi / 2 + 0.2, 1.6, 0.5
    args = (np.array([-1.0, 0.0]), heading, speed, 1.0, max_dv, points, dirs, heading)
    envelope = BrakingEnvelope(*wall, position, 0.7, 1.0, 0.5)

    def stop_speed(h):
        return braking_speed(free_travel(*wall, position, np.array([h]), 0.7), 1.0, 0.5)[0]

    floor = speed - max_dv
    old_speed, old_heading = unicycle_command(*args)
    assert old_speed == 0.0 and stop_speed(old_heading) < floor     # turns into the wall
    new_speed, new_heading = unicycle_command(*args, envelope)
    assert new_speed == 0.0 and stop_speed(new_heading) >= floor    # can still stop


def test_clearance_is_the_distance_to_the_nearest_segment():
    starts, ends = np.array([[0.0, 0.0], [5.0, 0.0]]), np.array([[4.0, 0.0], [5.0, 3.0]])
    assert clearance(starts, ends, np.array([2.0, 1.5])) == pytest.approx(1.5)
    assert clearance(starts, ends, np.array([-3.0, 4.0])) == pytest.approx(5.0)   # end point
    assert clearance(starts, ends, np.array([6.0, 1.0])) == pytest.approx(1.0)
    assert math.isinf(clearance(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(2)))


def test_an_anchor_inside_the_radius_slides_on_but_never_closer():
    # a corner at (0, 0): edges along -x and down along -y; the anchor 0.69 m above the first
    # edge, inside the 0.7 m envelope radius, just before the corner. Sliding along the edge
    # past the corner keeps its clearance: free. Any heading toward the edge: capped to 0.
    starts = np.array([[-5.0, 0.0], [0.0, 0.0]])
    ends = np.array([[0.0, 0.0], [0.0, -5.0]])
    position = np.array([-0.2, 0.69])
    envelope = BrakingEnvelope(starts, ends, position, 0.7, 1.0, 0.5)
    caps = envelope(np.array([0.0, -0.3, math.pi / 2]))
    assert math.isinf(caps[0]) and caps[1] < 0.01 and math.isinf(caps[2])


def test_an_anchor_sliding_at_its_clearance_is_not_frozen_by_round_off():
    # the anchor 0.696 m from a wall (inside the 0.7 m radius) heads along it, 0.0006 rad
    # toward it: ORCA lets it slide; the envelope must too (it froze a sweep for 2800 s)
    starts, ends = np.array([[0.0, 0.0]]), np.array([[100.0, 0.0]])
    position = np.array([50.0, 0.696])
    envelope = BrakingEnvelope(starts, ends, position, 0.7, 1.0, 0.5)
    assert envelope(np.array([-0.0006]))[0] > 1.0


def test_a_heading_along_a_line_through_the_origin_is_not_held_by_round_off():
    # ORCA's line of a disc already touching a segment passes through the origin; v* slides
    # along it. A heading parallel to it up to round-off must keep its speed (a sweep froze
    # for 2800 s at speed 0 when it did not).
    d = np.array([[-0.69845617, 0.71565283]])
    heading = math.atan2(-d[0, 1], -d[0, 0]) + 1e-15
    assert speed_bounds(np.zeros((1, 2)), d, np.array([heading]))[0] > 100.0
    # a heading into the forbidden side is still held to (almost) nothing
    assert speed_bounds(np.zeros((1, 2)), d, np.array([heading + 0.1]))[0] < 1e-7


def test_an_opposite_target_is_commanded_as_the_checked_arc():
    """A target exactly opposite the heading: the command is the end of the arc that was
    checked, so the drive cannot turn the other way round (into a wall; issue 24)."""
    for heading in (-1.2217304763960306, 0.3, 2.0):
        target = heading + math.pi
        v_star = 0.5 * np.array([math.cos(target), math.sin(target)])
        speed, command = unicycle_command(v_star, heading, 0.6, math.pi / 4, 0.5,
                                          np.zeros((0, 2)), np.zeros((0, 2)),
                                          fallback_heading=0.0)
        # a quarter of a half turn away: the drive turns to it one way only
        turn = math.remainder(command - heading, 2.0 * math.pi)
        assert abs(turn) == pytest.approx(math.pi / 4)


# --- the float path against the array code (issue 20) -------------------------------------
def _free_travel_arrays(starts, ends, position, headings, radius):
    """free_travel before issue 20's tenth round, on NumPy's arrays (the oracle)."""
    headings = np.asarray(headings, dtype=np.float64)
    if len(starts) == 0:
        return np.full(len(headings), np.inf)
    u = np.stack([np.cos(headings), np.sin(headings)], axis=1)
    p = np.asarray(position, dtype=np.float64)
    r2 = radius * radius
    best = np.full(len(headings), np.inf)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for vertex in (starts, ends):
            w = p - vertex
            wu = u @ w.T
            ww = (w * w).sum(axis=1)
            disc = wu * wu - (ww - r2)
            t = np.where(ww > r2, -wu - np.sqrt(disc), 0.0)
            t = np.where((wu < 0.0) & (disc >= 0.0), t, np.inf)
            best = np.minimum(best, t.min(axis=1))
        e = ends - starts
        length = np.hypot(e[:, 0], e[:, 1])
        n = np.stack([-e[:, 1], e[:, 0]], axis=1) / length[:, None]
        side = ((p - starts) * n).sum(axis=1)
        rate = u @ n.T
        approach = side[None, :] * rate < -1e-12
        t = np.maximum(np.abs(side)[None, :] - radius, 0.0) / np.abs(rate)
        along = ((p - starts) * e).sum(axis=1)[None, :] + t * (u @ e.T)
        inside = (along >= 0.0) & (along <= length * length)
        t = np.where(approach & inside, t, np.inf)
        best = np.minimum(best, t.min(axis=1))
    return best


def _caps_arrays(envelope, headings):
    """BrakingEnvelope(headings) on NumPy's arrays (the oracle): braking_speed of
    _free_travel_arrays at the radius the anchor's clearance allows."""
    if len(envelope.starts):
        gap = _clearance_arrays(envelope.starts, envelope.ends, envelope.position)
    else:
        gap = math.inf
    radius = max(min(envelope.radius, gap - 1e-3), 0.0)
    travel = _free_travel_arrays(envelope.starts, envelope.ends, envelope.position, headings,
                                 radius)
    return braking_speed(travel, envelope.max_accel, envelope.dt)


def _bytes(values):
    return np.asarray(values, dtype=np.float64).tobytes()


def test_compiled_free_travel_and_caps_are_the_array_code_bit_for_bit():
    """Random edges around the anchor (some touching it, some of zero length, some behind),
    on random headings and ones straight at end points and along edges: the compiled free
    travel and the envelope's caps are the array code's floats, signs of zeros included."""
    rng = np.random.default_rng(32)
    for case in range(3000):
        m = int(rng.integers(0, 9))
        position = rng.uniform(-60.0, 60.0, 2)
        starts = position + rng.uniform(-5.0, 5.0, (m, 2))
        ends = starts + rng.uniform(-7.0, 7.0, (m, 2))
        if m and case % 7 == 0:
            ends[0] = starts[0]                                  # a zero-length edge
        if m and case % 5 == 0:                                   # an edge through the disc
            starts[-1] = position + [-3.0, 0.3 * rng.random()]
            ends[-1] = position + [3.0, 0.3 * rng.random()]
        k = int(rng.integers(1, 12))
        headings = rng.uniform(-4.0, 4.0, k)
        if m:
            toward = np.concatenate([starts - position, ends - starts])
            headings = np.concatenate([headings, np.arctan2(toward[:, 1], toward[:, 0])])
        radius = float(rng.choice([0.0, 0.3, 0.7, rng.uniform(0.0, 3.0)]))
        got = free_travel(starts, ends, position, headings, radius)
        assert _bytes(got) == _bytes(_free_travel_arrays(starts, ends, position, headings,
                                                         radius)), case
        if m and case % 7 == 0:
            continue                 # the envelope's clearance rejects a zero-length edge
        envelope = BrakingEnvelope(starts, ends, position, 0.7, float(rng.choice([1.0, 2.5])),
                                   0.5)
        assert _bytes(envelope(headings)) == _bytes(_caps_arrays(envelope, headings)), case


def test_the_certificate_bounds_the_free_travel_from_below():
    """_travel_floor never exceeds free_travel as NumPy and BLAS compute it: random edges
    around the anchor, and the headings where a decision of free_travel turns on round-off
    (straight at end points, tangent to the disc around an end point, along and across
    edges, grazing a side), radii of 0 and up to the clearance."""
    import aoass_env.safety.unicycle as unicycle
    if not unicycle.compiled_trig():
        pytest.skip("the certificate runs only where compiled trig is math's")
    rng = np.random.default_rng(33)
    bound_finite = 0
    for case in range(1500):
        m = int(rng.integers(1, 8))
        position = rng.uniform(-60.0, 60.0, 2)
        starts = position + rng.uniform(-5.0, 5.0, (m, 2))
        ends = starts + rng.uniform(-7.0, 7.0, (m, 2))
        if case % 3 == 0:                               # a wall the anchor slides along
            y = rng.uniform(0.6, 1.2)
            starts[0], ends[0] = position + [-6.0, y], position + [6.0, y]
        gap = clearance(starts, ends, position)
        radius = float(rng.choice([0.0, 0.5 * gap, max(gap - 1e-3, 0.0), 0.7]))
        radius = max(min(radius, gap - 1e-3), 0.0)
        headings = list(rng.uniform(-4.0, 4.0, 6))
        for vertex in np.concatenate([starts, ends]):
            w = vertex - position
            dist, toward = float(np.hypot(*w)), math.atan2(w[1], w[0])
            headings.append(toward)
            if dist > radius:                           # tangent to the disc around it
                tangent = math.asin(radius / dist)
                headings += [toward + tangent, toward - tangent,
                             math.nextafter(toward + tangent, 10.0)]
        for a, b in zip(starts, ends, strict=True):
            along = math.atan2(*(b - a)[::-1])
            headings += [along, along + math.pi, math.nextafter(along, 10.0),
                         along + 1e-13, along + math.pi / 2]
        headings = np.array(headings)
        want = free_travel(starts, ends, position, headings, radius)
        for h, w in zip(headings.tolist(), want.tolist(), strict=True):
            got = unicycle._travel_floor(math.cos(h), math.sin(h), starts, ends,
                                         *position.tolist(), radius)
            assert got <= w, (case, h, got, w)
            bound_finite += math.isfinite(got)
    assert bound_finite > 1000


def _reference_command(v_star, heading, speed, max_turn, max_dv, points, directions,
                       fallback_heading, envelope=None):
    """unicycle_command as it was before its float path (commit 3fdd7e9), on the arrays."""
    vx, vy = float(v_star[0]), float(v_star[1])
    wanted = math.hypot(vx, vy)
    target = math.atan2(vy, vx) if wanted > 1e-9 else fallback_heading
    arc = turn_headings(heading, target, max_turn, n=8)
    bounds = speed_bounds(points, directions, arc)
    floor = max(speed - max_dv, 0.0)
    if envelope is not None:
        caps = _caps_arrays(envelope, arc)
        bounds = np.minimum(bounds, caps)
    reach = np.minimum.accumulate(bounds)
    if reach[0] + 1e-9 < floor:
        if envelope is None:
            return 0.0, float(arc[int(np.argmax(bounds))])
        stoppable = np.minimum.accumulate(caps) + 1e-9 >= floor
        if not stoppable.any():
            return 0.0, float(arc[int(np.argmax(np.minimum.accumulate(caps)))])
        return 0.0, float(arc[int(np.argmax(np.where(stoppable, bounds, -np.inf)))])
    k = int(np.flatnonzero(reach + 1e-9 >= floor)[-1])
    command = target if k == len(arc) - 1 else float(arc[k])
    if abs(math.remainder(target - heading, 2.0 * math.pi)) > math.pi - 1e-3:
        command = float(arc[k])
    return float(min(wanted, reach[k])), command


def _random_case(rng):
    """Random arguments of unicycle_command near what the safety filter passes: ORCA lines
    (some through the origin, some violated), edges within a few metres of the anchor (some
    inside its radius), speeds up to and past the floor."""
    n = int(rng.integers(0, 7))
    angles = rng.uniform(-math.pi, math.pi, n)
    directions = np.column_stack([np.cos(angles), np.sin(angles)])
    points = rng.normal(0.0, 1.0, (n, 2))
    through = rng.random(n) < 0.3
    points[through] = directions[through] * rng.normal(0.0, 1.0, (int(through.sum()), 1))
    m = int(rng.integers(0, 8))
    position = rng.uniform(-50.0, 50.0, 2)
    starts = position + rng.uniform(-4.0, 4.0, (m, 2))
    ends = starts + rng.uniform(-6.0, 6.0, (m, 2))
    envelope = None if rng.random() < 0.15 else BrakingEnvelope(
        starts, ends, position, 0.7, float(rng.choice([1.0, 2.5])), 0.5)
    heading = float(rng.uniform(-4.0, 4.0))
    if rng.random() < 0.1:                         # a target opposite the heading
        v_star = 0.8 * np.array([math.cos(heading + math.pi), math.sin(heading + math.pi)])
    elif rng.random() < 0.1:
        v_star = np.zeros(2)
    else:
        v_star = rng.uniform(-2.0, 2.0, 2)
    return (v_star, heading, float(rng.uniform(0.0, 2.2)), float(rng.choice([0.3, math.pi / 4])),
            0.5, points, directions, float(rng.uniform(-math.pi, math.pi)), envelope)


@pytest.mark.parametrize("path", ["compiled", "floats", "arrays"])
def test_the_float_path_commands_what_the_array_code_commands(monkeypatch, path):
    """Bit for bit, over random cases that take every path: the ORCA lines alone, compiled
    (envelope floor clear of the speeds), the caps from the arrays, and braking with and
    without them; with the compiled path off (compiled trig unlike math's), the float path
    decides those cases; with the float path off, the array code decides all."""
    import aoass_env.safety.unicycle as unicycle
    scalar_trig = path != "arrays"
    if not scalar_trig:
        monkeypatch.setattr(unicycle, "SCALAR_TRIG", False)
    if path == "floats":
        monkeypatch.setattr(unicycle, "compiled_trig", lambda: False)
    rng = np.random.default_rng(20)
    paths = {"lines": 0, "caps": 0, "braking": 0}
    lines_only, with_caps = unicycle._compiled_command, unicycle._command_with_caps

    def counted(name, function):
        def wrapper(*args):
            result = function(*args)
            if name == "caps":
                paths[name] += 1
                paths["braking"] += result[0] == 0.0
            elif result[0]:
                paths[name] += 1
                paths["braking"] += result[1] == 0.0
            return result
        return wrapper

    monkeypatch.setattr(unicycle, "_compiled_command", counted("lines", lines_only))
    monkeypatch.setattr(unicycle, "_command_with_caps", counted("caps", with_caps))
    for _ in range(3000):
        args = _random_case(rng)
        got = unicycle.unicycle_command(*args)
        want = _reference_command(*args)
        assert got == want and all(type(x) is float for x in got), args
        assert [math.copysign(1.0, x) for x in got] == [math.copysign(1.0, x) for x in want]
    if path == "compiled" and unicycle.compiled_trig():
        assert min(paths.values()) > 100, paths
    elif path == "floats" and unicycle.SCALAR_TRIG:
        assert paths["lines"] == 0 and min(paths["caps"], paths["braking"]) > 100, paths


def _clearance_arrays(starts, ends, point):
    """clearance() before issue 20's ninth round (NumPy's arrays; the oracle)."""
    e = ends - starts
    w = np.asarray(point, dtype=np.float64) - starts
    s = np.clip((w * e).sum(axis=1) / (e * e).sum(axis=1), 0.0, 1.0)
    gap = w - s[:, None] * e
    return float(np.sqrt((gap * gap).sum(axis=1)).min())


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(-5, 5),
                          st.floats(-5, 5)), min_size=1, max_size=6),
       st.floats(-100, 100), st.floats(-100, 100), st.floats(0.0, 1.0),
       st.floats(-4.0, 4.0), st.floats(0.0, 1.0))
def test_the_envelope_floor_is_below_every_cap(segments, x, y, radius, heading, skew):
    """The compiled clearance is the array form's float; the envelope's floor lies below its cap
    on any heading, straight at an end point (where the round-off of free_travel is largest)
    included."""
    import aoass_env.safety.unicycle as unicycle
    position = np.array([x, y])
    starts = position + np.array([s[:2] for s in segments])
    ends = position + np.array([s[2:] for s in segments])
    if np.any(np.hypot(*(ends - starts).T) < 1e-6):
        return
    gap = clearance(starts, ends, position)
    assert gap == _clearance_arrays(starts, ends, position)
    envelope = BrakingEnvelope(starts, ends, position, radius, 1.0, 0.5)
    vertex = starts[0] - position
    headings = np.array([heading, math.atan2(vertex[1], vertex[0]) + 1e-9 * skew])
    assert np.all(unicycle._envelope_floor(radius, 1.0, 0.5, gap) <= envelope(headings))


def test_mismatched_lines_or_edges_name_the_arrays():
    """The compiled loops read the arrays by index: mismatched shapes are a clear error, never
    a read past an array."""
    lines = np.array([[0.0, 1.0]]), np.array([[1.0, 0.0]])
    with pytest.raises(ValueError, match="points and directions must be"):
        unicycle_command(np.array([1.0, 0.0]), 0.0, 0.5, 0.5, 0.5, lines[0],
                         np.zeros((2, 2)), 0.0)
    with pytest.raises(ValueError, match="points and directions must be"):
        unicycle_command(np.array([1.0, 0.0]), 0.0, 0.5, 0.5, 0.5, np.zeros((1, 3)),
                         np.zeros((1, 3)), 0.0)
    envelope = BrakingEnvelope(np.zeros((2, 2)), np.ones((1, 2)), np.zeros(2), 0.5, 1.0, 0.5)
    with pytest.raises(ValueError, match="the envelope's starts and ends"):
        unicycle_command(np.array([1.0, 0.0]), 0.0, 0.5, 0.5, 0.5, *lines, 0.0, envelope)


@settings(max_examples=400, deadline=None)
@given(st.one_of(st.floats(-1e6, 1e6), st.integers(-40, 40).map(lambda k: k * math.pi),
                 st.integers(-40, 40).map(lambda k: (k + 0.5) * 2.0 * math.pi),
                 st.sampled_from([0.0, -0.0, 5e-324, -5e-324, math.pi, -math.pi])))
def test_the_compiled_remainder_is_maths(x):
    """The compiled turn's wrap is math.remainder(x, 2 pi), sign of a zero included: odd and
    even multiples of pi (the float nearest a half-way case, and the ties the even rule
    breaks), huge and tiny angles."""
    import aoass_env.safety.unicycle as unicycle
    got, want = unicycle._remainder(x), math.remainder(x, 2.0 * math.pi)
    assert got == want and math.copysign(1.0, got) == math.copysign(1.0, want)


def test_the_compiled_remainder_breaks_a_tie_to_the_even_multiple():
    """Half periods x = (k + 1/2) 2 pi: where x lies exactly half way between two multiples
    of the float period (at least four of them), the even multiple wins, as in math."""
    import aoass_env.safety.unicycle as unicycle
    period = 2.0 * math.pi
    ties = 0
    for k in range(-7, 8):
        x = (k + 0.5) * period
        m = math.fmod(abs(x), period)
        ties += m == period - m              # the half-way branch
        got, want = unicycle._remainder(x), math.remainder(x, period)
        assert got == want and math.copysign(1.0, got) == math.copysign(1.0, want), x
    assert ties >= 4


_COMMAND = dict(v_star=np.array([1.0, 0.0]), heading=0.0, speed=0.5, max_turn=0.3, max_dv=0.25,
                points=np.zeros((0, 2)), directions=np.zeros((0, 2)), fallback_heading=0.0)


@pytest.mark.parametrize("name, value, match", [
    ("v_star", np.array([math.nan, 0.0]), "v_star must be a pair of finite numbers"),
    ("v_star", np.array([1.0, 0.0, 0.0]), "v_star must be a pair"),
    ("heading", math.nan, "heading="), ("heading", "0", "heading="), ("speed", True, "speed="),
    ("speed", -1.0, "speed="), ("speed", math.inf, "speed="),
    ("max_turn", -0.3, "max_turn="), ("max_dv", math.nan, "max_dv="),
    ("fallback_heading", -math.inf, "fallback_heading="),
    ("points", np.array([[math.nan, 0.0]]), "must be finite"),
])
def test_unicycle_command_refuses_what_would_command_nonsense(name, value, match):
    """A NaN heading used to give a full-speed command, a negative turn limit a turn beyond
    it, a NaN in v* a NaN speed: each is now an error naming the argument."""
    kwargs = dict(_COMMAND, **{name: value})
    if name == "points":
        kwargs["directions"] = np.array([[1.0, 0.0]])
    with pytest.raises(ValueError, match=match):
        unicycle_command(**kwargs)
    assert unicycle_command(**_COMMAND) == (1.0, 0.0)      # the good call still commands


@pytest.mark.parametrize("field, value, match", [
    ("position", np.array([math.nan, 0.0]), r"position must be finite \(m\)"),
    ("position", np.zeros(3), "position must be a"),
    ("starts", np.array([[math.inf, 0.0]]), "starts must be finite"),
    ("ends", np.zeros((1, 3)), r"ends must be an array of shape \(n, 2\)"),
    ("ends", [[1.0, 1.0]], "ends must be a float64 array"),
    ("radius", -0.5, "radius="), ("max_accel", 0.0, "max_accel="), ("dt", math.nan, "dt="),
])
def test_a_braking_envelope_of_nonfinite_or_bad_values_is_refused(field, value, match):
    """A NaN position used to cap no heading (an infinite cap), a negative deceleration every
    heading with NaN."""
    good = dict(starts=np.array([[1.0, -1.0]]), ends=np.array([[1.0, 1.0]]),
                position=np.zeros(2), radius=0.5, max_accel=0.5, dt=0.5)
    with pytest.raises(ValueError, match=match):
        BrakingEnvelope(**dict(good, **{field: value}))
    assert np.isfinite(BrakingEnvelope(**good)(np.array([0.0]))).all()
