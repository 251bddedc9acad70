"""The paper's evaluation metrics (Eq. 15-19) as pure functions."""

from __future__ import annotations

import numpy as np

from aoass_env.validators import integer, number_array, real


def localization_rmse(true_xy: np.ndarray, est_xy: np.ndarray) -> tuple[float, float]:
    """Eq. 15: RMSE (m) over the nodes that have an estimate, and the localized fraction.

    Nodes whose estimate is NaN (both coordinates: a localizer's "not localized") are left out
    of the RMSE; the fraction of nodes that were localized is returned beside it so that the
    two are always reported together. Any other non-finite estimate (an infinity, one NaN
    coordinate) is a localizer's fault, not a missing estimate: ValueError. The RMSE of no
    nodes (N = 0) is undefined: ValueError, as for :func:`coverage_ratio`.
    """
    t, e = number_array("true_xy", true_xy, "m"), number_array("est_xy", est_xy, "m")
    if t.shape != e.shape or t.ndim != 2 or t.shape[1] != 2 or len(t) == 0:
        raise ValueError(f"true_xy {t.shape} and est_xy {e.shape} must have the same shape (N, 2)"
                         f", N >= 1")
    if not np.isfinite(t).all():
        raise ValueError("true_xy must be finite (the nodes' true positions, m)")
    ok = np.all(np.isfinite(e), axis=1)
    bad = ~ok & ~np.all(np.isnan(e), axis=1)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise ValueError(f"est_xy row {row} is {e[row].tolist()}: an estimate must be a finite "
                         f"position (m) or NaN in both coordinates (not localized)")
    if not ok.any():
        return float("nan"), 0.0
    err2 = np.sum((t[ok] - e[ok]) ** 2, axis=1)
    return float(np.sqrt(err2.mean())), float(ok.mean())


def energy_per_beacon(energy_total: float, n_beacons: int) -> float:
    """Eq. 16: E_norm = E_total / N_beacons (J per beacon); inf for energy without beacons,
    NaN for neither (0 / 0: undefined, as its inverse :func:`energy_efficiency_ratio`)."""
    energy, beacons = _energy_and_beacons(energy_total, n_beacons)
    return energy / beacons if beacons > 0 else float("inf") if energy > 0 else float("nan")


def energy_efficiency_ratio(energy_total: float, n_beacons: int) -> float:
    """Eq. 17: EER = 1 / E_norm (beacons per J); inf for beacons sent without energy, NaN for
    neither (0 / 0: undefined)."""
    energy, beacons = _energy_and_beacons(energy_total, n_beacons)
    return beacons / energy if energy > 0 else float("inf") if beacons > 0 else float("nan")


def _energy_and_beacons(energy_total: float, n_beacons: int) -> tuple[float, int]:
    return (real("energy_total", energy_total, "J", low=0.0),
            integer("n_beacons", n_beacons, low=0))


def coverage_ratio(covered: np.ndarray) -> float:
    """Eq. 18: share of nodes (in [0, 1]; x 100 for %) that heard >= 3 non-collinear beacons.

    ``covered`` is one flag per node, (N,) with N >= 1: the coverage of no nodes is undefined.
    """
    c = np.asarray(covered)
    if c.ndim != 1 or c.size == 0:
        raise ValueError(f"covered must be a non-empty (N,) array of one flag per node, got "
                         f"shape {c.shape}")
    if c.dtype != bool:
        if not (np.issubdtype(c.dtype, np.number) and np.isin(c, (0, 1)).all()):
            raise ValueError(f"covered must hold booleans (or 0 and 1), got dtype {c.dtype}")
        c = c.astype(bool)
    return float(c.mean())


def trajectory_efficiency(l_ideal: float, l_actual: float, t_ideal: float,
                          t_actual: float) -> float:
    """Eq. 19: eta_traj = (L_ideal / L_actual) * (T_ideal / T_actual), lengths in m, times in s.

    Zero when the anchor did not move (no path, no efficiency).
    """
    l_ideal, l_actual = (real(n, v, "m", low=0.0) for n, v in
                         (("l_ideal", l_ideal), ("l_actual", l_actual)))
    t_ideal, t_actual = (real(n, v, "s", low=0.0) for n, v in
                         (("t_ideal", t_ideal), ("t_actual", t_actual)))
    if l_actual <= 0 or t_actual <= 0:
        return 0.0
    return (l_ideal / l_actual) * (t_ideal / t_actual)
