"""Coverage replayed from a log agrees with the simulator; config and reception errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from aoass_env.beacon_log import BeaconLog, BeaconLogError
from aoass_env.localization import METHODS, localize
from aoass_env.localization.episode import log_config, prepare
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
    with pytest.raises(BeaconLogError, match=r"receptions.*row 1 repeats an earlier \(beacon, "
                                             r"node\)"):
        make_log(np.zeros((1, 2)), np.zeros((1, 2)), [[0, 0], [0, 0]], [])


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


def test_a_log_without_nodes_is_named() -> None:
    log = make_log(np.zeros((0, 2)), np.array([[5.0, 5.0]]), [], [])
    for method in METHODS:
        with pytest.raises(BeaconLogError) as info:
            localize(log, method)
        assert str(info.value) == "beacon log key 'nodes': the log holds no nodes: nothing to " \
                                  "localize"


def test_flood_limit_of_a_prepared_episode(small_log) -> None:
    episode = prepare(small_log, flood_limit=2)
    np.testing.assert_array_equal(localize(episode, "dvhop"),
                                  localize(small_log, "dvhop", flood_limit=2))
    assert np.array_equal(localize(episode, "dvhop", flood_limit=2),
                          localize(episode, "dvhop"), equal_nan=True)
    with pytest.raises(ValueError) as info:
        localize(episode, "dvhop", flood_limit=5)       # was silently flooded 2 hops
    assert str(info.value) == ("flood_limit=5 differs from the prepared episode's "
                               "flood_limit=2; pass the log, or prepare it with this flood_limit")
    with pytest.raises(ValueError, match="flood_limit=0 must be an integer"):
        localize(episode, "dvhop", flood_limit=0)       # was silently ignored
    # a whole float is that integer, as for every integer parameter (2.0 used to be refused)
    assert np.array_equal(localize(episode, "dvhop", flood_limit=2.0),
                          localize(episode, "dvhop"), equal_nan=True)
    for bad in (2.5, True):
        with pytest.raises(ValueError, match=rf"flood_limit={bad!r} must be an integer in "
                                             r"\[2, inf\) hops"):
            localize(small_log, "dvhop", flood_limit=bad)


@pytest.mark.parametrize("method", ["dvhop", "consensus"])
def test_a_checkpoint_for_a_method_that_reads_none_is_refused(small_log, method) -> None:
    # it used to be ignored, even a wrong type or a missing file
    for checkpoint in (3, "/no/such/checkpoint.pt"):
        with pytest.raises(ValueError, match=rf"checkpoint is read by method='olstm-dvhop' "
                                             rf"only, not '{method}'"):
            localize(small_log, method, checkpoint=checkpoint)


@pytest.mark.parametrize("method", ["consensus", "olstm-dvhop"])
def test_a_flood_limit_for_a_method_that_floods_nothing_is_refused(small_log, method) -> None:
    # it was ignored: localize(log, "consensus", flood_limit=999999) gave the default's answer
    with pytest.raises(ValueError, match=rf"flood_limit is read by method='dvhop' only, not "
                                         rf"'{method}'"):
        localize(small_log, method, flood_limit=999999)


@pytest.mark.parametrize("checkpoint", [3, b"m.pt", ["m.pt"]])
def test_a_checkpoint_of_the_wrong_type_is_named(small_log, checkpoint) -> None:
    with pytest.raises(TypeError) as info:
        localize(small_log, "olstm-dvhop", checkpoint=checkpoint)
    assert str(info.value) == (f"checkpoint must be a path or a loaded OLSTM, got "
                               f"{type(checkpoint).__name__}")
