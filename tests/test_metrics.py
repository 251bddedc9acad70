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


def test_energy_metrics_eq16_eq17():
    assert energy_per_beacon(10.0, 4) == pytest.approx(2.5)
    assert energy_efficiency_ratio(10.0, 4) == pytest.approx(0.4)
    assert energy_efficiency_ratio(10.0, 4) == pytest.approx(1 / energy_per_beacon(10.0, 4))
    assert energy_per_beacon(1.0, 0) == math.inf


def test_coverage_eq18():
    assert coverage_ratio(np.array([True, False, True, True])) == 0.75
    assert coverage_ratio(np.array([], bool)) == 0.0


def test_trajectory_efficiency_eq19():
    assert trajectory_efficiency(100, 100, 50, 50) == 1.0
    assert trajectory_efficiency(100, 200, 50, 100) == pytest.approx(0.25)
    assert trajectory_efficiency(100, 0, 50, 0) == 0.0
