"""Constant-velocity multi-target tracker (aoass_env.safety.kalman)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from aoass_env.safety.kalman import MultiTargetTracker

DT = 0.5          # s, the env's control period
SIGMA_P = 0.3     # m, the env's observation noise on obstacle positions
SIGMA_V = 0.2     # m/s, on obstacle velocities


def cv_truth(p0, v0, steps: int) -> np.ndarray:
    """(steps, 4) states of a constant-velocity target after 1..steps periods."""
    k = np.arange(1, steps + 1)[:, None]
    p = np.asarray(p0, float) + k * DT * np.asarray(v0, float)
    return np.hstack([p, np.broadcast_to(np.asarray(v0, float), p.shape)])


def noisy(truth: np.ndarray, rng: np.random.Generator, velocities: bool) -> np.ndarray:
    """Detections of the states ``truth`` (n, 4): positions (+ velocities) with noise."""
    z = truth[:, :2] + rng.normal(0, SIGMA_P, (len(truth), 2))
    if velocities:
        z = np.hstack([z, truth[:, 2:] + rng.normal(0, SIGMA_V, (len(truth), 2))])
    return z


@pytest.mark.parametrize("process_noise, maneuver_speed, pos_tol, vel_tol", [
    (0.05, None, 0.8 * SIGMA_P, 0.3 * SIGMA_P),   # a plain CV filter that trusts the model
    (0.5, 2.0, SIGMA_P, SIGMA_P),                 # the defaults, made for turning obstacles
])
def test_cv_track_converges_from_positions_only(process_noise, maneuver_speed, pos_tol,
                                                vel_tol):
    """Velocity from positions alone: per-axis RMS errors over steps 10-30 are below the
    position noise (m), the velocity's (m/s) well below it for the plain CV filter."""
    rng = np.random.default_rng(1)
    tr = MultiTargetTracker(DT, position_noise=SIGMA_P, velocity_noise=None,
                            process_noise=process_noise, maneuver_speed=maneuver_speed)
    truth = cv_truth((10.0, 20.0), (0.8, -0.4), 30)
    err = []
    for x in truth:
        tr.step(noisy(x[None], rng, velocities=False))
        err.append(tr.states(confirmed_only=False)[0] - x)
    assert [t.id for t in tr.confirmed] == [0]
    e = np.array(err[10:])
    assert np.sqrt(np.mean(e[:, :2] ** 2)) < pos_tol
    assert np.sqrt(np.mean(e[:, 2:] ** 2)) < vel_tol


def test_estimates_are_consistent_with_their_covariance():
    """Truth driven by the model's own white acceleration: the mean NEES over 40 runs is near
    the state dimension 4 (Q, R, P0 and the gating are coherent)."""
    f = np.eye(4)
    f[0, 2] = f[1, 3] = DT
    q = 0.5
    cov = q * q * np.kron([[DT ** 4 / 4, DT ** 3 / 2], [DT ** 3 / 2, DT ** 2]], np.eye(2))
    root = np.linalg.cholesky(cov + 1e-12 * np.eye(4))
    for velocities in (False, True):
        rng = np.random.default_rng(10)
        nees = []
        for _ in range(40):
            tr = MultiTargetTracker(DT, position_noise=SIGMA_P, process_noise=q,
                                    velocity_noise=SIGMA_V if velocities else None)
            x = np.r_[rng.uniform(0, 50, 2), rng.uniform(-1, 1, 2)]
            for _ in range(20):
                x = f @ x + root @ rng.normal(size=4)
                tr.step(noisy(x[None], rng, velocities))
            (t,) = tr.confirmed
            e = t.state - x
            nees.append(e @ np.linalg.solve(t.covariance, e))
        assert 2.8 < np.mean(nees) < 5.6, velocities


def test_measured_velocities_are_fused():
    rng = np.random.default_rng(2)
    tr = MultiTargetTracker(DT, position_noise=SIGMA_P, velocity_noise=SIGMA_V)
    truth = cv_truth((0.0, 0.0), (1.0, 0.5), 30)
    tr.step(noisy(truth[:1], rng, velocities=True))
    born = tr.tracks[0].state
    assert np.hypot(*(born[2:] - truth[0, 2:])) < 4 * SIGMA_V   # velocity from the detection
    err = []
    for x in truth[1:]:
        tr.step(noisy(x[None], rng, velocities=True))
        err.append(tr.states()[0] - x)
    rms = np.sqrt(np.mean(np.square(err[-20:]), axis=0))      # per axis, default noise levels
    assert (rms[:2] < SIGMA_P).all() and (rms[2:] < SIGMA_V).all()


def maneuvering_run(tracker: MultiTargetTracker, seed: int, turn: tuple[float, float],
                    velocities: bool) -> tuple[bool, float]:
    """Env-like target at 1 m/s turning by ``turn`` (rad, either side) every 10 s for 60 s.
    Returns (the target kept track id 0 alone from step 2 on, largest position error (m))."""
    rng = np.random.default_rng(seed)
    p, heading, kept, worst = np.array([50.0, 50.0]), 0.0, True, 0.0
    for k in range(120):
        if k and k % 20 == 0:
            heading += rng.choice([-1, 1]) * rng.uniform(*turn)
        truth = np.r_[p + DT * np.array([math.cos(heading), math.sin(heading)]),
                      math.cos(heading), math.sin(heading)]
        p = truth[:2]
        tracker.step(noisy(truth[None], rng, velocities))
        if k >= 2:
            kept &= [t.id for t in tracker.confirmed] == [0]
            if kept:
                worst = max(worst, float(np.hypot(*(tracker.states()[0, :2] - p))))
    return kept, worst


@pytest.mark.parametrize("velocity_noise", [None, SIGMA_V])
def test_maneuvering_target_keeps_its_track(velocity_noise):
    """Turns of 60-120 degrees at 1 m/s with the default noise levels: one track throughout."""
    tr = MultiTargetTracker(DT, position_noise=SIGMA_P, velocity_noise=velocity_noise)
    kept, worst = maneuvering_run(tr, 3, (math.pi / 3, 2 * math.pi / 3),
                                  velocity_noise is not None)
    assert kept and worst < 1.5


def test_maneuver_stage_is_what_keeps_a_reversing_target():
    """U-turns (Delta v ~ 2 m/s in one period) break the track without the maneuver stage."""
    turn = (0.9 * math.pi, math.pi)
    on = MultiTargetTracker(DT, position_noise=SIGMA_P, velocity_noise=None)
    off = MultiTargetTracker(DT, position_noise=SIGMA_P, velocity_noise=None,
                             maneuver_speed=None)
    assert maneuvering_run(on, 8, turn, False)[0]
    assert not maneuvering_run(off, 8, turn, False)[0]


def test_crossing_targets_keep_their_ids():
    rng = np.random.default_rng(4)
    tr = MultiTargetTracker(DT, position_noise=SIGMA_P, velocity_noise=None)
    a = cv_truth((0.0, 0.0), (1.0, 1.0), 60)        # they cross at (15, 15) at step 30
    b = cv_truth((30.0, 0.0), (-1.0, 1.0), 60)
    owner = {}
    for k in range(60):
        order = rng.permutation(2)                   # detections arrive in any order
        tr.step(noisy(np.stack([a[k], b[k]])[order], rng, velocities=False))
        assert len(tr.confirmed) <= 2
        if k >= 2:
            assert len(tr.confirmed) == 2, k
        if abs(k - 29) > 6:                          # well separated (> 8 m apart)
            for t in tr.confirmed:
                pos = t.state[:2]
                which = "a" if np.hypot(*(pos - a[k, :2])) < np.hypot(*(pos - b[k, :2])) \
                    else "b"
                assert owner.setdefault(t.id, which) == which, (k, t.id)
    assert sorted(owner.values()) == ["a", "b"]


def test_birth_needs_birth_hits_detections():
    tr = MultiTargetTracker(DT, position_noise=SIGMA_P, velocity_noise=None, birth_hits=3)
    for k in range(3):
        tr.step([[5.0, 5.0]])
        assert len(tr.tracks) == 1
        assert tr.tracks[0].hits == k + 1
        assert len(tr.confirmed) == (1 if k == 2 else 0)
    assert tr.states().shape == (1, 4) and tr.states(confirmed_only=False).shape == (1, 4)
    once = MultiTargetTracker(DT, position_noise=SIGMA_P, velocity_noise=None, birth_hits=1)
    once.step([[5.0, 5.0], [20.0, 5.0]])
    assert [t.id for t in once.confirmed] == [0, 1] and once.n_tracks == 2


def test_tentative_track_dies_at_first_miss():
    tr = MultiTargetTracker(DT, position_noise=SIGMA_P, velocity_noise=None, birth_hits=3)
    tr.step([[5.0, 5.0]])
    tr.step([[5.0, 5.0]])
    assert tr.n_tracks == 1
    tr.step(np.zeros((0, 2)))
    assert tr.tracks == [] and tr.n_tracks == 0


def test_confirmed_track_deleted_after_max_misses():
    tr = MultiTargetTracker(DT, position_noise=SIGMA_P, velocity_noise=None, max_misses=3)
    for k in range(4):
        tr.step([[1.0 + 0.5 * k, 2.0]])
    (t,) = tr.confirmed
    before = t.state
    for miss in (1, 2):
        tr.step([])
        assert tr.confirmed == [t] and t.misses == miss
    np.testing.assert_allclose(t.state[:2], before[:2] + 2 * DT * before[2:])   # coasts
    tr.step([])
    assert tr.tracks == []
    # a detection in between resets the count
    for k in range(4):
        tr.step([[1.0 + 0.5 * k, 2.0]])
    tr.step([])
    tr.step([])
    tr.step([[4.0, 2.0]])
    tr.step([])
    tr.step([])
    assert len(tr.confirmed) == 1 and tr.confirmed[0].misses == 2


def test_far_clutter_does_not_hijack_a_track():
    rng = np.random.default_rng(5)
    tr = MultiTargetTracker(DT, position_noise=SIGMA_P, velocity_noise=None)
    truth = cv_truth((10.0, 10.0), (0.6, 0.2), 20)
    for x in truth[:-1]:
        tr.step(noisy(x[None], rng, velocities=False))
    (t,) = tr.confirmed
    # the true detection is missing this step; clutter 4 m away must stay out of the gate
    tr.step([truth[-1, :2] + [4.0, 0.0]])
    assert t.misses == 1 and tr.confirmed == [t]
    assert np.hypot(*(t.state[:2] - truth[-1, :2])) < 1.0                 # coasted
    assert len(tr.tracks) == 2 and not tr.tracks[1].confirmed      # the clutter's own track
    # with both present, the track takes the true one; clutter is born elsewhere
    nxt = cv_truth(truth[-1, :2], truth[-1, 2:], 1)[0]
    tr.step([nxt[:2] + [-30.0, 5.0], nxt[:2]])
    assert t.misses == 0
    assert np.hypot(*(t.state[:2] - nxt[:2])) < 0.5
    assert [u.id for u in tr.tracks] == [0, 2]


def test_predictions_follow_the_cv_model_and_change_nothing():
    rng = np.random.default_rng(6)
    tr = MultiTargetTracker(DT, position_noise=SIGMA_P, velocity_noise=None)
    for x in cv_truth((3.0, 4.0), (1.0, -0.5), 10):
        tr.step(noisy(np.stack([x, x + [20, 0, 0, 1]]), rng, velocities=False))
    states, covs = tr.states(), [t.covariance for t in tr.confirmed]
    for h in (0.0, 0.3, DT, 2.75):
        np.testing.assert_allclose(tr.predict_positions(h), states[:, :2] + h * states[:, 2:])
    f = np.eye(4)
    f[0, 2] = f[1, 3] = DT
    for k in (0, 1, 4):
        expected = (np.linalg.matrix_power(f, k) @ states.T).T[:, :2]
        np.testing.assert_allclose(tr.predict_steps(k), expected, atol=1e-12)
    np.testing.assert_array_equal(tr.states(), states)
    for t, c in zip(tr.confirmed, covs, strict=True):
        np.testing.assert_array_equal(t.covariance, c)
    assert tr.predict_positions(1.0, confirmed_only=False).shape == (2, 2)
    assert MultiTargetTracker(DT, position_noise=1, velocity_noise=None) \
        .predict_positions(1.0).shape == (0, 2)


def test_state_and_covariance_are_copies():
    tr = MultiTargetTracker(DT, position_noise=SIGMA_P, velocity_noise=None, birth_hits=1)
    tr.step([[1.0, 2.0]])
    t = tr.tracks[0]
    t.state[0] = 99.0
    t.covariance[0, 0] = 99.0
    assert t.state[0] == 1.0 and t.covariance[0, 0] == pytest.approx(SIGMA_P ** 2)
    np.testing.assert_array_equal(t.state, [1.0, 2.0, 0.0, 0.0])


def test_deterministic_and_reset():
    rng = np.random.default_rng(7)
    frames = [rng.uniform(0, 30, (rng.integers(0, 4), 2)) for _ in range(25)]

    def run(tr: MultiTargetTracker):
        out = []
        for z in frames:
            tr.step(z)
            out.append(([t.id for t in tr.tracks], tr.states(confirmed_only=False)))
        return out

    tr = MultiTargetTracker(DT, position_noise=1.0, velocity_noise=None)
    first = run(tr)
    second = run(MultiTargetTracker(DT, position_noise=1.0, velocity_noise=None))
    tr.reset()
    assert tr.tracks == []
    third = run(tr)
    for (ia, sa), (ib, sb), (ic, sc) in zip(first, second, third, strict=True):
        assert ia == ib == ic
        np.testing.assert_array_equal(sa, sb)
        np.testing.assert_array_equal(sa, sc)


@pytest.mark.parametrize("kwargs, name", [
    ({"dt": 0.0}, "dt"), ({"dt": -1.0}, "dt"), ({"dt": math.nan}, "dt"),
    ({"position_noise": 0.0}, "position_noise"), ({"position_noise": math.inf}, "position_noise"),
    ({"velocity_noise": -0.1}, "velocity_noise"), ({"process_noise": 0.0}, "process_noise"),
    ({"gate": 0.0}, "gate"), ({"gate": 1.0}, "gate"), ({"gate": math.nan}, "gate"),
    ({"birth_hits": 0}, "birth_hits"), ({"birth_hits": 1.5}, "birth_hits"),
    ({"birth_hits": True}, "birth_hits"), ({"max_misses": 0}, "max_misses"),
    ({"initial_speed_std": -2.0}, "initial_speed_std"),
    ({"dt": "fast"}, "dt"), ({"gate": None}, "gate"),
    ({"maneuver_speed": 0.0}, "maneuver_speed"), ({"maneuver_speed": math.inf}, "maneuver_speed"),
])
def test_bad_parameters(kwargs, name):
    args = {"dt": DT, "position_noise": SIGMA_P, "velocity_noise": None} | kwargs
    with pytest.raises(ValueError, match=name):
        MultiTargetTracker(args.pop("dt"), **args)


@pytest.mark.parametrize("velocity_noise, detections", [
    (None, [[1.0, 2.0, 3.0]]), (None, [1.0, 2.0]), (None, [[[1.0, 2.0]]]),
    (None, [[1.0, 2.0, 0.0, 0.0]]), (SIGMA_V, [[1.0, 2.0]]), (None, [[1.0, math.nan]]),
    (None, [[1.0, math.inf]]), (None, [["a", "b"]]),
])
def test_bad_detections(velocity_noise, detections):
    tr = MultiTargetTracker(DT, position_noise=SIGMA_P, velocity_noise=velocity_noise)
    with pytest.raises(ValueError, match="detections"):
        tr.step(detections)
    assert tr.tracks == []


def test_empty_detections_and_bad_horizons():
    tr = MultiTargetTracker(DT, position_noise=SIGMA_P, velocity_noise=SIGMA_V)
    for empty in ([], np.zeros((0, 4)), np.zeros(0)):
        tr.step(empty)
    assert tr.tracks == []
    with pytest.raises(ValueError, match="horizon"):
        tr.predict_positions(-0.1)
    with pytest.raises(ValueError, match="horizon"):
        tr.predict_positions(math.nan)
    for k in (-1, 1.5, True):
        with pytest.raises(ValueError, match="k="):
            tr.predict_steps(k)


def test_stacked_queries_are_np_stack_bit_for_bit():
    """states() and covariances() (np.array over the tracks) give np.stack's arrays, for every
    number of tracks a run of crossing, appearing and vanishing targets passes through."""
    rng = np.random.default_rng(12)
    tracker = MultiTargetTracker(0.5, position_noise=0.3, velocity_noise=0.2)
    seen = set()
    for k in range(200):
        n = int(rng.integers(0, 5))
        z = np.column_stack([rng.uniform(-1, 1, (n, 2)) + np.arange(n)[:, None] * 3.0 + 0.1 * k,
                             rng.uniform(-1, 1, (n, 2))])
        tracker.step(z)
        for confirmed_only in (True, False):
            sel = tracker.confirmed if confirmed_only else tracker.tracks
            states, covariances = tracker.states(confirmed_only), tracker.covariances(
                confirmed_only)
            seen.add(len(sel))
            if sel:
                for got, want in ((states, np.stack([t.filter.x[:, 0] for t in sel])),
                                  (covariances, np.stack([t.filter.P for t in sel]))):
                    assert got.tobytes() == want.tobytes() and got.shape == want.shape
                    assert got.dtype == want.dtype and got.flags.c_contiguous
    assert {0, 1, 2, 3} <= seen


def _random_tracks(tracker: MultiTargetTracker, rng: np.random.Generator, m: int) -> list:
    """``m`` confirmed tracks at random states with random SPD covariances (as a run leaves
    them: predicted, inflated, updated)."""
    tracks = []
    for _ in range(m):
        t = tracker._birth(rng.uniform(-3, 3, tracker._dz))
        t.filter.x[:, 0] = rng.uniform(-3, 3, 4)
        a = rng.normal(0, rng.uniform(0.05, 1.5), (4, 4))
        t.filter.P = a @ a.T + 0.01 * np.eye(4)
        t.confirmed = True
        tracks.append(t)
    return tracks


def _associated(tracker, tracks, z, extra, fast: bool, monkeypatch) -> tuple:
    """:meth:`_associate`'s pairs, free mask and unpaired tracks, with or without the compiled
    path."""
    with monkeypatch.context() as patch:
        if not fast:
            patch.setattr(tracker, "_nearest", lambda *args: None)
        free, pairs = np.ones(len(z), bool), []
        left = tracker._associate(tracks, z, free, pairs, extra)
    return [(t.id, j) for t, j in pairs], free.tolist(), [t.id for t in left]


@pytest.mark.parametrize("velocity_noise", [None, 0.2])
@pytest.mark.parametrize("maneuver", [False, True])
def test_compiled_association_decides_as_numpy(velocity_noise, maneuver, monkeypatch):
    """One track and several detections, or several tracks and one detection (the cases the
    compiled gate takes): the same pairs, detections used and tracks left as NumPy's inverse
    and linear_sum_assignment, over draws that put many detections near the gate; the compiled
    distances are NumPy's to 1e-12."""
    from aoass_env.safety.kalman import _gate_distances
    rng = np.random.default_rng(31 + (velocity_noise is None) + 2 * maneuver)
    tracker = MultiTargetTracker(DT, position_noise=SIGMA_P, velocity_noise=velocity_noise)
    dz = tracker._dz
    outcomes = set()
    for draw in range(300):
        m, n = (1, int(rng.integers(1, 5))) if draw % 2 else (int(rng.integers(1, 5)), 1)
        tracks = _random_tracks(tracker, rng, m)
        z = tracks[0].filter.x[:dz, 0] + rng.normal(0, rng.uniform(0.1, 3.0), (n, dz))
        extra = tracker._dQ if maneuver else None
        fast = _associated(tracker, tracks, z, extra, True, monkeypatch)
        assert fast == _associated(tracker, tracks, z, extra, False, monkeypatch)
        outcomes.add(len(fast[0]))
        for t in tracks:
            s = t.filter.P[:dz, :dz] + tracker._R + (0.0 if extra is None else extra[:dz, :dz])
            y = z - t.filter.x[:dz, 0]
            want = ((y @ np.linalg.inv(s)) * y).sum(axis=1)
            got = np.empty(n)
            assert _gate_distances(t.filter.x, t.filter.P, tracker._R,
                                   tracker._no_extra if extra is None else extra, z,
                                   np.arange(n), got)
            np.testing.assert_allclose(got, want, rtol=1e-12)
    assert outcomes == {0, 1}                # draws both inside and outside the gate


def test_compiled_association_defers_near_the_gate_and_on_ties():
    """Within the decision band of the gate, or of another gated distance, NumPy decides
    (None); otherwise the gated entry of least distance, or no pair."""
    from aoass_env.safety.kalman import _DECISION_BAND, _nearest_pairs
    gate = 13.28
    near = gate * (1 + 0.5 * _DECISION_BAND)
    assert _nearest_pairs(np.array([[near, 1.0]]), gate, _DECISION_BAND) is None
    assert _nearest_pairs(np.array([[2.0], [2.0 + 1e-9]]), gate, _DECISION_BAND) is None
    assert _nearest_pairs(np.array([[np.nan]]), gate, _DECISION_BAND) is None
    assert _nearest_pairs(np.array([[3.0], [2.0], [20.0]]), gate, _DECISION_BAND).tolist() \
        == [[1, 0]]
    assert _nearest_pairs(np.array([[30.0, 14.0]]), gate, _DECISION_BAND).shape == (0, 2)


def test_compiled_association_is_taken_in_a_run():
    """The tracker of a single target pairs it by the compiled path (not NumPy's fallback)."""
    tracker = MultiTargetTracker(DT, position_noise=SIGMA_P, velocity_noise=SIGMA_V)
    truth = cv_truth([0.0, 0.0], [0.8, 0.3], 5)
    for z in noisy(truth, np.random.default_rng(3), True):
        tracker.step(z[None])
    tracks = tracker.confirmed
    assert len(tracks) == 1
    tracks[0].filter.predict()
    z = noisy(cv_truth(truth[-1, :2], truth[-1, 2:], 1), np.random.default_rng(4), True)
    assert tracker._nearest(tracks, z, np.arange(1), None).tolist() == [[0, 0]]
