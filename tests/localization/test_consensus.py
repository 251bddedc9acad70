"""Visibility consensus: exact on symmetric records, DOI ranges, line of sight, coverage."""

from __future__ import annotations

import numpy as np
import pytest

from aoass_env.localization import localize, prepare
from aoass_env.localization.consensus import consensus, node_consensus, visibility_raster
from tests.localization.conftest import make_log

CENTRE = np.array([50.0, 50.0])


def ring(radius: float, n: int = 12, phase: float = 0.0) -> np.ndarray:
    """``n`` points on a circle of ``radius`` [m] around CENTRE, every 360 / n degrees."""
    a = np.radians(phase) + np.arange(n) * 2 * np.pi / n
    return CENTRE + radius * np.column_stack([np.cos(a), np.sin(a)])


def record(heard: np.ndarray, unheard: np.ndarray, doi: float = 0.0):
    """A prepared log: one node at CENTRE hearing exactly the beacons ``heard``."""
    beacons = np.concatenate([heard, unheard])
    receptions = [[b, 0] for b in range(len(heard))]
    return prepare(make_log(CENTRE[None], beacons, receptions, [], doi=doi))


def test_node_on_a_ring_is_found_exactly() -> None:
    # 12 heard beacons 20 m away, 12 unheard 30 m away, 25 m range: the cells within ~5 m of
    # the centre fit all of them, a set symmetric under 90 degree turns about the centre
    episode = record(ring(20.0), ring(30.0, phase=15.0))
    result = node_consensus(episode)
    np.testing.assert_allclose(result.estimate[0], CENTRE, atol=1e-9)
    assert result.violations[0] == 0
    np.testing.assert_allclose(consensus(episode)[0], CENTRE, atol=1e-9)


def test_unheard_beacons_shrink_the_region() -> None:
    alone = node_consensus(record(ring(20.0), np.zeros((0, 2))))
    with_unheard = node_consensus(record(ring(20.0), ring(28.0, phase=15.0)))
    assert with_unheard.spread[0] < 0.8 * alone.spread[0]


def test_doi_widens_the_heard_range_and_narrows_the_certain_one() -> None:
    # heard 28 m away is possible only with DOI >= 0.12; unheard 22 m away rules nothing out
    # with DOI 0.2 (hearing is certain only within 20 m)
    episode = record(ring(28.0), ring(22.0, phase=15.0), doi=0.2)
    result = node_consensus(episode)
    np.testing.assert_allclose(result.estimate[0], CENTRE, atol=1e-9)
    assert result.violations[0] == 0
    # without DOI no cell is within 25 m of all heard beacons: the heard centroid, NaN counts
    flat = node_consensus(record(ring(28.0), np.zeros((0, 2))))
    np.testing.assert_allclose(flat.estimate[0], CENTRE, atol=1e-9)
    assert np.isnan(flat.violations[0]) and np.isnan(flat.spread[0])


def test_raster_ranges_follow_the_doi() -> None:
    beacon = np.array([[50.2, 50.3]])
    raster = visibility_raster(record(beacon, np.zeros((0, 2)), doi=0.2), cell=1.0)
    ix, iy = np.meshgrid(np.arange(20, 80), np.arange(20, 80), indexing="ij")
    dist = np.hypot((ix + 0.5) - 50.2, (iy + 0.5) - 50.3)
    weight = raster.weight[raster.key[0] + ix * raster.size + iy]
    np.testing.assert_array_equal(weight, (dist <= 20.0).astype(int) + (dist <= 30.0))


def test_raster_line_of_sight_matches_the_exact_test(small_log) -> None:
    episode = prepare(small_log)
    raster = visibility_raster(episode)
    r = small_log.radio_range
    nx, ny = raster.shape
    ix, iy = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    cells = np.column_stack([(ix.ravel() + 0.5), (iy.ravel() + 0.5)]) * raster.cell
    inside = episode.line_of_sight.inside(cells)
    np.testing.assert_array_equal(raster.inside.ravel(), inside)
    agree = total = 0
    for b in range(0, small_log.n_beacons, 7):
        xy = episode.beacon_xy[b]
        near = np.flatnonzero((np.hypot(*(cells - xy).T) <= r) & ~inside)
        exact = ~episode.line_of_sight.blocked(cells[near], xy)
        got = raster.weight[raster.key[b] + ix.ravel()[near] * raster.size + iy.ravel()[near]] > 0
        agree, total = agree + np.sum(got == exact), total + len(near)
    assert total > 1000 and agree / total > 0.995


def test_consensus_method_covers_exactly_the_covered(small_sim) -> None:
    log = small_sim.finish()
    est = localize(log, "consensus")
    covered = np.asarray(small_sim.network.covered)
    assert np.all(np.isfinite(est[covered])) and np.all(np.isnan(est[~covered]))
    w, h = log.field
    assert np.all((est[covered] >= 0) & (est[covered] <= [w, h]))


def test_bad_cell_and_silent_node() -> None:
    episode = record(ring(20.0), np.zeros((0, 2)))
    with pytest.raises(ValueError, match="cell"):
        visibility_raster(episode, cell=0.0)
    silent = prepare(make_log(np.array([CENTRE, CENTRE]), ring(20.0),
                              [[b, 0] for b in range(12)], []))
    with pytest.raises(ValueError, match="heard no beacon"):
        node_consensus(silent, np.array([1]))


def test_band_of_the_doi_bound_is_the_default_and_a_narrow_band_changes_the_estimates(
        doi_sim) -> None:
    episode = prepare(doi_sim.finish())
    doi = episode.config.doi
    default = node_consensus(episode)
    bound = (np.full(360, 1 - doi), np.full(360, 1 + doi))
    np.testing.assert_array_equal(node_consensus(episode, band=bound).estimate, default.estimate)
    exact = (doi_sim.radio.anchor_pattern, doi_sim.radio.anchor_pattern)
    narrow = node_consensus(episode, band=exact)
    err = np.hypot(*(narrow.estimate - episode.log.nodes[narrow.nodes]).T)
    err0 = np.hypot(*(default.estimate - episode.log.nodes[default.nodes]).T)
    assert np.sqrt(np.mean(err ** 2)) < np.sqrt(np.mean(err0 ** 2))
