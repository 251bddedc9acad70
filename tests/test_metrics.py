import math

import numpy as np
import pytest

from aoass_env.metrics import (
    coverage_ratio,
    energy_efficiency_ratio,
    energy_per_beacon,
    localization_rmse,
    trajectory_efficiency,
)


def test_rmse_eq15_and_localized_fraction():
    true = np.array([[0, 0], [3, 4], [1, 1], [2, 2]], float)
    est = np.array([[0, 0], [0, 0], [np.nan, np.nan], [2, 3]], float)
    rmse, frac = localization_rmse(true, est)
    assert rmse == pytest.approx(math.sqrt((0 + 25 + 1) / 3))
    assert frac == pytest.approx(0.75)
    assert math.isnan(localization_rmse(true, np.full((4, 2), np.nan))[0])
    with pytest.raises(ValueError, match="same shape"):
        localization_rmse(true, est[:2])
    # (N, 4) arrays used to be read as (2N, 2) positions, a silent nonsense RMSE
    with pytest.raises(ValueError, match=r"true_xy \(2, 4\) and est_xy \(2, 4\) must have the "
                                         r"same shape \(N, 2\)"):
        localization_rmse(true.reshape(2, 4), est.reshape(2, 4))
    with pytest.raises(ValueError, match="true_xy must be finite"):
        localization_rmse(est, true)
    with pytest.raises(ValueError, match=r"est_xy must be an array of numbers \(m\), got dtype"):
        localization_rmse(true, [["a", 1]] * 4)
    # complex positions used to lose their imaginary part with only a NumPy warning
    with pytest.raises(ValueError, match=r"est_xy must be an array of numbers \(m\), got dtype "
                                         r"complex128"):
        localization_rmse(true, est + 1j)
    # the RMSE of no nodes used to be (nan, 0.0): "0 % localized" of an empty network
    with pytest.raises(ValueError, match=r"must have the same shape \(N, 2\), N >= 1"):
        localization_rmse(np.zeros((0, 2)), np.zeros((0, 2)))


@pytest.mark.parametrize("row", [[np.inf, 1.0], [1.0, -np.inf], [np.nan, 1.0], [2.0, np.nan]])
def test_rmse_refuses_estimates_that_are_neither_positions_nor_unlocalized(row):
    """An infinite or half-NaN estimate (a localizer's fault) used to count as "not localized":
    a lower localized share beside a plausible RMSE, nothing said."""
    est = np.array([[0.0, 0.0], row, [1.0, 1.0]])
    with pytest.raises(ValueError, match=r"est_xy row 1 is \[.*\]: an estimate must be a "
                                         r"finite position \(m\) or NaN in both coordinates"):
        localization_rmse(np.zeros((3, 2)), est)


def test_energy_metrics_eq16_eq17():
    assert energy_per_beacon(10.0, 4) == pytest.approx(2.5)
    assert energy_efficiency_ratio(10.0, 4) == pytest.approx(0.4)
    assert energy_efficiency_ratio(10.0, 4) == pytest.approx(1 / energy_per_beacon(10.0, 4))
    assert energy_per_beacon(1.0, 0) == math.inf and energy_efficiency_ratio(1.0, 0) == 0.0
    assert energy_efficiency_ratio(0.0, 3) == math.inf and energy_per_beacon(0.0, 3) == 0.0
    # nothing spent, nothing sent: 0 / 0 in both (E_norm and EER used to be inf, each other's
    # inverse only in name)
    assert math.isnan(energy_per_beacon(0.0, 0)) and math.isnan(energy_efficiency_ratio(0.0, 0))


@pytest.mark.parametrize(("energy", "beacons", "message"), [
    (-10.0, 5, r"energy_total=-10.0 must be a number in \[0.0, inf\) J"),
    (float("nan"), 5, "energy_total=nan must be a number"),
    (10.0, -1, r"n_beacons=-1 must be an integer in \[0, inf\)"),
    (10.0, 2.5, "n_beacons=2.5 must be an integer"),
])
def test_energy_metrics_refuse_impossible_inputs(energy, beacons, message):
    """A negative energy or beacon count used to give a negative E_norm or EER."""
    for metric in (energy_per_beacon, energy_efficiency_ratio):
        with pytest.raises(ValueError, match=message):
            metric(energy, beacons)


def test_coverage_eq18():
    assert coverage_ratio(np.array([True, False, True, True])) == 0.75
    assert coverage_ratio(np.array([1, 0, 0, 1])) == 0.5
    # no nodes used to read as 0 % covered; a 2-D mask and a bare flag were flattened
    for covered in (np.array([], bool), np.ones((2, 2), bool), True):
        with pytest.raises(ValueError, match=r"covered must be a non-empty \(N,\) array of one "
                                             r"flag per node, got shape"):
            coverage_ratio(covered)
    # any non-zero float used to count as covered: [0.5, 2.0] gave 100 %
    with pytest.raises(ValueError, match="covered must hold booleans .or 0 and 1., got dtype "
                                         "float64"):
        coverage_ratio(np.array([0.5, 2.0]))


def test_trajectory_efficiency_eq19():
    assert trajectory_efficiency(100, 100, 50, 50) == 1.0
    assert trajectory_efficiency(100, 200, 50, 100) == pytest.approx(0.25)
    assert trajectory_efficiency(100, 0, 50, 0) == 0.0
    # a negative length or time used to read as "did not move" (0.0)
    with pytest.raises(ValueError, match=r"l_actual=-5 must be a number in \[0.0, inf\) m"):
        trajectory_efficiency(10, -5, 10, 5)
    with pytest.raises(ValueError, match="t_ideal=nan must be a number"):
        trajectory_efficiency(10, 5, float("nan"), 5)


def test_rmse_with_no_localized_node_reports_a_zero_localized_fraction():
    """No estimate at all: no RMSE, and 0 % of the nodes localized (not 100 %)."""
    rmse, frac = localization_rmse(np.zeros((3, 2)), np.full((3, 2), np.nan))
    assert math.isnan(rmse)
    assert frac == 0.0


@pytest.mark.parametrize(("energy", "beacons"), [(0.5, 1), (1.0, 1), (0.25, 2), (3.0, 1)])
def test_energy_metrics_for_one_beacon_or_under_a_joule(energy, beacons):
    """Eq. 16 / 17 are plain ratios for any positive energy and beacon count: one beacon or
    less than a joule is not a special case (the inf / NaN cases need a zero)."""
    assert energy_per_beacon(energy, beacons) == pytest.approx(energy / beacons)
    assert energy_efficiency_ratio(energy, beacons) == pytest.approx(beacons / energy)


def test_energy_metrics_zero_cases_with_one_beacon_or_under_a_joule():
    """The inf cases hold for a single beacon and for energy below a joule: one beacon sent
    for free is inf beacons per J, half a joule spent on no beacon is inf J per beacon."""
    assert energy_efficiency_ratio(0.0, 1) == math.inf and energy_per_beacon(0.0, 1) == 0.0
    assert energy_per_beacon(0.5, 0) == math.inf and energy_efficiency_ratio(0.5, 0) == 0.0


def test_trajectory_efficiency_is_zero_when_either_actual_is_zero():
    """No path or no time, each on its own, gives 0.0 (not a division by zero)."""
    assert trajectory_efficiency(100, 0, 50, 50) == 0.0
    assert trajectory_efficiency(100, 100, 50, 0) == 0.0


def test_trajectory_efficiency_of_short_paths_and_times():
    """Eq. 19 below a metre and a second: (0.5 / 0.5) * (0.2 / 0.4) = 0.5, by hand."""
    assert trajectory_efficiency(0.5, 0.5, 0.2, 0.4) == pytest.approx(0.5)
    assert trajectory_efficiency(0.3, 0.6, 0.9, 0.9) == pytest.approx(0.5)
