"""Eq. 13 solver: exact on noise-free distances, bounds, padding, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env.localization.multilateration import multilaterate


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000), st.integers(3, 12))
def test_exact_on_noise_free_distances(seed: int, m: int) -> None:
    rng = np.random.default_rng(seed)
    truth = rng.uniform(5, 95, (20, 2))
    anchors = rng.uniform(0, 100, (20, m, 2))
    anchors[:, :3] = truth[:, None, :] + [[-20, -5], [15, -10], [0, 20]]  # never collinear
    dist = np.hypot(*(anchors - truth[:, None, :]).transpose(2, 0, 1))
    init = np.clip(truth + rng.normal(0, 5, truth.shape), 0, 100)
    est = multilaterate(anchors, dist, np.ones_like(dist), init, (100.0, 100.0))
    np.testing.assert_allclose(est, truth, atol=1e-3)


def test_padding_with_zero_weight_is_ignored() -> None:
    truth = np.array([[30.0, 40.0]])
    anchors = np.array([[[0, 0], [60, 0], [30, 80], [99, 99]]], dtype=float)
    dist = np.hypot(*(anchors - truth[:, None]).transpose(2, 0, 1))
    dist[0, 3] = 1e3  # garbage on a padded entry
    est = multilaterate(anchors, dist, np.array([[1, 1, 1, 0.0]]), [[50, 50]], (100, 100))
    np.testing.assert_allclose(est, truth, atol=1e-4)


def test_estimates_stay_in_the_field() -> None:
    anchors = np.array([[[1, 1], [2, 1], [1, 2]]], dtype=float)
    est = multilaterate(anchors, np.full((1, 3), 50.0), np.ones((1, 3)), [[5, 5]], (20, 10))
    assert np.all(est >= 0) and est[0, 0] <= 20 and est[0, 1] <= 10


@pytest.mark.parametrize("change, match", [
    ({"distances": np.zeros((1, 2))}, "shapes"),
    ({"weights": -np.ones((1, 3))}, "non-negative"),
    ({"init": np.array([[np.nan, 0.0]])}, "init must be finite"),
])
def test_bad_input(change: dict, match: str) -> None:
    args = {"anchors": np.zeros((1, 3, 2)), "distances": np.ones((1, 3)),
            "weights": np.ones((1, 3)), "init": np.zeros((1, 2))}
    args.update(change)
    with pytest.raises(ValueError, match=match):
        multilaterate(args["anchors"], args["distances"], args["weights"], args["init"],
                      (10, 10))


@pytest.mark.parametrize("change, message", [
    # each of these was accepted: a negative width put the estimate outside the field, NaN
    # gave a NaN estimate, a third entry was dropped, max_iter <= 0 returned the start point,
    # a NaN or negative tol never converged, a negative distance was fitted
    ({"field": (-1.0, 10.0)}, "field[0]=-1.0 must be a number in (0.0, inf) m"),
    ({"field": (10.0, float("nan"))},
     "field must be a pair of finite numbers (m), got (10.0, nan)"),
    ({"field": (10.0, 10.0, 3.0)},
     "field must be a pair of finite numbers (m), got (10.0, 10.0, 3.0)"),
    ({"max_iter": 0}, "max_iter=0 must be an integer in [1, inf)"),
    ({"max_iter": -1}, "max_iter=-1 must be an integer in [1, inf)"),
    ({"tol": float("nan")}, "tol=nan must be a number in [0, inf) m"),
    ({"tol": -1.0}, "tol=-1.0 must be a number in [0, inf) m"),
    ({"distances": np.array([[1.0, -1.0, 1.0]])}, "distances must be non-negative"),
    ({"weights": [["1", "x", "1"]]},   # numpy's own text named no parameter
     "weights must be an array of numbers (could not convert string to float: 'x')"),
])
def test_bad_field_limits_and_distances_are_named(change: dict, message: str) -> None:
    args = {"anchors": np.array([[[1, 1], [8, 1], [1, 8]]], dtype=float),
            "distances": np.ones((1, 3)), "weights": np.ones((1, 3)), "init": np.zeros((1, 2)),
            "field": (10.0, 10.0)}
    args.update(change)
    with pytest.raises(ValueError) as info:
        multilaterate(**args)
    assert str(info.value) == message


@pytest.mark.parametrize("seed", [550030, 550031, 550032])
def test_noisy_weighted_fit_is_the_least_squares_minimum(seed: int) -> None:
    """With noisy distances (no exact solution) and unequal weights, each estimate is the
    minimum of sum_i w_i (d_i - |a_i - p|)^2 as an independent solver (scipy's least squares
    on sqrt(w_i)-scaled residuals) finds it: anchors all round each node keep the minimum
    unique and inside the field."""
    from scipy.optimize import least_squares

    rng = np.random.default_rng(seed)
    s, m = 20, 6
    truth = rng.uniform(30, 70, (s, 2))
    ang = rng.uniform(0, 2 * np.pi, (s, 1)) + np.arange(m) * 2 * np.pi / m
    rad = rng.uniform(10, 30, (s, m))
    anchors = truth[:, None] + np.stack([rad * np.cos(ang), rad * np.sin(ang)], axis=2)
    dist = np.abs(rad + rng.normal(0, 3, (s, m)))
    weights = rng.uniform(0.2, 1.0, (s, m))
    init = truth + rng.normal(0, 5, truth.shape)
    est = multilaterate(anchors, dist, weights, init, (100.0, 100.0))
    for k in range(s):
        def residuals(p: np.ndarray, k: int = k) -> np.ndarray:
            return np.sqrt(weights[k]) * (np.hypot(*(p - anchors[k]).T) - dist[k])
        fit = least_squares(residuals, init[k], xtol=1e-14, ftol=1e-14, gtol=1e-14)
        np.testing.assert_allclose(est[k], fit.x, atol=1e-3)



@pytest.mark.parametrize("seed", [551040, 551041, 551042])
def test_a_minimum_outside_the_field_gives_the_bounded_least_squares_minimum(seed: int) -> None:
    """Nodes near the field's edges whose distances put the unbounded minimum outside it (the
    DV-Hop distances of edge nodes): each estimate is the bounded minimum scipy's least squares
    (trf, with the field's bounds) finds, on the edge, not a point the damping stopped short
    of it (clipping every trial step cancelled the step along the edge; up to 7 m off)."""
    from scipy.optimize import least_squares

    rng = np.random.default_rng(seed)
    s, m, size = 24, 6, 100.0
    # unbounded minima 1-6 m beyond a random edge or corner, anchors inside the field within
    # 30 m of them, noisy distances (the bounded minimum unique)
    truth = rng.uniform(10, 90, (s, 2))
    side = rng.integers(0, 3, s)      # 0: x edge, 1: y edge, 2: corner
    beyond = -rng.uniform(1, 6, (s, 2))
    truth[side != 1, 0] = beyond[side != 1, 0]
    truth[side != 0, 1] = beyond[side != 0, 1]
    flip = rng.random((s, 2)) < 0.5   # the low or the high edge
    truth = np.where(flip & (truth < 0), size - truth, truth)
    lo, hi = np.clip(truth - 30, 1, size - 1), np.clip(truth + 30, 1, size - 1)
    anchors = rng.uniform(lo[:, None], hi[:, None], (s, m, 2))
    dist = np.abs(np.hypot(*(anchors - truth[:, None]).transpose(2, 0, 1))
                  + rng.normal(0, 0.5, (s, m)))
    weights = rng.uniform(0.2, 1.0, (s, m))
    init = np.clip(truth + rng.normal(0, 5, truth.shape), 0, size)
    est = multilaterate(anchors, dist, weights, init, (size, size))
    on_edge = 0
    for k in range(s):
        def residuals(p: np.ndarray, k: int = k) -> np.ndarray:
            return np.sqrt(weights[k]) * (np.hypot(*(p - anchors[k]).T) - dist[k])
        fit = least_squares(residuals, init[k], bounds=([0, 0], [size, size]), method="trf",
                            xtol=1e-14, ftol=1e-14, gtol=1e-14)
        np.testing.assert_allclose(est[k], fit.x, atol=1e-3)
        on_edge += bool(np.any((fit.x <= 1e-6) | (fit.x >= size - 1e-6)))
    assert on_edge >= s // 2      # the bounds are active for most nodes

def test_estimates_reach_the_field_edges() -> None:
    """Nodes within a metre of the field's lower edges are found where they are (the bounds
    are [0, w] x [0, h], not narrower), from starting points outside the field too."""
    truth = np.array([[0.3, 0.2], [0.0, 5.0], [7.0, 0.6]])
    anchors = truth[:, None, :] + np.array([[6.0, 1.0], [-2.0, 7.0], [4.0, 9.0], [9.0, 3.0]])
    anchors = np.clip(anchors, 0.0, 20.0)
    dist = np.hypot(*(anchors - truth[:, None, :]).transpose(2, 0, 1))
    est = multilaterate(anchors, dist, np.ones_like(dist), [[-3.0, -3.0], [2.0, 2.0],
                                                            [5.0, -1.0]], (20.0, 20.0))
    np.testing.assert_allclose(est, truth, atol=1e-3)


def test_a_node_without_anchors_stays_at_its_clipped_start() -> None:
    """Zero weights (no anchor): nothing to fit, the estimate is the start clipped to the
    field, per coordinate."""
    init = np.array([[-5.0, 0.5], [0.4, 12.0], [3.0, 4.0]])
    est = multilaterate(np.zeros((3, 2, 2)), np.ones((3, 2)), np.zeros((3, 2)), init,
                        (10.0, 10.0))
    np.testing.assert_array_equal(est, [[0.0, 0.5], [0.4, 10.0], [3.0, 4.0]])
