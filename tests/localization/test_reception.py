"""Reception record: pairs agree with the true DOI pattern; histograms and bands."""

from __future__ import annotations

import numpy as np
import pytest

from aoass_env.localization.episode import prepare
from aoass_env.localization.reception import (
    HIST_BINS,
    N_FEATURES,
    Z_RANGE,
    pair_histograms,
    pair_statistics,
    range_band,
)


def test_pairs_at_true_positions_obey_the_anchor_pattern(doi_sim) -> None:
    episode = prepare(doi_sim.finish())
    nodes = np.arange(episode.log.n_nodes)
    record = pair_statistics(episode, nodes, episode.log.nodes)
    k = doi_sim.radio.anchor_pattern[record.degree]
    reach = (k - 1) / 0.15  # z of the range circle in each pair's direction
    assert record.heard.any() and (~record.heard).any()
    # no moving obstacles: heard iff within the pattern's range (unheard pairs are in sight)
    assert np.all(record.z[record.heard] <= reach[record.heard] + 1e-9)
    assert np.all(record.z[~record.heard] > reach[~record.heard] - 1e-9)
    assert np.all(np.abs(record.z) <= Z_RANGE + 1e-9)


def test_histograms_count_pairs_per_degree(doi_sim) -> None:
    episode = prepare(doi_sim.finish())
    record = pair_statistics(episode, np.arange(episode.log.n_nodes), episode.log.nodes)
    x = pair_histograms(record)
    assert x.shape == (360, N_FEATURES)
    counts = np.expm1(x[:, :2 * HIST_BINS])
    np.testing.assert_allclose(counts[:, :HIST_BINS].sum(), record.heard.sum(), rtol=1e-5)
    np.testing.assert_allclose(counts[:, HIST_BINS:].sum(), (~record.heard).sum(), rtol=1e-5)
    np.testing.assert_allclose(x[:, -1], 1.5)  # 10 DOI
    none = pair_histograms(record, np.zeros(len(record.z), dtype=bool))
    assert np.all(none[:, :-1] == 0)


def test_pair_statistics_need_irregularity(small_log) -> None:
    episode = prepare(small_log)
    with pytest.raises(ValueError, match="DOI > 0"):
        pair_statistics(episode, np.arange(3), episode.log.nodes[:3])


def test_range_band_is_ordered_and_clipped_to_the_doi_bound() -> None:
    mean = np.linspace(-1, 1, 360)
    lo, hi = range_band(mean, np.full(360, 0.3), 0.1, 1.0)
    assert np.all(lo <= hi) and lo.min() >= 0.9 - 1e-12 and hi.max() <= 1.1 + 1e-12
    np.testing.assert_allclose(lo[180], 1 + 0.1 * (mean[180] - 0.3))
    lo0, hi0 = range_band(mean, np.full(360, 0.3), 0.1, 0.0)
    np.testing.assert_array_equal(lo0, hi0)


def test_no_reliable_nodes_give_an_empty_record(doi_sim) -> None:
    episode = prepare(doi_sim.finish())
    record = pair_statistics(episode, np.zeros(0, np.int64), np.zeros((0, 2)))
    assert len(record.z) == 0
    assert np.all(pair_histograms(record)[:, :-1] == 0)


def test_with_radio_through_obstacles_every_unheard_pair_is_kept() -> None:
    """line_of_sight false: an obstacle blocks no reception, so an unheard pair behind one is
    evidence of the range like any other; the record dropped it (1019 of 1034 unheard pairs
    on a dense log), and OLSTM-DV-Hop then localized worse than the consensus alone."""
    from aoass_env.config import AOASSConfig
    from aoass_env.simulator import Simulator
    config = AOASSConfig(field_size=40.0, n_nodes=60, obstacle_density=0.3,
                         n_moving_obstacles=0, doi=0.15, line_of_sight=False)
    sim = Simulator(config, np.random.default_rng(2), seed=2)
    sim.run()
    episode = prepare(sim.finish())
    log, nodes = episode.log, episode.log.nodes
    record = pair_statistics(episode, np.arange(log.n_nodes), nodes)
    lo, hi = log.radio_range * (1 - Z_RANGE * 0.15), log.radio_range * (1 + Z_RANGE * 0.15)
    d = np.hypot(*(nodes[None, :, :] - episode.beacon_xy[:, None, :]).transpose(2, 0, 1))
    heard = np.zeros(d.shape, dtype=bool)
    heard[log.receptions[:, 0], log.receptions[:, 1]] = True
    in_band = (d >= lo) & (d <= hi)
    assert (~record.heard).sum() == (in_band & ~heard).sum() > 0
    assert record.heard.sum() == (in_band & heard).sum()
