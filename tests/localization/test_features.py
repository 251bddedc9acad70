"""Feature sequences: windows, order, heard flags, caps."""

from __future__ import annotations

import numpy as np
import pytest

from aoass_env.localization.episode import prepare
from aoass_env.localization.features import FEATURE_NAMES, build_sequences


@pytest.fixture(scope="module")
def episode(small_log):
    return prepare(small_log)


def test_sequences_hold_every_heard_beacon_in_time_order(episode) -> None:
    nodes = np.flatnonzero(episode.covered)
    seq = build_sequences(episode, nodes, episode.heard_centroid[nodes], np.zeros(len(nodes)))
    assert seq.features.shape == (len(nodes), seq.beacons.shape[1], len(FEATURE_NAMES))
    heard_col = FEATURE_NAMES.index("heard")
    rec = episode.log.receptions
    for s, node in enumerate(nodes):
        b = seq.beacons[s, :seq.lengths[s]]
        assert np.all(np.diff(b) > 0)
        assert np.all(seq.beacons[s, seq.lengths[s]:] == -1)
        heard = set(rec[rec[:, 1] == node, 0])
        assert heard <= set(b)
        np.testing.assert_array_equal(seq.features[s, :len(b), heard_col],
                                      [float(x in heard) for x in b])
    assert np.all(seq.features[~seq.mask] == 0)


def test_max_len_keeps_the_nearest(episode) -> None:
    nodes = np.flatnonzero(episode.covered)[:3]
    refs = episode.heard_centroid[nodes]
    seq = build_sequences(episode, nodes, refs, np.zeros(3), max_len=5)
    full = build_sequences(episode, nodes, refs, np.zeros(3))
    rng_col = FEATURE_NAMES.index("range")
    for s in range(3):
        kept = np.sort(seq.features[s, :seq.lengths[s], rng_col])
        np.testing.assert_allclose(kept, np.sort(full.features[s, :full.lengths[s],
                                                               rng_col])[:5])


def test_node_without_beacons_is_an_error(episode) -> None:
    silent = np.flatnonzero(np.bincount(episode.log.receptions[:, 1],
                                        minlength=episode.log.n_nodes) == 0)
    if len(silent) == 0:
        pytest.skip("every node heard a beacon")
    with pytest.raises(ValueError, match="heard no beacon"):
        build_sequences(episode, silent[:1], np.zeros((1, 2)), np.zeros(1))
