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


def test_an_estimate_in_a_last_partial_cell_stays_on_the_field() -> None:
    # a 40.1 m field: the last column of 0.5 m cells is [40.0, 40.5], its centre 40.25 lies off
    # the field; the node by the edge is estimated at the centre of the cell's part on it
    heard = np.array([[20.0, 20.0], [38.0, 5.0], [38.0, 35.0]])
    unheard = np.array([[15.1, 20.0], [15.1, 12.0], [15.1, 28.0]])
    log = make_log(np.array([[40.08, 20.0]]), np.concatenate([heard, unheard]),
                   [[0, 0], [1, 0], [2, 0]], [], field=40.1)
    result = node_consensus(prepare(log))
    np.testing.assert_allclose(result.estimate[0], [40.05, 20.0], rtol=0, atol=1e-12)
    assert result.violations[0] == 0


@pytest.mark.parametrize("nodes, message", [
    ([1.7], "nodes must be integer indices in \\[0, 2\\), got dtype float64"),
    ([-1], "nodes must be indices in \\[0, 2\\), got -1"),
    ([2], "nodes must be indices in \\[0, 2\\), got 2"),
    ([1, 1], "nodes must not repeat an index"),
    ([True], "nodes must be integer indices"),
    ([[0, 1]], "nodes must be a 1-D array"),
])
def test_bad_node_indices_are_named(nodes, message) -> None:
    episode = prepare(make_log(np.array([CENTRE, CENTRE]), ring(20.0),
                               [[b, n] for b in range(12) for n in (0, 1)], []))
    with pytest.raises(ValueError, match=message):
        node_consensus(episode, nodes)


def test_the_cell_follows_the_rule_for_numbers() -> None:
    episode = record(ring(20.0), np.zeros((0, 2)))
    for bad in (True, "0.5", float("nan"), 0.0):
        with pytest.raises(ValueError, match="cell="):
            node_consensus(episode, cell=bad)
    assert node_consensus(episode, cell=np.float32(0.5)).estimate.tolist() == \
        node_consensus(episode, cell=0.5).estimate.tolist()


def test_no_nodes_give_an_empty_result() -> None:
    result = node_consensus(record(ring(20.0), np.zeros((0, 2))), np.array([], dtype=int))
    assert result.nodes.shape == (0,) and result.estimate.shape == (0, 2)
    assert result.spread.shape == result.violations.shape == (0,)
    with pytest.raises(ValueError, match="cell"):
        node_consensus(record(ring(20.0), np.zeros((0, 2))), np.array([], dtype=int), cell=-1.0)


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


def _reference_raster(episode, band=None, cell=0.5, bins=1024):
    """The visibility raster as computed before issue 20's speed-up: whole-raster arrays, the
    band as float64 thresholds (the oracle of the chunked, shared-geometry version)."""
    from aoass_env.localization.consensus import _inside_cells, _profiles

    config, xy = episode.config, episode.beacon_xy
    r_hi = episode.log.radio_range * (1 + config.doi)
    r_lo = episode.log.radio_range * (1 - config.doi)
    w, h = episode.field
    shape = (int(np.ceil(w / cell)), int(np.ceil(h / cell)))
    half = int(np.ceil(r_hi / cell)) + 2
    size = 2 * half + 1
    origin = np.floor(xy / cell).astype(np.int64) - half
    offs = np.arange(size)
    cx = ((origin[:, 0, None] + offs + 0.5) * cell - xy[:, 0, None]).astype(np.float32)
    cy = ((origin[:, 1, None] + offs + 0.5) * cell - xy[:, 1, None]).astype(np.float32)
    dx, dy = cx[:, :, None], cy[:, None, :]
    dist = np.sqrt(dx * dx + dy * dy)
    inside = _inside_cells(episode.log.obstacle_map.polygons, shape, cell)
    pad = half + 1
    excluded = np.ones((shape[0] + 2 * pad, shape[1] + 2 * pad), dtype=bool)
    excluded[pad:-pad, pad:-pad] = inside
    sight = ~excluded[(origin[:, 0, None] + pad + offs)[:, :, None],
                      (origin[:, 1, None] + pad + offs)[:, None, :]]
    profile = _profiles(xy, episode.log.obstacle_map.polygons, r_hi, bins)
    k = (np.arctan2(dy, dx) * np.float32(bins / (2 * np.pi)) + np.float32(bins)).astype(
        np.int32) & (bins - 1)
    k += (np.arange(len(xy), dtype=np.int32) * bins)[:, None, None]
    sight &= dist < np.take(profile.astype(np.float32).reshape(-1), k)
    if band is None:
        near = sight & (dist <= r_lo)
        weight = near.astype(np.uint8) + (sight & (dist <= r_hi))
    else:
        deg = np.rint(np.degrees(np.arctan2(dy, dx))).astype(np.int64) % 360
        radius = episode.log.radio_range
        near = sight & (dist <= radius * band[0][deg])
        weight = near.astype(np.uint8) + (sight & (dist <= radius * band[1][deg]))
    certain = np.zeros((shape[0] + 2 * pad, shape[1] + 2 * pad), dtype=np.int32)
    for (ox, oy), block in zip(origin + pad, near, strict=True):
        certain[ox:ox + size, oy:oy + size] += block
    return weight.reshape(-1), certain[pad:-pad, pad:-pad]


def test_chunked_raster_with_shared_geometry_equals_the_whole_raster(small_log, monkeypatch):
    """The raster computed in chunks of transmitters, with the beacons' geometry shared between
    a DOI-bound pass and a band pass, is the whole-raster computation, entry for entry."""
    from aoass_env.localization import consensus as module

    episode = prepare(small_log)
    assert small_log.obstacle_map.polygons          # line of sight in play
    rng = np.random.default_rng(1)
    band = (0.9 + 0.1 * rng.uniform(0.0, 1.0, 360), 1.0 + 0.1 * rng.uniform(-1.0, 1.0, 360))
    band[1][::7] = 1.0                              # thresholds at the exact range too
    for cells in (1 << 21, 5000):                   # one chunk; a few transmitters per chunk
        monkeypatch.setattr(module, "_CHUNK_CELLS", cells)
        monkeypatch.setattr(module, "_LAST_GEOMETRY", [])
        for b in (None, band, None):                # the later passes reuse the geometry
            raster = visibility_raster(episode, band=b)
            weight, certain = _reference_raster(episode, band=b)
            n = len(weight)
            np.testing.assert_array_equal(raster.weight[:n], weight)
            assert not raster.weight[n:].any()
            np.testing.assert_array_equal(raster.certain, certain)
        assert module._LAST_GEOMETRY[0][0]() is episode


def test_float32_floor_keeps_float64_comparisons_exact():
    from aoass_env.localization.consensus import _float32_floor

    rng = np.random.default_rng(0)
    t = rng.uniform(20.0, 30.0, 360)
    floor = _float32_floor(t)
    assert floor.dtype == np.float32 and np.all(floor.astype(np.float64) <= t)
    d = np.concatenate([t.astype(np.float32), floor, np.nextafter(floor, np.float32(np.inf)),
                        rng.uniform(20.0, 30.0, 5000).astype(np.float32)])
    idx = np.concatenate([np.arange(360)] * 3 + [rng.integers(0, 360, 5000)])
    np.testing.assert_array_equal(d <= floor[idx], d <= t[idx])


def _consistent_log(nodes: np.ndarray, beacons: np.ndarray, radio_range: float = 25.0):
    """A prepared log whose receptions and node links are exactly the unit-disk ones."""
    d = np.hypot(*(beacons[:, None, :] - nodes[None, :, :]).transpose(2, 0, 1))
    receptions = np.argwhere(d <= radio_range)
    i, j = np.triu_indices(len(nodes), 1)
    links = np.column_stack([i, j])[np.hypot(*(nodes[i] - nodes[j]).T) <= radio_range]
    return prepare(make_log(nodes, beacons, receptions, links, radio_range=radio_range))


def test_a_reliable_node_is_no_transmitter_to_itself() -> None:
    # heard just inside the range, unheard just beyond: a region of about 0.5 m (reliable);
    # in the neighbour stage the node transmits, but its own certain range is no violation
    episode = record(ring(24.5, n=24), ring(25.5, n=24, phase=7.5))
    result = node_consensus(episode, np.array([0]))
    assert result.spread[0] <= 1.0 and result.violations[0] == 0
    np.testing.assert_allclose(result.estimate[0], CENTRE, atol=1e-9)


def test_the_neighbour_stage_refines_reliable_nodes_too(monkeypatch) -> None:
    """Node 0 is pinned to about 0.5 m by its beacons (reliable); node 1, 25.2 m to its west
    and not linked to it, rules out the western part of that region."""
    from aoass_env.localization import consensus as module

    true = np.array([CENTRE + [0.3, 0.0], CENTRE - [24.9, 0.0]])
    beacons = np.concatenate([ring(24.5, n=24), ring(25.5, n=24, phase=7.5),
                              true[1] + ring(24.5, n=24) - CENTRE,
                              true[1] + ring(25.5, n=24, phase=7.5) - CENTRE])
    episode = _consistent_log(true, beacons)
    assert len(episode.log.node_links) == 0
    refined = node_consensus(episode, np.array([0, 1]))
    monkeypatch.setattr(module, "NEIGHBOUR_ROUNDS", 0)
    beacons_only = node_consensus(episode, np.array([0, 1]))
    assert beacons_only.spread[0] <= 1.0                     # reliable after the first stage
    err = np.hypot(*(refined.estimate[0] - true[0]))
    err0 = np.hypot(*(beacons_only.estimate[0] - true[0]))
    assert refined.estimate[0, 0] > beacons_only.estimate[0, 0] and err < err0


def test_neighbour_stages_reuse_the_beacon_scores_exactly(doi_sim, monkeypatch) -> None:
    """The neighbour stages read the beacons' violations kept from the first stage; scoring
    the beacons again gives the same estimates, spreads and violations."""
    from aoass_env.localization import consensus as module

    episode = prepare(doi_sim.finish())
    kept = node_consensus(episode)
    solve = module._solve
    monkeypatch.setattr(module, "_solve",
                        lambda parts, reach, result, rows, kept=None:
                        solve(parts, reach, result, rows))
    again = node_consensus(episode)
    for name in ("estimate", "spread", "violations"):
        np.testing.assert_array_equal(getattr(kept, name), getattr(again, name))


@pytest.mark.parametrize("method", ["consensus", "olstm-dvhop"])
@pytest.mark.parametrize("x", [-0.6, -1.0, 100.6, 101.0])
def test_a_beacon_a_log_places_just_off_the_field_is_localized(method, x) -> None:
    """A log may place a beacon up to 1 % of its side off the field; the consensus raster's
    ring of off-field cells held only about one cell, and such a beacon's stencil ran past
    it: a broadcast error or an IndexError, in a traceback."""
    log = make_log(np.array([[5.0 if x < 50 else 95.0, 50.0]]),
                   np.array([[x, 50.0], [10.0 if x < 50 else 90.0, 40.0],
                             [10.0 if x < 50 else 90.0, 60.0]]),
                   np.array([[0, 0], [1, 0], [2, 0]]), np.zeros((0, 2)))
    est = localize(log, method)
    assert np.isfinite(est).all() and (0.0 <= est).all() and (est <= 100.0).all()


def test_the_fallback_centroid_of_beacons_off_the_field_stays_on_it() -> None:
    """A covered node whose heard discs do not overlap keeps its heard beacons' centroid, which
    beacons just off the field put off it (x = -0.225 m)."""
    ys = np.r_[np.linspace(0, 10, 12), np.linspace(90, 100, 12)]
    beacons = np.column_stack([np.where(np.arange(24) % 2, -0.45, 0.0), ys])
    log = make_log(np.array([[0.5, 50.0]]), beacons, np.array([[i, 0] for i in range(24)]),
                   np.zeros((0, 2)))
    assert prepare(log).heard_centroid[0, 0] < 0.0
    for method in ("consensus", "olstm-dvhop"):
        est = localize(log, method)
        assert est[0, 0] == 0.0 and est[0, 1] == 50.0
