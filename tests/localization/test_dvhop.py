"""Eq. 11 on a hand-computed case and classical DV-Hop on a simulated episode."""

from __future__ import annotations

import numpy as np
import pytest

from aoass_env.localization import localize
from aoass_env.localization.hops import hop_size


def test_hop_size_hand_computed() -> None:
    # beacons on a line at x = 0, 10, 30; hops 0-1: 2, 1-2: 2, 0-2: 4; beacon 3 reaches nobody
    xy = np.array([[0, 0], [10, 0], [30, 0], [50, 50]], dtype=float)
    inf = np.inf
    hops = np.array([[0, 2, 4, inf], [2, 0, 2, inf], [4, 2, 0, inf], [inf, inf, inf, 0]])
    size = hop_size(xy, hops)
    pooled = (40 + 30 + 50) / (6 + 4 + 6)
    np.testing.assert_allclose(size, [40 / 6, 30 / 4, 50 / 6, pooled])


def test_hop_size_shape_error() -> None:
    with pytest.raises(ValueError, match="beacon_hops"):
        hop_size(np.zeros((3, 2)), np.zeros((2, 2)))


def test_dvhop_estimates_covered_nodes_only(small_sim) -> None:
    log = small_sim.finish()
    est = localize(log, "dvhop")
    covered = np.asarray(small_sim.network.covered)
    assert est.shape == (log.n_nodes, 2)
    assert np.all(np.isfinite(est[covered])) and np.all(np.isnan(est[~covered]))
    assert np.all((est[covered] >= 0) & (est[covered] <= 40))
    # range-free DV-Hop is coarse but must beat guessing the field centre
    err = np.hypot(*(est[covered] - log.nodes[covered]).T)
    centre = np.hypot(*(log.nodes[covered] - 20).T)
    assert np.sqrt(np.mean(err ** 2)) < np.sqrt(np.mean(centre ** 2))


def test_unknown_method(small_log) -> None:
    with pytest.raises(ValueError, match="method"):
        localize(small_log, "trilateration")


@pytest.mark.parametrize("xy, hops, message", [
    # were a NaN HopSize for every beacon, without a word
    ([[0.0, 0.0], [np.nan, 1.0]], [[0, 2], [2, 0]], "beacon_xy must be finite"),
    ([[0.0, 0.0], [1.0, 1.0]], [[0, -2], [-2, 0]],
     "beacon_hops must be hop counts >= 0 (inf: unreachable)"),
    ([[0.0, 0.0], [1.0, 1.0]], [[0, np.nan], [np.nan, 0]],
     "beacon_hops must be hop counts >= 0 (inf: unreachable)"),
])
def test_hop_size_refuses_impossible_input(xy, hops, message) -> None:
    with pytest.raises(ValueError) as info:
        hop_size(np.array(xy), np.array(hops, dtype=float))
    assert str(info.value) == message
