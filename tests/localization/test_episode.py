"""Coverage replayed from a log agrees with the simulator; config and reception errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from aoass_env.beacon_log import BeaconLog, BeaconLogError
from aoass_env.localization.episode import covered_nodes, log_config, prepare
from tests.localization.conftest import make_log


def test_coverage_matches_the_simulator(small_sim) -> None:
    episode = prepare(small_sim.finish())
    np.testing.assert_array_equal(episode.covered, small_sim.network.covered)


def test_heard_centroid(small_log) -> None:
    episode = prepare(small_log)
    rec = small_log.receptions
    node = rec[0, 1]
    heard = small_log.beacons[rec[rec[:, 1] == node, 0], 1:]
    np.testing.assert_allclose(episode.heard_centroid[node], heard.mean(axis=0))


def test_duplicate_reception_is_named() -> None:
    log = make_log(np.zeros((1, 2)), np.zeros((1, 2)), [[0, 0], [0, 0]], [])
    with pytest.raises(BeaconLogError, match="more than once"):
        covered_nodes(log, log_config(log))


def test_invalid_recorded_config(small_log) -> None:
    arrays = small_log.arrays()
    arrays["config_json"] = json.dumps({"config": {"radio_range": -1}})
    bad = BeaconLog(**{k: v for k, v in arrays.items()})
    with pytest.raises(BeaconLogError, match="config_json"):
        log_config(bad)


def test_config_defaults_to_the_log_radio_range(small_log) -> None:
    arrays = small_log.arrays()
    arrays["config_json"] = "{}"
    assert log_config(BeaconLog(**arrays)).radio_range == small_log.radio_range
