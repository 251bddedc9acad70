"""The look-ahead's pure functions (aoass_env.safety.lookahead) and the tracker's covariances."""

from __future__ import annotations

import math

import numpy as np
import pytest

from aoass_env.safety import lookahead
from aoass_env.safety.kalman import MultiTargetTracker
from aoass_env.safety.lookahead import (
    OPEN_SPACE,
    EscapeBudget,
    bounce_reach,
    candidate_commands,
    escape_velocity,
    look_ahead_horizon,
    obstacle_radii,
    position_std,
    predict_obstacles,
    rollout,
    rollout_reach,
    segment_distances,
    violation,
)
from aoass_env.safety.orca import StaticObstacles

LIMITS = {"max_speed": 2.0, "max_accel": 1.0, "max_turn_rate": math.pi / 2}


def test_horizon_is_a_period_a_full_stop_and_a_half_turn():
    assert look_ahead_horizon(2.0, 1.0, math.pi / 2, 0.5) == pytest.approx(4.5)
    assert look_ahead_horizon(1.0, 2.0, math.pi, 0.1) == pytest.approx(1.6)


def test_position_std_is_the_propagated_covariance():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(3, 4, 4))
    p = a @ a.transpose(0, 2, 1) + 0.1 * np.eye(4)
    times = np.array([0.0, 0.5, 2.0, 4.5])
    std = position_std(p, times)
    for i in range(3):
        for j, t in enumerate(times):
            f = np.eye(4)
            f[0, 2] = f[1, 3] = t
            block = (f @ p[i] @ f.T)[:2, :2]
            assert std[i, j] == pytest.approx(math.sqrt(np.linalg.eigvalsh(block).max()))


def test_tracker_exposes_the_filters_covariances():
    tracker = MultiTargetTracker(0.5, position_noise=0.3, velocity_noise=0.2)
    for k in range(3):
        tracker.step([[k * 0.5, 0.0, 1.0, 0.0], [10.0, k * 0.5, 0.0, 1.0]])
    cov = tracker.covariances()
    assert cov.shape == (2, 4, 4)
    for row, track in zip(cov, tracker.confirmed, strict=True):
        np.testing.assert_array_equal(row, track.filter.P)
    np.testing.assert_array_equal(tracker.position_covariances(), cov[:, :2, :2])
    cov[0, 0, 0] = 1e9                                        # a copy
    assert tracker.confirmed[0].filter.P[0, 0] < 1.0
    assert tracker.covariances(confirmed_only=False).shape == (2, 4, 4)
    assert MultiTargetTracker(0.5, position_noise=0.3, velocity_noise=None
                              ).covariances().shape == (0, 4, 4)


def test_obstacle_radii_grow_with_uncertainty_and_speed():
    times = np.array([0.0, 1.0, 2.0])
    r = obstacle_radii(np.array([1.5]), np.array([1.0]), np.array([[0.1, 0.2, 0.3]]), times,
                       sigma=2.0, maneuver=0.25)
    np.testing.assert_allclose(r, [[1.7, 2.15, 2.6]])


def test_segment_distances():
    starts, ends = np.array([[0.0, 0.0]]), np.array([[10.0, 0.0]])
    d = segment_distances(np.array([[5.0, 2.0], [-3.0, 4.0], [12.0, 0.0]]), starts, ends)
    np.testing.assert_allclose(d, [2.0, 5.0, 2.0])
    assert np.isinf(segment_distances(np.zeros((1, 2)), np.zeros((0, 2)), np.zeros((0, 2)))).all()


def test_obstacles_go_straight_and_bounce_off_edges():
    free = predict_obstacles(np.array([[0.0, 0.0, 1.0, 0.5]]), 0.5, 4, np.zeros((0, 2)),
                             np.zeros((0, 2)), np.array([1.0]))
    np.testing.assert_allclose(free[0, -1], [2.0, 1.0])
    # a wall at x = 3 (a vertical segment): a disc of radius 1 moving +x turns back at x ~ 2
    wall = (np.array([[3.0, -10.0]]), np.array([[3.0, 10.0]]))
    path = predict_obstacles(np.array([[0.0, 0.0, 1.0, 0.0]]), 0.5, 8, *wall, np.array([1.0]))
    assert path[0, :, 0].max() <= 2.0 + 1e-9
    assert path[0, -1, 0] < path[0, 3, 0]                       # it came back


def test_an_obstacle_beyond_the_anchors_reach_bounces_back_into_its_way():
    """An obstacle 6 m ahead runs away from the anchor toward a wall 10.5 m ahead, beyond the
    edges the anchor's own rollouts read (9 m of travel plus its radius): the look-ahead took
    only those, so the obstacle was predicted through the wall and out of the anchor's way.
    With its own edges (within :func:`bounce_reach`) it bounces back into the anchor's path."""
    border = StaticObstacles.from_loops([np.array([[-10.5, -20.0], [-10.5, 20.0], [20.0, 20.0],
                                                   [20.0, -20.0]])])     # clockwise: inside free
    anchor, horizon, step = np.zeros(2), 4.5, 0.25
    obstacles = np.array([[-6.0, 0.0, -1.8, 0.0, 1.5]])
    old = border.segments_near(anchor, 2.0 * horizon + 0.7)            # the old reach: none
    starts, ends = border.segments_near(anchor, rollout_reach(2.0, horizon, step, 0.7))
    bounce = border.segments_near_any(obstacles[:, :2],
                                      bounce_reach(obstacles, horizon, step, 0.5))
    assert len(old[0]) == 0 and len(bounce[0]) == 1
    v = np.array([-2.0, 0.0])

    def escape(starts, ends, **kw):
        return escape_velocity(v, v, anchor, math.pi, 2.0, obstacles,
                               np.diag([0.04, 0.04, 0.01, 0.01])[None], **LIMITS,
                               horizon=horizon, step=step, starts=starts, ends=ends,
                               radius=0.7, sigma=2.0, maneuver=0.25, clearance=0.5,
                               obstacle_radius=0.5, **kw)

    through = escape(*old)                      # the old edges: the obstacle leaves the field
    bounced = escape(starts, ends, bounce_starts=bounce[0], bounce_ends=bounce[1])
    assert through.shortfall == 0.0 and not through.escaping
    assert bounced.shortfall > 0.0 and bounced.escaping
    with pytest.raises(ValueError, match="bounce_starts and bounce_ends must be given together"):
        escape(starts, ends, bounce_starts=bounce[0])
    with pytest.raises(ValueError, match="bounce_starts and bounce_ends .* must be finite"):
        escape(starts, ends, bounce_starts=np.array([[math.nan, 0.0]]),
               bounce_ends=np.array([[1.0, 0.0]]))


def test_the_edge_reaches_hold_every_edge_the_look_ahead_reads():
    """Among the edges of a generated map, those within :func:`rollout_reach` of the anchor give
    its rollouts and their ends' wall prices (distances up to OPEN_SPACE) as all the map's
    edges do, and those within :func:`bounce_reach` of the obstacles give their predicted
    paths, bit for bit, from random anchors, headings, speeds and obstacles."""
    from aoass_env.maps import generate_map

    so = StaticObstacles.from_loops(generate_map(60.0, 0.4, np.random.default_rng(41))
                                    .free_space_loops)
    every = (so.point, so.point[so.next])
    rng = np.random.default_rng(42)
    horizon, step = 4.5, 0.25
    n_steps = math.ceil(horizon / step - 1e-9)
    bounced = fewer = 0
    for _ in range(300):
        position = rng.uniform(0.0, 60.0, 2)
        radius = float(rng.choice([0.7, 1.2, 2.5]))
        starts, ends = so.segments_near(position, rollout_reach(2.0, horizon, step, radius))
        headings, speeds = rng.uniform(-4.0, 4.0, 6), rng.uniform(0.0, 2.0, 6)
        args = (position, float(rng.uniform(-4.0, 4.0)), float(rng.uniform(0.0, 2.0)),
                headings, speeds, math.pi / 2, 1.0, step, n_steps)
        paths = rollout(*args, starts, ends, radius)
        assert paths.tobytes() == rollout(*args, *every, radius).tobytes()
        clip = np.minimum(segment_distances(paths[:, -1], starts, ends), OPEN_SPACE)
        assert np.array_equal(clip, np.minimum(segment_distances(paths[:, -1], *every),
                                               OPEN_SPACE))
        obstacles = np.column_stack([position + rng.uniform(-15.0, 15.0, (4, 2)),
                                     rng.uniform(-1.5, 1.5, (4, 2))])
        near = so.segments_near_any(obstacles[:, :2],
                                    bounce_reach(obstacles, horizon, step, 0.5))
        got = predict_obstacles(obstacles, step, n_steps, *near, np.full(4, 0.5))
        want = predict_obstacles(obstacles, step, n_steps, *every, np.full(4, 0.5))
        assert got.tobytes() == want.tobytes()
        straight = obstacles[:, None, :2] + (step * np.arange(1, n_steps + 1))[None, :, None] \
            * obstacles[:, None, 2:]
        bounced += int((np.abs(want - straight) > 1e-6).any(axis=(1, 2)).sum())
        fewer += len(near[0]) < len(so.point)
    assert bounced > 50 and fewer == 300


def test_rollout_follows_the_unicycle_and_stops_at_walls():
    none = np.zeros((0, 2))
    path = rollout(np.zeros(2), 0.0, 1.0, np.array([0.0]), np.array([1.0]), **{
        k: LIMITS[k] for k in ("max_turn_rate", "max_accel")}, step=0.5, n_steps=4,
        starts=none, ends=none, radius=0.7)
    np.testing.assert_allclose(path[0, :, 0], [0.5, 1.0, 1.5, 2.0])
    # a half turn takes 2 s at pi/2 rad/s: the heading reverses within 4 steps of 0.5 s
    back = rollout(np.zeros(2), 0.0, 0.0, np.array([math.pi]), np.array([1.0]), math.pi / 2,
                   1.0, 0.5, 8, none, none, 0.7)
    assert back[0, -1, 0] < back[0, 3, 0]
    # a wall 2 m ahead: the centre never gets closer than the radius
    wall = (np.array([[2.0, -5.0]]), np.array([[2.0, 5.0]]))
    held = rollout(np.zeros(2), 0.0, 2.0, np.array([0.0]), np.array([2.0]), math.pi / 2, 1.0,
                   0.25, 12, *wall, 0.7)
    assert held[0, :, 0].max() <= 2.0 - 0.7 + 1e-12


def test_violation_sums_the_shortfall():
    paths = np.array([[[0.0, 0.0], [0.0, 0.0]], [[10.0, 0.0], [10.0, 0.0]]])
    centres = np.array([[[2.0, 0.0], [3.0, 0.0]]])
    radii = np.array([[1.5, 1.5]])
    np.testing.assert_allclose(violation(paths, centres, radii, 1.0), [0.5, 0.0])
    np.testing.assert_allclose(violation(paths, np.zeros((0, 2, 2)), np.zeros((0, 2)), 1.0),
                               [0.0, 0.0])


def test_candidates_cover_every_direction_and_a_stop():
    headings, speeds = candidate_commands(0.3, 2.0, 8, (1.0,))
    assert len(headings) == len(speeds) == 9 * 3 + 1
    assert speeds[-1] == 0.0 and headings[-1] == 0.3
    assert set(np.round(speeds[:-1], 9)) == {0.5, 1.0, 2.0}


def _escape(velocity, obstacles, covariances=None, **kw):
    obstacles = np.asarray(obstacles, float).reshape(-1, 5)
    if covariances is None:
        covariances = np.tile(np.diag([0.04, 0.04, 0.01, 0.01]), (len(obstacles), 1, 1))
    args = dict(max_speed=2.0, max_accel=1.0, max_turn_rate=math.pi / 2, horizon=4.5,
                step=0.25, starts=np.zeros((0, 2)), ends=np.zeros((0, 2)), radius=0.7,
                sigma=2.0, maneuver=0.25, clearance=0.5, obstacle_radius=1.0)
    args.update(kw)
    return escape_velocity(np.asarray(velocity, float), np.asarray(velocity, float),
                           np.zeros(2), 0.0, float(np.hypot(*velocity)), obstacles,
                           covariances, **args)


def test_a_clear_velocity_is_kept():
    out = _escape([1.0, 0.0], np.zeros((0, 5)))
    assert not out.escaping and out.shortfall == 0.0
    np.testing.assert_array_equal(out.velocity, [1.0, 0.0])
    far = _escape([1.0, 0.0], [[0.0, 30.0, 0.0, -0.5, 1.5]])
    assert not far.escaping


def test_a_head_on_obstacle_makes_the_anchor_escape_sideways_or_back():
    out = _escape([1.0, 0.0], [[6.0, 0.0, -1.0, 0.0, 1.5]])
    assert out.escaping and out.shortfall > 0.0
    assert out.chosen_shortfall < out.shortfall
    # the escape does not keep driving at the obstacle
    assert out.velocity[0] < 0.5 or abs(out.velocity[1]) > 0.5


def test_escape_avoids_a_dead_end():
    """A wall across the way ahead and on the left: the escape from an obstacle coming from
    behind-left takes the open side, not the corner."""
    starts = np.array([[4.0, -10.0], [-10.0, 2.5]])
    ends = np.array([[4.0, 10.0], [10.0, 2.5]])
    out = _escape([1.0, 0.0], [[-3.0, 1.0, 1.0, 0.0, 1.5]], starts=starts, ends=ends)
    assert out.escaping
    assert out.velocity[1] < 0.0                     # toward the open side (-y)


def test_a_late_shortfall_is_left_to_orca_when_a_reaction_time_is_given():
    """An obstacle crossing 6 m ahead misses the bare disc, but its grown disc reaches the
    straight rollout late in the horizon. Without a reaction time the look-ahead escapes at
    once; with 2.5 s it keeps the given velocity (nothing is imminent) and reports the
    shortfall."""
    obstacle = [[6.0, -6.5, 0.0, 1.0, 1.5]]
    eager = _escape([1.0, 0.0], obstacle)
    assert eager.escaping and eager.shortfall > 0.0
    calm = _escape([1.0, 0.0], obstacle, react=2.5)
    assert not calm.escaping and calm.shortfall == eager.shortfall
    np.testing.assert_array_equal(calm.velocity, [1.0, 0.0])
    # a predicted contact with the bare disc is imminent whatever the reaction time
    head_on = _escape([1.0, 0.0], [[8.0, 0.0, -1.0, 0.0, 1.5]], react=0.5)
    assert head_on.escaping


def test_the_sweeps_headway_picks_among_escapes():
    """An obstacle crossing 4 m ahead of a slow sweep heading +y: without a price on headway
    the escape stops (the candidate nearest the slow preferred velocity); with it the escape
    is a safe candidate that keeps going along the sweep."""
    obstacle = np.array([[3.0, 4.0, -1.0, 0.0, 1.5]])
    args = dict(max_speed=2.0, max_accel=1.0, max_turn_rate=math.pi / 2, horizon=4.5,
                step=0.25, starts=np.zeros((0, 2)), ends=np.zeros((0, 2)), radius=0.7,
                sigma=2.0, maneuver=0.25, clearance=0.5, obstacle_radius=1.0)
    cov = np.diag([0.04, 0.04, 0.01, 0.01])[None]
    v = np.array([0.0, 0.5])
    plain = escape_velocity(v, v, np.zeros(2), math.pi / 2, 0.5, obstacle, cov, **args)
    keen = escape_velocity(v, v, np.zeros(2), math.pi / 2, 0.5, obstacle, cov,
                           progress_weight=10.0, **args)
    assert plain.escaping and keen.escaping
    assert plain.velocity[1] < 0.5
    assert keen.velocity[1] > 1.0 and keen.chosen_shortfall == 0.0


def _passage(tolerance, ahead=6.0, maneuver=0.5, progress_weight=2.0):
    """The anchor 1 m inside a 3.2 m passage (walls x = +-1.6 from y = -1 on, heading -y out
    of it, standing); an obstacle ``ahead`` m ahead drives into the mouth at 1 m/s (the
    look-ahead's ``maneuver`` and ``progress_weight``: 0 and 10 while yielding)."""
    starts = np.array([[-1.6, -1.0], [1.6, 20.0]])
    ends = np.array([[-1.6, 20.0], [1.6, -1.0]])
    v = np.array([0.0, -1.0])
    return escape_velocity(v, v, np.zeros(2), -math.pi / 2, 0.0,
                           np.array([[0.0, -ahead, 0.0, 1.0, 1.5]]),
                           np.diag([0.01, 0.01, 0.01, 0.01])[None], max_speed=2.0,
                           max_accel=1.0, max_turn_rate=math.pi / 2, horizon=4.5, step=0.25,
                           starts=starts, ends=ends, radius=0.7, sigma=2.0, maneuver=maneuver,
                           clearance=0.2, obstacle_radius=1.0, react=2.5,
                           progress_weight=progress_weight, tolerance=tolerance)


def test_free_space_does_not_buy_clearance_in_a_passage():
    """Issue 24, the contacts left: backing up the passage keeps clear of the obstacle, but
    ends between its walls; dashing past the obstacle ends in the open. On one cost the price
    on ending near a wall outweighed the shortfall and the anchor dashed at the obstacle;
    with the tolerance, the prices choose only among the (nearly) safest candidates."""
    one_cost = _passage(None)
    assert one_cost.escaping and one_cost.velocity[1] < -1.0     # toward the obstacle
    assert one_cost.chosen_shortfall > 10.0
    out = _passage(1.0)
    assert out.escaping and out.velocity[1] > 0.5                # backs up the passage
    assert out.chosen_shortfall <= 1.0


def test_a_wider_tolerance_while_yielding_leaves_the_passage_but_not_at_the_obstacle():
    """Issue 24, third round: with the clearance first (tolerance 1) an anchor yielding to the
    sweep stays in the passage an obstacle drives at, however small the shortfall of leaving
    (it stood pinned in such pockets and lost sweeps to the time limit); the yielding
    tolerance (3) lets the sweep's headway take it out past the obstacle 8 m off for a small
    shortfall, but not past it 6 m off, where the one cost dashes at it anyway."""
    yielding = {"maneuver": 0.0, "progress_weight": 10.0}
    stays = _passage(1.0, ahead=8.0, **yielding)
    assert stays.escaping and stays.velocity[1] > -0.1           # stands in the passage
    leaves = _passage(3.0, ahead=8.0, **yielding)
    assert leaves.escaping and leaves.velocity[1] < -1.0         # out toward the sweep
    assert 0.0 < leaves.chosen_shortfall <= 3.0
    near = _passage(3.0, ahead=6.0, **yielding)
    assert near.escaping and near.velocity[1] > -0.1 and near.chosen_shortfall <= 3.0
    one_cost = _passage(None, ahead=6.0, **yielding)
    assert one_cost.velocity[1] < -1.0 and one_cost.chosen_shortfall > 3.0


def test_the_escape_budget_yields_with_hysteresis():
    budget = EscapeBudget(budget=2.0, refill=0.5)
    for _ in range(3):
        budget.update(True, 0.5)
    assert not budget.yielding and budget.spent == pytest.approx(1.5)
    budget.update(True, 0.5)
    assert budget.yielding                                   # 2 s spent
    budget.update(False, 0.5)
    assert budget.yielding                                   # 1.75 s: still above half
    for _ in range(3):
        budget.update(False, 0.5)
    assert not budget.yielding and budget.spent == pytest.approx(1.0)
    budget.update(True, 0.5)
    budget.reset()
    assert budget.spent == 0.0 and not budget.yielding
    # a negative or NaN budget used to be taken (yielding at once, or never)
    for bad, message in ((-5.0, "budget=-5.0 must be"), (math.nan, "budget=nan must be")):
        with pytest.raises(ValueError, match=message):
            EscapeBudget(budget=bad)
    with pytest.raises(ValueError, match=r"refill=-1.0 must be a number in \[0.0, inf\) s per s"):
        EscapeBudget(budget=2.0, refill=-1.0)


def _predict_step_by_step(states, step, n_steps, starts, ends, radii):
    """predict_obstacles' model with the edge test on every obstacle at every step (the
    oracle of its shortcut for obstacles too far from the edges to reach them)."""
    xy, v = states[:, :2].copy(), states[:, 2:].copy()
    out = np.empty((len(states), n_steps, 2))
    for i in range(n_steps):
        moved = xy + step * v
        for j in range(len(states)):
            d = segment_distances(moved[j:j + 1], starts, ends)[0]
            if d >= radii[j]:
                continue
            # the nearest segment's normal toward the disc
            e = ends - starts
            s = np.clip(((moved[j] - starts) * e).sum(1) / (e * e).sum(1), 0.0, 1.0)
            g = moved[j] - (starts + s[:, None] * e)
            k = int(np.argmin((g * g).sum(1)))
            normal = g[k] / max(np.hypot(*g[k]), 1e-12)
            along = v[j] @ normal
            if along < 0.0:
                v[j] = v[j] - 2.0 * along * normal
                moved[j] = xy[j] + step * v[j]
        xy = moved
        out[:, i] = xy
    return out


def test_prediction_shortcut_matches_the_step_by_step_model():
    rng = np.random.default_rng(5)
    for _ in range(200):
        m, e = rng.integers(1, 5), rng.integers(1, 6)
        states = np.column_stack([rng.uniform(-12, 12, (m, 2)), rng.uniform(-1, 1, (m, 2))])
        starts = rng.uniform(-12, 12, (e, 2))
        ends = starts + rng.uniform(-6, 6, (e, 2))
        radii = np.full(m, 1.0)
        np.testing.assert_allclose(predict_obstacles(states, 0.25, 18, starts, ends, radii),
                                   _predict_step_by_step(states, 0.25, 18, starts, ends, radii),
                                   rtol=0, atol=1e-9)


def _segment_distances_clip(points, starts, ends):
    """segment_distances before issue 20's fifth round (np.clip, the edge vectors per call):
    the exact-equality oracle of the prepared segments' distances."""
    points = np.asarray(points, dtype=np.float64)
    if len(starts) == 0:
        return np.full(len(points), np.inf)
    e = ends - starts
    ee = np.maximum((e * e).sum(axis=1), 1e-300)
    wx = points[:, 0, None] - starts[None, :, 0]
    wy = points[:, 1, None] - starts[None, :, 1]
    s = np.clip((wx * e[:, 0] + wy * e[:, 1]) / ee, 0.0, 1.0)
    gx, gy = wx - s * e[:, 0], wy - s * e[:, 1]
    return np.sqrt((gx * gx + gy * gy).min(axis=1))


def test_segment_distances_are_the_clipped_array_code_bit_for_bit():
    rng = np.random.default_rng(20)
    for i in range(2000):
        e, k = int(rng.integers(0, 9)), int(rng.integers(1, 60))
        starts = rng.uniform(-10, 10, (e, 2))
        ends = starts + rng.uniform(-6, 6, (e, 2))
        if i % 4 == 0 and e:
            ends[0] = starts[0]                         # a zero-length segment
        points = rng.uniform(-12, 12, (k, 2))
        if e and i % 3 == 0:
            # points on segment ends, on the segments' lines and their extensions: zero
            # projections (either sign) and s clipped to exactly 0 or 1
            j = rng.integers(0, e, k)
            t = rng.choice([-1.0, -0.0, 0.0, 0.5, 1.0, 2.0], k)
            points = starts[j] + t[:, None] * (ends[j] - starts[j])
        want = _segment_distances_clip(points, starts, ends)
        np.testing.assert_array_equal(segment_distances(points, starts, ends), want)
        if e:
            np.testing.assert_array_equal(lookahead._Segments(starts, ends).distances(points),
                                          want)


def test_the_compiled_base_verdict_is_the_array_code_bit_for_bit():
    """escape_velocity's first stage (near obstacles, their predicted and grown discs, the
    given velocity's rollout, its cost and whether it is imminent), compiled, gives the array
    code's floats on random scenes: obstacles near and far, straight or bouncing off edges,
    anchors at walls, zero velocities, with and without a reaction time."""
    if not (lookahead.SCALAR_TRIG and lookahead.compiled_trig()):
        pytest.skip("the compiled stage runs only where compiled trig is math's")
    rng = np.random.default_rng(23)
    kinds = {"found": 0, "none": 0, "imminent": 0, "walls": 0}
    for case in range(600):
        m = int(rng.integers(0, 5))
        position = rng.uniform(-5.0, 5.0, 2)
        obstacles = np.column_stack([position + rng.uniform(-15.0, 15.0, (m, 2)),
                                     rng.uniform(-1.5, 1.5, (m, 2)), rng.uniform(0.5, 1.5, m)])
        a = rng.normal(0.0, 0.3, (m, 4, 4))
        covariances = a @ a.transpose(0, 2, 1) + 0.01 * np.eye(4)
        e = int(rng.integers(0, 6))
        starts = position + rng.uniform(-4.0, 4.0, (e, 2))
        ends = starts + rng.uniform(-6.0, 6.0, (e, 2))
        # the obstacles' own edges: the anchor's, or others farther out
        if case % 3:
            b = int(rng.integers(0, 6))
            bounce_starts = position + rng.uniform(-16.0, 16.0, (b, 2))
            bounce_ends = bounce_starts + rng.uniform(-6.0, 6.0, (b, 2))
        else:
            bounce_starts, bounce_ends = starts, ends
        velocity = np.zeros(2) if case % 9 == 0 else rng.uniform(-2.0, 2.0, 2)
        wanted = float(np.hypot(*velocity))
        heading = float(rng.uniform(-4.0, 4.0))
        own = math.atan2(velocity[1], velocity[0]) if wanted > 1e-9 else heading
        speed = float(rng.uniform(0.0, 2.0))
        n_steps, step = 18, 0.25
        times = step * np.arange(1, n_steps + 1)
        soon = int(rng.choice([0, 1, 7, 18]))
        obstacle_radius = None if case % 4 == 0 else 0.5
        sigma, maneuver = float(rng.choice([0.0, 1.0, 1.7])), float(rng.choice([0.0, 0.3, 0.5]))
        want = lookahead._base_arrays(own, wanted, position, heading, speed, obstacles,
                                      covariances, 2.0, 1.0, math.pi / 2, 4.5, step, n_steps,
                                      times, starts, ends, 0.7, sigma, maneuver, 0.3,
                                      obstacle_radius, soon, bounce_starts, bounce_ends)
        segments = lookahead._Segments(starts, ends)
        bounces = lookahead._Segments(bounce_starts, bounce_ends)
        got = lookahead._base_compiled(
            own, wanted, *position.tolist(), heading, speed, obstacles, covariances, 2.0, 1.0,
            math.pi / 2, 4.5, step, n_steps, times, segments.sx, segments.sy, segments.ex,
            segments.ey, segments.ee, 0.7, sigma, maneuver, 0.3,
            -1.0 if obstacle_radius is None else obstacle_radius, soon, bounces.sx, bounces.sy,
            bounces.ex, bounces.ey, bounces.ee)
        assert got[0] == want[0] and got[6] == want[6], case
        if want[0]:
            assert all(np.asarray(g).tobytes() == np.asarray(w).tobytes()
                       for g, w in zip(got[1:6], want[1:6], strict=True)), case
        kinds["found" if want[0] else "none"] += 1
        kinds["imminent"] += want[6]
        kinds["walls"] += bool(e) and want[0]
    assert min(kinds.values()) > 30, kinds



@pytest.mark.parametrize("std, sigma, horizon, distances", [
    (5.0, 2.0, 4.5, (16.0, 16.9, 17.0, 18.0)),     # a position std above 3 m
    (10.0, 2.0, 4.5, (16.0, 17.0, 30.0)),
    (0.0, 0.0, 4.6, (17.9, 18.0)),                 # a rollout (19 steps) past the horizon
])
def test_an_obstacle_that_reaches_the_rollout_is_never_left_out(std, sigma, horizon,
                                                                 distances):
    """The obstacles left out before the rollout are those that cannot reach it: the given
    velocity's shortfall is the one of its rollout against every obstacle's grown disc
    (rollout and violation, independently), whatever the tracks' position std (the filter
    assumed at most 3 m: a standing obstacle 17 m ahead with a 5 m std counted 0) and to the
    rollout's last step (ceil(horizon / step) steps, past the horizon)."""
    step, maneuver, clearance = 0.25, 0.5, 0.2
    n_steps = math.ceil(horizon / step - 1e-9)
    times = step * np.arange(1, n_steps + 1)
    covariances = np.diag([std * std, std * std, 0.04, 0.04])[None]
    no_edges = np.zeros((0, 2))
    counted = 0
    for distance in distances:
        obstacles = np.array([[distance, 0.0, -1.0 if std == 0.0 else 0.0, 0.0, 1.5]])
        escape = escape_velocity(np.array([2.0, 0.0]), np.array([2.0, 0.0]), np.zeros(2), 0.0,
                                 2.0, obstacles, covariances, **LIMITS, horizon=horizon,
                                 step=step, starts=no_edges, ends=no_edges, radius=0.7,
                                 sigma=sigma, maneuver=maneuver, clearance=clearance,
                                 react=None)
        path = rollout(np.zeros(2), 0.0, 2.0, np.array([0.0]), np.array([2.0]),
                       LIMITS["max_turn_rate"], LIMITS["max_accel"], step, n_steps, no_edges,
                       no_edges, 0.7)
        centres = obstacles[:, None, :2] + times[None, :, None] * obstacles[:, None, 2:4]
        speeds = np.hypot(obstacles[:, 2], obstacles[:, 3])
        radii = obstacle_radii(obstacles[:, 4], speeds, position_std(covariances, times),
                               times, sigma, maneuver)
        want = float(violation(path, centres, radii, clearance)[0])
        assert escape.shortfall == pytest.approx(want, abs=1e-9), distance
        base = lookahead._base_arrays(0.0, 2.0, np.zeros(2), 0.0, 2.0, obstacles, covariances,
                                      2.0, 1.0, math.pi / 2, horizon, step, n_steps, times,
                                      no_edges, no_edges, 0.7, sigma, maneuver, clearance,
                                      None, 0, no_edges, no_edges)
        assert base[5] == pytest.approx(want, abs=1e-9), distance
        counted += want > 0.0
    assert counted >= 2

def test_segment_tables_are_the_array_code_bit_for_bit():
    """The compiled tables of _Segments: the starts' coordinates, e = end - start and
    max(|e|^2, 1e-300) as NumPy computes them, for edges of zero, tiny and large lengths."""
    rng = np.random.default_rng(22)
    for i in range(300):
        e = int(rng.integers(0, 12))
        starts = rng.uniform(-1e3, 1e3, (e, 2))
        ends = starts + rng.choice([0.0, 1e-160, 1e-9, 1.0, 50.0]) * rng.normal(size=(e, 2))
        tables = lookahead._Segments(starts, ends)
        d = ends - starts
        want = (starts[:, 0], starts[:, 1], d[:, 0], d[:, 1],
                np.maximum((d * d).sum(axis=1), 1e-300))
        got = (tables.sx, tables.sy, tables.ex, tables.ey, tables.ee)
        assert all(g.tobytes() == w.tobytes() for g, w in zip(got, want, strict=True)), i


def _rollout_step_by_step(position, heading, speed, headings, speeds, starts, ends, radius,
                          step=0.25, n_steps=18, max_turn_rate=math.pi / 2, max_accel=1.0):
    """rollout's model with the edge test at every step (the oracle of its shortcut for
    paths that cannot reach an edge)."""
    k = len(headings)
    xy = np.tile(position, (k, 1))
    theta, v = np.full(k, heading), np.full(k, speed)
    gap = np.full(k, _segment_distances_clip(xy[:1], starts, ends)[0])
    out = np.empty((k, n_steps, 2))
    for i in range(n_steps):
        turn = np.remainder(headings - theta + math.pi, 2.0 * math.pi) - math.pi
        theta = theta + np.clip(turn, -max_turn_rate * step, max_turn_rate * step)
        v = v + np.clip(speeds - v, -max_accel * step, max_accel * step)
        moved = xy + (v * step)[:, None] * np.stack([np.cos(theta), np.sin(theta)], axis=1)
        new_gap = _segment_distances_clip(moved, starts, ends)
        ok = (new_gap >= radius) | (new_gap >= gap)
        xy = np.where(ok[:, None], moved, xy)
        gap = np.where(ok, new_gap, gap)
        v = np.where(ok, v, 0.0)
        out[:, i] = xy
    return out


def test_rollout_shortcut_matches_the_step_by_step_model():
    rng = np.random.default_rng(6)
    for _ in range(600):
        e, k = rng.integers(1, 6), rng.integers(1, 12)
        starts = rng.uniform(-15, 15, (e, 2))
        ends = starts + rng.uniform(-6, 6, (e, 2))
        position, heading = rng.uniform(-3, 3, 2), rng.uniform(-math.pi, math.pi)
        speed = rng.uniform(0.0, 2.0)
        headings = rng.uniform(-math.pi, math.pi, k)
        speeds = rng.choice([0.0, 0.5, 1.0, 2.0], k)
        if rng.random() < 0.3:      # turns and speed changes exactly at their limits
            speed = float(rng.choice([0.0, 0.25, 0.5]))
            headings = heading + rng.choice([-1.0, 1.0, 0.0, 2.0], k) * (math.pi / 2 * 0.25)
        got = rollout(position, heading, speed, headings, speeds, math.pi / 2, 1.0, 0.25, 18,
                      starts, ends, 0.7)
        want = _rollout_step_by_step(position, heading, speed, headings, speeds, starts, ends,
                                     0.7)
        assert got.tobytes() == want.tobytes()      # bit for bit, signs of zeros included


def _walls_and_starts(rng, e):
    starts = rng.uniform(-6, 6, (e, 2))
    return starts, starts + rng.uniform(-6, 6, (e, 2))


@pytest.mark.skipif(not lookahead.SCALAR_TRIG, reason="math's cos/sin differ from NumPy's here")
def test_one_candidate_rollout_in_floats_is_the_array_code_bit_for_bit(monkeypatch):
    # the Python-float path (one candidate, clearance certificates) against the array path
    rng = np.random.default_rng(7)
    cases = []
    for _ in range(400):
        e = int(rng.integers(0, 7))
        starts, ends = _walls_and_starts(rng, e)
        args = (rng.uniform(-4, 4, 2), rng.uniform(-math.pi, math.pi), rng.uniform(0.0, 2.0),
                rng.uniform(-4, 4, 1), rng.choice([0.0, 0.5, 1.0, 2.0], 1), math.pi / 2, 1.0,
                0.25, 18, starts, ends, float(rng.choice([0.3, 0.7, 1.5])))
        cases.append((args, rollout(*args)))
    monkeypatch.setattr(lookahead, "SCALAR_TRIG", False)
    refused = 0
    for args, fast in cases:
        slow = rollout(*args)
        np.testing.assert_array_equal(fast, slow)
        refused += bool((np.diff(slow[0], axis=0) == 0.0).all(axis=1).any())
    assert refused > 20                  # steps held at a wall were exercised


@pytest.mark.skipif(not lookahead.SCALAR_TRIG, reason="math's cos/sin differ from NumPy's here")
def test_obstacle_prediction_in_floats_is_the_array_code_bit_for_bit(monkeypatch):
    rng = np.random.default_rng(8)
    cases = []
    for _ in range(300):
        m, e = int(rng.integers(1, 5)), int(rng.integers(1, 7))
        states = np.column_stack([rng.uniform(-8, 8, (m, 2)), rng.uniform(-1.5, 1.5, (m, 2))])
        starts, ends = _walls_and_starts(rng, e)
        args = (states, 0.25, 18, starts, ends, np.full(m, float(rng.choice([0.5, 1.0]))))
        cases.append((args, predict_obstacles(*args)))
    monkeypatch.setattr(lookahead, "SCALAR_TRIG", False)
    bounced = 0
    for args, fast in cases:
        slow = predict_obstacles(*args)
        np.testing.assert_array_equal(fast, slow)
        straight = args[0][:, None, :2] + 0.25 * np.arange(1, 19)[None, :, None] * args[0][
            :, None, 2:]
        bounced += bool(np.abs(slow - straight).max() > 1e-6)
    assert bounced > 20                  # bounces were exercised


def test_many_candidates_near_walls_match_the_step_by_step_model():
    # the array rollout's clearance certificates (edge tests skipped for rows provably clear)
    # against the model that tests every row at every step, with the look-ahead's candidates
    rng = np.random.default_rng(9)
    held = 0
    for _ in range(150):
        e = int(rng.integers(1, 8))
        starts, ends = _walls_and_starts(rng, e)
        position, heading = rng.uniform(-4, 4, 2), rng.uniform(-math.pi, math.pi)
        speed = rng.uniform(0.0, 2.0)
        headings, speeds = candidate_commands(heading, 2.0, 16, (rng.uniform(-4, 4),))
        radius = float(rng.choice([0.3, 0.7, 1.5]))
        fast = rollout(position, heading, speed, headings, speeds, math.pi / 2, 1.0, 0.25, 18,
                       starts, ends, radius)
        slow = _rollout_step_by_step(position, heading, speed, headings, speeds, starts, ends,
                                     radius)
        np.testing.assert_array_equal(fast, slow)
        held += int((np.diff(slow, axis=1) == 0.0).all(axis=2).any(axis=1)[:-1].sum())
    assert held > 100                     # refused steps were exercised


def _position_std_arrays(covariances, times):
    """position_std before issue 20's ninth round (the array form; the oracle)."""
    p = np.asarray(covariances, dtype=np.float64).reshape(-1, 4, 4)
    t = np.asarray(times, dtype=np.float64)[None, :]
    pv = p[:, :2, 2:] + p[:, 2:, :2].transpose(0, 2, 1)
    a = p[:, 0, 0, None] + t * pv[:, 0, 0, None] + t * t * p[:, 2, 2, None]
    c = p[:, 1, 1, None] + t * pv[:, 1, 1, None] + t * t * p[:, 3, 3, None]
    b = (p[:, 0, 1, None] + 0.5 * t * (pv[:, 0, 1, None] + pv[:, 1, 0, None])
         + t * t * p[:, 2, 3, None])
    largest = 0.5 * (a + c) + np.sqrt(0.25 * (a - c) ** 2 + b * b)
    return np.sqrt(np.maximum(largest, 0.0))


def test_position_std_is_the_array_form_bit_for_bit():
    """The compiled position_std against the array form: tracker-like covariances (small,
    symmetric, positive definite), asymmetric and indefinite ones (a floored eigenvalue), at
    the look-ahead's times and at 0."""
    rng = np.random.default_rng(12)
    for _ in range(300):
        m = int(rng.integers(0, 5))
        a = rng.normal(size=(m, 4, 4)) * 10.0 ** rng.uniform(-3, 1)
        p = a @ a.transpose(0, 2, 1) + 1e-4 * np.eye(4) if rng.random() < 0.7 else a
        times = np.concatenate([[0.0], 0.25 * np.arange(1, 19)]) if rng.random() < 0.5 \
            else rng.uniform(0.0, 10.0, int(rng.integers(1, 20)))
        got, want = position_std(p, times), _position_std_arrays(p, times)
        assert got.shape == want.shape and got.tobytes() == want.tobytes()


def _violation_arrays(paths, centres, radii, clearance):
    """violation before issue 20's ninth round (NumPy's arrays; the oracle)."""
    d = paths[:, None, :, :] - centres[None, :, :, :]
    gap = np.sqrt((d * d).sum(axis=3)) - radii[None, :, :]
    return np.maximum(clearance - gap.min(axis=1), 0.0).sum(axis=1)


def test_violation_is_the_array_form_bit_for_bit():
    """The compiled shortfalls against the array form: the look-ahead's 52 candidates of 18
    steps and other shapes, clearances 0 (contacts) and positive, obstacles near and far (all
    shortfalls zero, some, all positive), and over the first steps only (imminence)."""
    from aoass_env.safety.lookahead import _shortfalls
    rng = np.random.default_rng(13)
    positive = 0
    for i in range(400):
        k = 52 if i % 3 == 0 else int(rng.integers(1, 12))
        s = 18 if i % 2 == 0 else int(rng.integers(1, 140))
        m = int(rng.integers(1, 5))
        paths = rng.normal(0.0, 2.0, (k, s, 2))
        centres = rng.normal(0.0, float(rng.choice([1.0, 3.0, 30.0])), (m, s, 2))
        radii = rng.uniform(0.5, 2.5, (m, s))
        clearance = float(rng.choice([0.0, 0.5, 1.0]))
        want = _violation_arrays(paths, centres, radii, clearance)
        got = violation(paths, centres, radii, clearance)
        assert got.tobytes() == want.tobytes()
        soon = int(rng.integers(1, s + 1))
        want = _violation_arrays(paths[:, :soon], centres[:, :soon], radii[:, :soon], clearance)
        assert _shortfalls(paths, centres, radii, clearance, soon).tobytes() == want.tobytes()
        positive += int((want > 0.0).sum())
    assert positive > 1000


def test_mismatched_candidates_or_obstacles_name_the_arrays():
    """The compiled loops read the arrays by index: mismatched shapes are a clear error."""
    with pytest.raises(ValueError, match="headings and speeds"):
        rollout(np.zeros(2), 0.0, 1.0, np.zeros(3), np.zeros(2), 1.0, 1.0, 0.25, 18,
                np.zeros((0, 2)), np.zeros((0, 2)), 0.5)
    paths = np.zeros((2, 18, 2))
    with pytest.raises(ValueError, match="centres must be"):
        violation(paths, np.zeros((1, 17, 2)), np.zeros((1, 17)), 1.0)
    with pytest.raises(ValueError, match="centres must be"):
        violation(paths, np.zeros((1, 18, 2)), np.zeros((2, 18)), 1.0)
    with pytest.raises(ValueError, match="paths must be"):
        violation(np.zeros((2, 18)), np.zeros((1, 18, 2)), np.zeros((1, 18)), 1.0)
    with pytest.raises(ValueError, match="points must be"):
        segment_distances(np.zeros(2), np.zeros((1, 2)), np.ones((1, 2)))
    with pytest.raises(ValueError, match="starts and ends must be"):
        segment_distances(np.zeros((1, 2)), np.zeros((2, 2)), np.ones((1, 2)))
    with pytest.raises(ValueError, match="starts and ends must be"):
        rollout(np.zeros(2), 0.0, 1.0, np.zeros(2), np.zeros(2), 1.0, 1.0, 0.25, 18,
                np.zeros((1, 3)), np.zeros((1, 3)), 0.5)


_HEAD_ON = [[3.0, 0.0, -1.0, 0.0, 1.0]]


@pytest.mark.parametrize("kw, match", [
    (dict(obstacles=[[math.nan, 0.0, -1.0, 0.0, 1.0]]), "obstacles and covariances"),
    (dict(covariances=np.full((1, 4, 4), math.inf)), "obstacles and covariances"),
    (dict(horizon=math.nan), "horizon="), (dict(step=0.0), "step="),
    (dict(max_accel=-1.0), "max_accel="), (dict(radius=math.inf), "radius="),
    (dict(sigma=-2.0), "sigma="), (dict(clearance=math.nan), "clearance="),
    (dict(react=-1.0), "react="), (dict(tolerance=math.inf), "tolerance="),
    (dict(obstacle_radius=math.nan), "obstacle_radius="), (dict(n_headings=0), "n_headings="),
    (dict(starts=np.array([[math.nan, 0.0]]), ends=np.array([[1.0, 0.0]])), "static edges"),
])
def test_escape_velocity_refuses_nonfinite_or_negative_inputs(kw, match):
    """A NaN obstacle used to read as nothing in the way (no escape), a NaN horizon crashed
    deep inside; each is now an error naming the argument."""
    obstacles = kw.pop("obstacles", _HEAD_ON)
    covariances = kw.pop("covariances", None)
    with pytest.raises(ValueError, match=match):
        _escape([1.0, 0.0], obstacles, covariances, **kw)
    assert _escape([1.0, 0.0], _HEAD_ON).escaping      # the same call, valid, escapes


@pytest.mark.parametrize("where, match", [
    ("velocity", "velocity must be a pair of finite"),
    ("position", "position must be a pair of finite"),
    ("heading", "heading="), ("speed", "speed="),
])
def test_escape_velocity_refuses_a_nonfinite_anchor(where, match):
    args = dict(velocity=np.array([1.0, 0.0]), preferred=np.array([1.0, 0.0]),
                position=np.zeros(2), heading=0.0, speed=1.0)
    args[where] = np.array([math.nan, 0.0]) if where in ("velocity", "position") else (
        -1.0 if where == "speed" else math.nan)
    with pytest.raises(ValueError, match=match):
        escape_velocity(**args, obstacles=np.array(_HEAD_ON),
                        covariances=np.tile(np.eye(4) * 0.01, (1, 1, 1)), max_speed=2.0,
                        max_accel=1.0, max_turn_rate=math.pi / 2, horizon=4.5, step=0.25,
                        starts=np.zeros((0, 2)), ends=np.zeros((0, 2)), radius=0.7, sigma=2.0,
                        maneuver=0.25, clearance=0.5)


@pytest.mark.parametrize("kw, match", [
    (dict(heading=math.nan), "heading="), (dict(speeds=np.array([math.nan])), "speeds"),
    (dict(position=np.array([0.0, math.inf])), "position must be"),
    (dict(max_turn_rate=0.0), "max_turn_rate="), (dict(n_steps=0), "n_steps="),
    (dict(n_steps=2.5), "n_steps="),
])
def test_rollout_refuses_nonfinite_or_bad_inputs(kw, match):
    args = dict(position=np.zeros(2), heading=0.0, speed=0.5, headings=np.array([0.0]),
                speeds=np.array([1.0]), max_turn_rate=0.6, max_accel=0.5, step=0.25,
                n_steps=4, starts=np.zeros((0, 2)), ends=np.zeros((0, 2)), radius=0.5)
    with pytest.raises(ValueError, match=match):
        rollout(**dict(args, **kw))
    assert rollout(**dict(args, n_steps=4.0)).shape == (1, 4, 2)     # a whole float is a count


def test_the_horizon_and_the_budget_refuse_bad_input_naming_it():
    """look_ahead_horizon divided by zero (a traceback) and took a negative speed; a NaN period
    spent the escape budget for good (spent NaN: it could never yield again)."""
    from aoass_env.safety.lookahead import EscapeBudget, look_ahead_horizon
    assert look_ahead_horizon(2.0, 1.0, 1.0, 0.5) == pytest.approx(0.5 + 2.0 + math.pi)
    for args, name in (((2.0, 0.0, 1.0, 0.5), "max_accel"), ((-1.0, 1.0, 1.0, 0.5), "max_speed"),
                       ((2.0, 1.0, 0.0, 0.5), "max_turn_rate"), ((2.0, 1.0, 1.0, math.nan), "dt")):
        with pytest.raises(ValueError, match=rf"^{name}="):
            look_ahead_horizon(*args)
    budget = EscapeBudget(budget=5.0, refill=0.5)
    for dt in (math.nan, -0.5, math.inf):
        with pytest.raises(ValueError, match=r"^dt="):
            budget.update(True, dt)
    assert budget.spent == 0.0
