"""Tests of aoass_env.network: the Eq. 18 coverage criterion and the energy ledger."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env.config import AOASSConfig
from aoass_env.network import Network, lambda_min, residual_after

CONFIG = AOASSConfig()


def reference_residual(points: np.ndarray) -> float:
    """Root-sum-square distance of points to their total-least-squares line (via SVD)."""
    if len(points) < 2:
        return 0.0
    centred = points - points.mean(axis=0)
    return float(np.linalg.svd(centred, compute_uv=False)[-1])


def assert_residual_matches(got: float, points: np.ndarray) -> None:
    """lambda_min = residual^2 agrees with SVD up to float noise, 1e-12 x trace(S)."""
    trace = float(((points - points.mean(axis=0)) ** 2).sum())
    assert abs(got ** 2 - reference_residual(points) ** 2) <= 1e-12 * trace


def test_three_collinear_beacons_do_not_cover_and_an_offset_one_does():
    net = Network(1, CONFIG)
    for x in (10.0, 20.0, 30.0):
        assert net.record_beacon(np.array([x, 50.0]), np.array([0])) == 0
    assert net.heard[0] == 3 and not net.covered[0]
    assert net.record_beacon(np.array([20.0, 52.0]), np.array([0])) == 1
    assert net.covered[0] and net.n_covered == 1 and net.coverage_ratio == 1.0
    assert net.record_beacon(np.array([40.0, 40.0]), np.array([0])) == 0  # already covered


def test_two_beacons_never_cover():
    net = Network(1, CONFIG)
    net.record_beacon(np.array([0.0, 0.0]), np.array([0]))
    net.record_beacon(np.array([50.0, 80.0]), np.array([0]))
    assert not net.covered[0]


@pytest.mark.parametrize(("h", "covered"), [(1.2, False), (1.25, True)])
def test_triangle_tolerance(h, covered):
    # Beacons (0, 0), (2, 0), (1, h): the residual is sqrt(2/3) h, so the 1 m tolerance sits
    # at h = sqrt(3/2) = 1.2247 m.
    net = Network(1, CONFIG)
    for p in ((0.0, 0.0), (2.0, 0.0), (1.0, h)):
        net.record_beacon(np.array(p), np.array([0]))
    assert net.line_residual[0] == pytest.approx(math.sqrt(2 / 3) * h, rel=1e-12)
    assert net.covered[0] == covered


def test_tolerance_comes_from_config():
    beacons = [(0.0, 0.0), (4.0, 0.0), (0.0, 2.0), (4.0, 2.0)]  # residual exactly 2 m
    for tol, covered in ((1.0, True), (2.0, True), (2.5, False)):
        net = Network(1, CONFIG.replace(collinearity_tol=tol))
        for p in beacons:
            net.record_beacon(np.array(p), np.array([0]))
        assert net.line_residual[0] == pytest.approx(2.0, rel=1e-12)
        assert net.covered[0] == covered


@pytest.mark.parametrize("angle", [0.0, 0.3, math.pi / 2, 2.0])
def test_many_collinear_beacons_never_cover(angle):
    # 2000 beacons on a 1.6 km line far from the origin: cancellation must not fake a spread.
    net = Network(3, CONFIG.replace(field_size=2000.0))
    direction = np.array([math.cos(angle), math.sin(angle)])
    for s in np.linspace(0.0, 1600.0, 2000):
        net.record_beacon(np.array([1960.0, 1980.0]) - s * direction, np.array([0, 2]))
    assert net.heard.tolist() == [2000, 0, 2000]
    assert not net.covered.any()
    # Float noise of lambda_min is about eps * lambda_max: residual ~ 1e-3 m here, far below 1 m.
    assert net.line_residual.max() < 1e-2


def test_each_node_follows_its_own_beacons():
    rng = np.random.default_rng(4)
    n = 40
    net = Network(n, CONFIG)
    heard: list[list[np.ndarray]] = [[] for _ in range(n)]
    for _ in range(60):
        p = rng.uniform(0, 100, 2)
        if rng.random() < 0.5:  # collinear stretches along y = 30 for some beacons
            p[1] = 30.0
        idx = np.flatnonzero(rng.random(n) < 0.2)
        before = net.covered.copy()
        new = net.record_beacon(p, idx)
        assert new == np.count_nonzero(net.covered & ~before)
        assert np.all(net.covered >= before)  # monotone
        for i in idx:
            heard[i].append(p)
    for i in range(n):
        pts = np.array(heard[i]).reshape(-1, 2)
        ref = reference_residual(pts)
        assert_residual_matches(net.line_residual[i], pts)
        assert net.heard[i] == len(pts)
        assert net.covered[i] == (len(pts) >= 3 and ref >= 1.0)
    assert net.coverage_ratio == net.covered.mean()


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(0, 100), st.floats(0, 100)), min_size=1, max_size=30))
def test_coverage_is_monotone_and_matches_svd(points):
    net = Network(1, CONFIG)
    was_covered = False
    for k, p in enumerate(points, start=1):
        net.record_beacon(np.array(p), np.array([0]))
        ref = reference_residual(np.array(points[:k]))
        assert_residual_matches(net.line_residual[0], np.array(points[:k]))
        if was_covered:
            assert net.covered[0]
        if abs(ref - 1.0) > 1e-6:  # away from the tolerance, the criterion is unambiguous
            assert net.covered[0] == (was_covered or (k >= 3 and ref >= 1.0))
        was_covered = bool(net.covered[0])


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(0, 20), st.floats(0, 20)), min_size=1, max_size=12),
       st.lists(st.tuples(st.floats(0, 20), st.floats(0, 20)), min_size=1, max_size=5))
def test_residual_after_one_more_beacon_matches_the_svd_of_the_grown_set(heard, extra):
    """``residual_after`` of a node's statistics: the spread it would have with each extra
    beacon alone, against SVD of the heard points plus that one (an uncovered node's
    statistics, which ``Network.scatter`` exposes)."""
    net = Network(1, AOASSConfig(collinearity_tol=100.0))   # points 20 m apart: never covered
    for p in heard:
        net.record_beacon(np.array(p), np.array([0]))
    got = residual_after(int(net.heard[0]), net.beacon_centroid[0], net.scatter[0],
                         np.array(extra))
    assert got.shape == (len(extra),)
    for r, q in zip(got, extra, strict=True):
        assert_residual_matches(float(r), np.array(heard + [q]))


def test_energy_ledger_exact_joules():
    net = Network(4, CONFIG)
    assert net.tx_energy_per_beacon == pytest.approx(256 * (50e-9 + 10e-12 * 25.0 ** 2),
                                                     rel=1e-15)
    assert net.tx_energy_per_beacon == pytest.approx(1.44e-5, rel=1e-12)
    assert net.rx_energy_per_beacon == pytest.approx(1.28e-5, rel=1e-12)
    receivers = [[0, 1], [1], [], [0, 1, 3], [3]]
    for k, idx in enumerate(receivers):
        net.record_beacon(np.array([float(k), 0.0]), np.array(idx, dtype=np.int64))
    net.charge_motion(2.0)
    net.charge_motion(0.5)
    assert net.beacons_sent == 5 and net.receptions == 7
    np.testing.assert_allclose(net.node_energy, np.array([2, 3, 0, 2]) * 1.28e-5, rtol=1e-12)
    np.testing.assert_allclose(net.node_residual_energy, 2.0 - net.node_energy, rtol=1e-15)
    assert net.distance_travelled == 2.5
    assert net.anchor_motion_energy_spent == pytest.approx(2.0, rel=1e-15)
    assert net.anchor_tx_energy == pytest.approx(5 * 1.44e-5, rel=1e-12)
    assert net.anchor_energy == pytest.approx(2.0 + 7.2e-5, rel=1e-12)
    assert net.node_energy_total == pytest.approx(7 * 1.28e-5, rel=1e-12)
    assert net.energy_total == pytest.approx(2.0 + 7.2e-5 + 8.96e-5, rel=1e-12)
    assert net.energy_total == pytest.approx(net.anchor_energy + net.node_energy.sum(),
                                             rel=1e-15)


def test_energy_uses_config_numbers():
    config = CONFIG.replace(packet_bits=1000, e_elec=1e-7, e_amp=1e-9, radio_range=10.0,
                            anchor_motion_energy=2.0)
    net = Network(2, config)
    net.record_beacon(np.array([0.0, 0.0]), np.array([0, 1]))
    net.charge_motion(3.0)
    assert net.anchor_tx_energy == pytest.approx(1000 * (1e-7 + 1e-9 * 100), rel=1e-15)
    np.testing.assert_allclose(net.node_energy, [1e-4, 1e-4], rtol=1e-15)
    assert net.energy_total == pytest.approx(6.0 + 2e-4 + 2e-4, rel=1e-12)


def test_views_are_read_only():
    net = Network(3, CONFIG)
    net.record_beacon(np.array([1.0, 1.0]), np.array([0, 2]))
    for array in (net.heard, net.covered, net.scatter, net.beacon_centroid):
        with pytest.raises(ValueError):
            array[0] = 0
    assert net.heard.tolist() == [1, 0, 1]


def test_empty_receivers_count_the_beacon_only():
    net = Network(2, CONFIG)
    assert net.record_beacon(np.array([1.0, 1.0]), np.array([], dtype=np.int64)) == 0
    assert net.record_beacon(np.array([1.0, 1.0]), []) == 0
    assert net.beacons_sent == 2 and net.receptions == 0 and net.node_energy_total == 0.0


def test_bad_input():
    with pytest.raises(ValueError, match="n_nodes"):
        Network(0, CONFIG)
    with pytest.raises(ValueError, match="n_nodes"):
        Network(2.5, CONFIG)
    with pytest.raises(TypeError, match="AOASSConfig"):
        Network(3, {"radio_range": 25})
    net = Network(3, CONFIG)
    for bad in ([2, 1], [0, 0], [0, 3], [-1, 0], [[0, 1]]):
        with pytest.raises(ValueError, match="receivers"):
            net.record_beacon(np.array([0.0, 0.0]), np.array(bad))
    with pytest.raises(ValueError, match="integer"):
        net.record_beacon(np.array([0.0, 0.0]), np.array([0.0, 1.0]))
    for bad in (np.array([np.nan, 0.0]), np.zeros(3)):
        with pytest.raises(ValueError, match="position"):
            net.record_beacon(bad, np.array([0]))
    for bad in (-1.0, math.inf, math.nan):
        with pytest.raises(ValueError, match="distance"):
            net.charge_motion(bad)
    assert net.beacons_sent == 0 and net.distance_travelled == 0.0


def _array_form(state: dict, p: np.ndarray, idx: np.ndarray, min_scatter: float) -> int:
    """The NumPy array form of Welford's update that ``Network.record_beacon`` ran before its
    compiled loop (kept as the reference, applied to ``state`` in place)."""
    old_cols, new_cols = np.array([0, 0, 1]), np.array([0, 1, 1])
    n = state["heard"][idx] + 1
    mean = state["mean"][idx]
    d_old = p - mean
    mean += d_old / n[:, None]
    d_new = p - mean
    state["scatter"][idx] += d_old[:, old_cols] * d_new[:, new_cols]
    state["mean"][idx] = mean
    state["heard"][idx] = n
    fresh = idx[~state["covered"][idx] & (n >= 3)]
    fresh = fresh[lambda_min(state["scatter"][fresh]) >= min_scatter]
    state["covered"][fresh] = True
    return int(fresh.size)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_nodes=st.integers(1, 40),
       scale=st.sampled_from([1e-3, 1.0, 100.0, 1e6]), tol=st.sampled_from([1e-9, 0.5, 1.0]))
def test_the_compiled_update_is_the_array_form_bit_for_bit(seed, n_nodes, scale, tol):
    """Counts, means, scatters and coverage after every beacon equal, by their bits, the NumPy
    array form's; beacons at nodes' means, repeated and collinear ones included."""
    rng = np.random.default_rng(seed)
    config = AOASSConfig(collinearity_tol=tol)
    net = Network(n_nodes, config)
    state = {"heard": np.zeros(n_nodes, dtype=np.int64), "mean": np.zeros((n_nodes, 2)),
             "scatter": np.zeros((n_nodes, 3)), "covered": np.zeros(n_nodes, dtype=bool)}
    for k in range(60):
        if k % 7 == 3:
            p = np.array([k * scale / 60.0, 2.0 * k * scale / 60.0])      # collinear run
        elif k % 11 == 5:
            p = state["mean"][0].copy()                                    # on a mean
        else:
            p = rng.uniform(-scale, scale, 2)
        idx = np.flatnonzero(rng.random(n_nodes) < 0.6)
        got = net.record_beacon(p, idx)
        assert got == _array_form(state, p, idx, tol * tol)
        assert net.heard.tobytes() == state["heard"].tobytes()
        assert net.beacon_centroid.tobytes() == state["mean"].tobytes()
        assert net.scatter.tobytes() == state["scatter"].tobytes()
        assert net.covered.tobytes() == state["covered"].tobytes()
        assert net.n_covered == int(state["covered"].sum())


def test_residual_after_names_bad_points_and_counts():
    mean, scatter = np.zeros(2), np.array([1.0, 0.0, 1.0])
    # (2, 3) points used to be read as three (2,) points
    with pytest.raises(ValueError, match=r"points must be an array of shape \(n, 2\)"):
        residual_after(2, mean, scatter, np.ones((2, 3)))
    with pytest.raises(ValueError, match="points must be finite"):
        residual_after(2, mean, scatter, [[np.nan, 0.0]])
    with pytest.raises(ValueError, match=r"heard=-1 must be an integer in \[0, inf\)"):
        residual_after(-1, mean, scatter, [[1.0, 0.0]])     # used to divide by zero
