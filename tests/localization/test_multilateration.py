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
