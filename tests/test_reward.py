"""Eq. 14 reward terms as pure functions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from aoass_env.config import AOASSConfig
from aoass_env.reward import REWARD_TERMS, energy_imbalance, online_rmse, reward_terms

energies = arrays(np.float64, st.integers(1, 50), elements=st.floats(0, 1e-3))


@settings(deadline=None)          # the first call may compile the mean and maximum
@given(energies)
def test_energy_imbalance_is_max_over_mean_minus_one(e):
    value = energy_imbalance(e)
    assert value >= 0.0
    if e.mean() > 0:
        assert value == pytest.approx(e.max() / e.mean() - 1.0, rel=1e-12, abs=1e-12)
    else:
        assert value == 0.0


@settings(deadline=None)
@given(arrays(np.float64, st.integers(1, 300),
              elements=st.floats(allow_nan=True, allow_infinity=True, width=64)
              | st.sampled_from([0.0, -0.0, 1e-300, 2.5e-5])))
def test_energy_imbalance_of_an_array_is_numpys_formula_to_the_bit(e):
    """The compiled mean and maximum (contiguous float64 arrays) against NumPy's, signed zeros
    and runs longer than NumPy's pairwise block included; a strided view takes NumPy's own
    path to the same answer. An array with a NaN, an infinity or a negative value is refused
    on both paths (a NaN read as balanced, 0; a negative energy gave a number)."""
    def reference(x):
        mean = float(x.mean())
        return max(float(x.max()) / mean - 1.0, 0.0) if mean > 0.0 else 0.0

    valid = bool(np.isfinite(e).all() and (e >= 0.0).all())
    with np.errstate(all="ignore"):
        for x in (e, np.repeat(e, 2)[::2]):
            if valid:
                assert np.float64(energy_imbalance(x)).tobytes() == \
                    np.float64(reference(e)).tobytes()
            else:
                with pytest.raises(ValueError, match=r"node_energy must be finite and >= 0"):
                    energy_imbalance(x)


def test_energy_imbalance_by_hand():
    assert energy_imbalance(np.array([1.0, 1.0, 1.0])) == 0.0
    assert energy_imbalance(np.array([3.0, 1.0, 2.0])) == pytest.approx(0.5)
    assert energy_imbalance(np.zeros(4)) == 0.0
    assert energy_imbalance(np.zeros(0)) == 0.0
    for bad in ([1.0, math.nan, 2.0], [math.nan, 1.0], [3.0, -1.0, 2.0], [1.0, math.inf]):
        with pytest.raises(ValueError, match=r"node_energy must be finite and >= 0 \(J\)"):
            energy_imbalance(np.array(bad))


def test_online_rmse_uses_only_localized_nodes():
    true = np.array([[0.0, 0.0], [10.0, 0.0], [5.0, 5.0]])
    est = np.array([[3.0, 4.0], [99.0, 99.0], [5.0, 5.0]])
    assert online_rmse(true, est, np.array([True, False, True])) == pytest.approx(
        math.sqrt(25.0 / 2))
    assert online_rmse(true, est, np.zeros(3, bool)) == 0.0


@given(st.floats(0, 1), st.floats(0, 50), st.floats(0, 100), st.integers(0, 5))
def test_reward_terms_are_the_weighted_eq14_terms(dcov, imbalance, rmse, contacts):
    cfg = AOASSConfig(w1=7.0, w2=0.3, w3=0.02, w_collision=1.5)
    terms = reward_terms(cfg, delta_coverage=dcov, imbalance=imbalance, rmse=rmse,
                         new_contacts=contacts)
    assert tuple(terms) == REWARD_TERMS
    assert terms == {"coverage": 7.0 * dcov, "energy_balance": -0.3 * imbalance,
                     "localization": -0.02 * rmse, "collision": -1.5 * contacts}


def test_default_weights_and_no_shaping():
    terms = reward_terms(AOASSConfig(), delta_coverage=0.01, imbalance=2.0, rmse=4.0,
                         new_contacts=3)
    assert terms["coverage"] == pytest.approx(1.0)
    assert terms["energy_balance"] == pytest.approx(-0.02)
    assert terms["localization"] == pytest.approx(-0.02)
    assert terms["collision"] == 0.0


def test_the_compiled_online_rmse_is_the_metrics_float():
    """The env's arrays go through the compiled pass: the float of localization_rmse over the
    localized rows (NumPy's pairwise summation order, every block size up to thousands of
    nodes, NaN estimates left out, none localized, none finite), bit for bit; lists go
    through the metric itself."""
    from aoass_env.metrics import localization_rmse
    rng = np.random.default_rng(21)
    sizes = [*range(1, 300), *rng.integers(300, 5000, 60).tolist()]
    for n in sizes:
        true = rng.uniform(0.0, 100.0, (n, 2))
        est = true + rng.normal(0.0, 10.0 ** rng.uniform(-3, 2), (n, 2))
        est[rng.random(n) < 0.1] = np.nan
        mask = rng.random(n) < rng.uniform(0.05, 1.0)
        got = online_rmse(true, est, mask)
        if not mask.any():
            assert got == 0.0
            continue
        want = localization_rmse(true[mask], est[mask])[0]
        assert (got == want) or (math.isnan(got) and math.isnan(want)), n
    assert math.isnan(online_rmse(np.zeros((2, 2)), np.full((2, 2), np.nan),
                                  np.array([True, False])))
    assert online_rmse([[0.0, 0.0], [1.0, 1.0]], [[3.0, 4.0], [1.0, 1.0]], [True, True]) == \
        pytest.approx(math.sqrt(12.5))
    # an infinite or half-NaN estimate is refused by both paths, as by the metric
    for row in ([np.inf, 0.0], [np.nan, 0.0]):
        est = np.array([[0.0, 0.0], row])
        for true in (np.zeros((2, 2)), [[0.0, 0.0], [0.0, 0.0]]):
            with pytest.raises(ValueError, match="finite position"):
                online_rmse(true, est, np.array([True, True]))
        assert online_rmse(np.zeros((2, 2)), est, np.array([True, False])) == 0.0
    # a non-finite true position of a localized node: refused by both paths (the compiled one
    # used to return nan or inf)
    for row in ([np.nan, 0.0], [np.inf, 0.0]):
        true = np.array([[0.0, 0.0], row])
        for path in (true, true.tolist()):
            with pytest.raises(ValueError, match="true_xy must be finite"):
                online_rmse(path, np.zeros((2, 2)), np.array([True, True]))
        assert online_rmse(true, np.zeros((2, 2)), np.array([True, False])) == 0.0
