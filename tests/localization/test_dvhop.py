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


def _least_squares_oracle(episode, node: int) -> tuple[np.ndarray, int]:
    """Eq. 13 for one node by scipy's bounded least squares (an independent solver): unit
    weights, distance hops x HopSize to every beacon it reaches with a HopSize, started from
    the centroid of its heard beacons; also how many beacons that is."""
    from scipy.optimize import least_squares

    hops, size = episode.hops.beacon_node[:, node], episode.hop_size
    used = np.flatnonzero(np.isfinite(hops) & np.isfinite(size))
    xy, dist = episode.beacon_xy[used], hops[used] * size[used]
    w, h = episode.field
    start = np.clip(episode.heard_centroid[node], 0.0, [w, h])
    fit = least_squares(lambda p: np.hypot(*(p - xy).T) - dist, start,
                        bounds=([0.0, 0.0], [w, h]), xtol=1e-12, ftol=1e-12, gtol=1e-12)
    return fit.x, len(used)


def test_dvhop_is_the_least_squares_fit_to_hop_distances(small_log) -> None:
    """Each covered node's estimate is the Eq. 13 fit to hops x HopSize over every beacon
    within the flooding limit (not, e.g., the heard beacons' centroid, nor a fit that
    leaves some beacon out), as an independent solver finds it."""
    from aoass_env.localization.dvhop import dvhop
    from aoass_env.localization.episode import prepare

    episode = prepare(small_log)
    est = dvhop(episode)
    nodes = np.flatnonzero(episode.covered)
    assert len(nodes) >= 10
    for node in nodes:
        expected, used = _least_squares_oracle(episode, node)
        assert used >= 3
        np.testing.assert_allclose(est[node], expected, atol=2e-3)
        # the fit moved away from the starting centroid (else the test would prove nothing)
        assert np.hypot(*(expected - episode.heard_centroid[node])) > 0.1


def test_dvhop_estimates_do_not_depend_on_which_other_nodes_are_covered(small_log) -> None:
    """A node's estimate is its own fit: with only one node (or a few) marked covered, those
    get the same estimates as in the full run and every other node stays NaN."""
    import dataclasses

    from aoass_env.localization.dvhop import dvhop
    from aoass_env.localization.episode import prepare

    episode = prepare(small_log)
    full = dvhop(episode)
    nodes = np.flatnonzero(episode.covered)
    for subset in (nodes[:1], nodes[-1:], nodes[::3]):
        covered = np.zeros_like(episode.covered)
        covered[subset] = True
        est = dvhop(dataclasses.replace(episode, covered=covered))
        np.testing.assert_allclose(est[subset], full[subset], atol=1e-9)
        assert np.all(np.isnan(est[~covered]))
