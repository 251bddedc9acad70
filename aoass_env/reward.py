"""The reward of AOASS-v0: Eq. 14 of the paper, term by term, as pure functions.

    R_t = w1 * dCoverage - w2 * (max_i E_i / E_avg - 1) - w3 * RMSE_loc          (Eq. 14)

How each term is computed during an episode (docs/env.md, "Rewards"):

* **dCoverage** -- the gain of the Eq. 18 coverage ratio (covered nodes / all nodes) during the
  step, in [0, 1]. Over a whole episode the w1 terms add up to w1 x final coverage.
* **Energy balance** -- E_i is the energy node i has spent so far (beacon receptions, J) and
  E_avg the mean over all nodes; the term is 0 while no node has spent anything.
* **RMSE_loc** -- a cheap online estimate, not the OLSTM-DV-Hop of evaluation: each covered node
  is placed at the centroid of the beacon positions it heard, and the RMSE (m) is taken over the
  covered nodes (0 while none is covered). The full localizer runs in evaluation only.
* **Collisions** -- an opt-in shaping term outside Eq. 14, ``w_collision`` per new contact of
  the anchor with an obstacle; 0 by default.
"""

from __future__ import annotations

import math

import numpy as np

from aoass_env.config import AOASSConfig
from aoass_env.jit import njit
from aoass_env.metrics import localization_rmse
from aoass_env.pairwise import pairwise_sum

__all__ = ["REWARD_TERMS", "energy_imbalance", "online_rmse", "reward_terms"]

#: Keys of ``info["reward_terms"]``; the reward is their sum.
REWARD_TERMS = ("coverage", "energy_balance", "localization", "collision")


def energy_imbalance(node_energy: np.ndarray) -> float:
    """max_i E_i / E_avg - 1 (>= 0) of the nodes' spent energy (J); 0 while all are zero.
    ValueError unless every E_i is finite and >= 0 (a NaN read as balanced, 0, and a negative
    energy gave a number).

    A contiguous 1-D float64 array (the env's) has its mean, maximum and minimum taken in one
    compiled pass with NumPy's floats (:func:`_mean_max_min`)."""
    e = np.asarray(node_energy, dtype=np.float64)
    if not e.size:
        return 0.0
    if e.ndim == 1 and e.flags.c_contiguous:
        mean, top, low = _mean_max_min(e)
    else:
        mean, top, low = float(e.mean()), float(e.max()), float(e.min())
    if not (low >= 0.0 and top < math.inf):
        raise ValueError(f"node_energy must be finite and >= 0 (J), got values from {low} to "
                         f"{top}")
    # max(0, .): the mean of equal values can round above their max
    return max(top / mean - 1.0, 0.0) if mean > 0.0 else 0.0


@njit
def _mean_max_min(e: np.ndarray) -> tuple[float, float, float]:
    """``(e.mean(), e.max(), e.min())`` of a non-empty contiguous float64 array, bit for bit:
    the sum in NumPy's order (:func:`~aoass_env.pairwise.pairwise_sum`) over the count, and
    extremes that NaN takes over as ``np.max`` lets it (the minimum then unread)."""
    top = low = e[0]
    for i in range(1, len(e)):
        v = e[i]
        if v > top or v != v:
            top = v
        if v < low:
            low = v
        if top != top:
            break
    return pairwise_sum(e, 0, len(e)) / len(e), top, low


def online_rmse(true_xy: np.ndarray, estimate_xy: np.ndarray, localized: np.ndarray) -> float:
    """RMSE (m, Eq. 15) of ``estimate_xy`` over the ``localized`` nodes; 0 when there are none.

    (N, 2) float64 positions and an (N,) bool mask (the env's) go through a compiled pass with
    :func:`~aoass_env.metrics.localization_rmse`'s floats (:func:`_masked_rmse`); any other
    input through that function itself."""
    if (type(true_xy) is np.ndarray and type(estimate_xy) is np.ndarray
            and type(localized) is np.ndarray and true_xy.dtype == estimate_xy.dtype == np.float64
            and localized.dtype == np.bool_ and true_xy.ndim == 2 and true_xy.shape[1] == 2
            and true_xy.shape == estimate_xy.shape and localized.shape == true_xy.shape[:1]):
        return _masked_rmse(true_xy, estimate_xy, localized)
    mask = np.asarray(localized, dtype=bool)
    if not mask.any():
        return 0.0
    return localization_rmse(np.asarray(true_xy)[mask], np.asarray(estimate_xy)[mask])[0]


@njit
def _masked_rmse(true_xy: np.ndarray, estimate_xy: np.ndarray, localized: np.ndarray) -> float:
    """``localization_rmse(true_xy[localized], estimate_xy[localized])[0]``, 0 without a
    localized node: the squared errors (dx^2 + dy^2) of the rows with a finite estimate, their
    sum in NumPy's order (:func:`~aoass_env.pairwise.pairwise_sum`) over their count, its
    square root; rows NaN in both coordinates left out, any other non-finite row (or true
    position) refused."""
    err2 = np.empty(len(localized))
    count = 0
    any_localized = False
    for i in range(len(localized)):
        if localized[i]:
            any_localized = True
            if not (math.isfinite(true_xy[i, 0]) and math.isfinite(true_xy[i, 1])):
                raise ValueError("true_xy must be finite (the nodes' true positions, m)")
            ex, ey = estimate_xy[i, 0], estimate_xy[i, 1]
            if math.isfinite(ex) and math.isfinite(ey):
                dx, dy = true_xy[i, 0] - ex, true_xy[i, 1] - ey
                err2[count] = dx * dx + dy * dy
                count += 1
            elif not (math.isnan(ex) and math.isnan(ey)):
                raise ValueError("est_xy: an estimate must be a finite position (m) or NaN in "
                                 "both coordinates (not localized)")
    if not any_localized:
        return 0.0
    if count == 0:
        return math.nan
    return math.sqrt(pairwise_sum(err2, 0, count) / count)


def reward_terms(config: AOASSConfig, *, delta_coverage: float, imbalance: float, rmse: float,
                 new_contacts: int) -> dict[str, float]:
    """The weighted terms of Eq. 14 (+ the opt-in collision shaping), keyed by
    :data:`REWARD_TERMS`; the step reward is their sum.

    Args:
        config: supplies the weights ``w1``, ``w2``, ``w3`` [1/m] and ``w_collision``.
        delta_coverage: coverage-ratio gain in the step, in [0, 1].
        imbalance: :func:`energy_imbalance` of the nodes' spent energy.
        rmse: online localization RMSE (m).
        new_contacts: anchor contacts with obstacles that began in the step.
    """
    return {"coverage": config.w1 * delta_coverage,
            "energy_balance": -config.w2 * imbalance,
            "localization": -config.w3 * rmse,
            "collision": -config.w_collision * new_contacts}
