"""OLSTM model, checkpoints and OLSTM-DV-Hop inference."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from aoass_env.beacon_log import BeaconLogError
from aoass_env.localization import localize, prepare
from aoass_env.localization.consensus import node_consensus
from aoass_env.localization.olstm import (
    OLSTM,
    CheckpointError,
    load_checkpoint,
    olstm_dvhop,
    save_checkpoint,
)
from aoass_env.localization.reception import N_FEATURES
from tests.localization.conftest import make_log


@pytest.fixture()
def model() -> OLSTM:
    torch.manual_seed(0)
    return OLSTM(hidden=8).eval()


def test_checkpoint_round_trip(tmp_path, model, small_log) -> None:
    path = tmp_path / "m.pt"
    save_checkpoint(model, path, {"note": "test"})
    loaded = load_checkpoint(path)
    np.testing.assert_array_equal(localize(small_log, checkpoint=model),
                                  localize(small_log, checkpoint=loaded))


def test_inference_is_deterministic_and_covers_exactly_the_covered(model, small_sim) -> None:
    log = small_sim.finish()
    a = localize(log, "olstm-dvhop", checkpoint=model)
    b = localize(log, "olstm-dvhop", checkpoint=model)
    np.testing.assert_array_equal(a, b)
    covered = np.asarray(small_sim.network.covered)
    assert np.all(np.isfinite(a[covered])) and np.all(np.isnan(a[~covered]))


def test_doi_zero_is_the_consensus(model, small_log) -> None:
    np.testing.assert_array_equal(localize(small_log, "olstm-dvhop", checkpoint=model),
                                  localize(small_log, "consensus"))


def test_doi_episode_localizes_exactly_the_covered_nodes(model, doi_sim) -> None:
    log = doi_sim.finish()
    episode = prepare(log)
    est = olstm_dvhop(episode, model)
    covered = np.asarray(doi_sim.network.covered)
    assert np.all(np.isfinite(est[covered])) and np.all(np.isnan(est[~covered]))
    np.testing.assert_array_equal(est, localize(log, "olstm-dvhop", checkpoint=model))


def test_output_is_a_bounded_mean_per_degree(model) -> None:
    with torch.no_grad():
        mean, logstd = model(torch.randn(2, 360, N_FEATURES) * 3)
    assert mean.shape == logstd.shape == (2, 360)
    assert float(mean.abs().max()) <= 1.0


@pytest.mark.parametrize("change, match", [
    ({"feature_names": ["dx", "dy"]}, "feature set"),
    ({"feature_version": 99}, "feature set"),
    ({"version": 99}, "version 99"),
    ({"format": "other"}, "not an"),
    ({"band_width": float("nan")}, "band_width"),
    ({"band_width": -1.0}, "band_width"),
    ({"hidden": 0}, "hidden"),
])
def test_mismatched_checkpoint(tmp_path, model, change, match) -> None:
    path = tmp_path / "m.pt"
    save_checkpoint(model, path, {})
    payload = torch.load(path, weights_only=True)
    payload.update(change)
    torch.save(payload, path)
    with pytest.raises(CheckpointError, match=match):
        load_checkpoint(path)


def test_nan_weights_are_refused(tmp_path, model) -> None:
    path = tmp_path / "m.pt"
    save_checkpoint(model, path, {})
    payload = torch.load(path, weights_only=True)
    payload["state_dict"]["head.2.bias"] = torch.full_like(payload["state_dict"]["head.2.bias"],
                                                           float("nan"))
    torch.save(payload, path)
    with pytest.raises(CheckpointError, match="head.2.bias holds NaN"):
        load_checkpoint(path)


def test_missing_and_garbage_checkpoints(tmp_path) -> None:
    with pytest.raises(CheckpointError, match="no localizer checkpoint"):
        load_checkpoint(tmp_path / "absent.pt")
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"not a checkpoint")
    with pytest.raises(CheckpointError, match="not a readable"):
        load_checkpoint(bad)
    with pytest.raises(CheckpointError, match="no localizer checkpoint"):
        localize(make_log(np.zeros((1, 2)), np.ones((1, 2)), [[0, 0]], []),
                 checkpoint=tmp_path / "absent.pt")


class _Evil:
    def __reduce__(self):
        return (math.hypot, (3.0, 4.0))   # not print: Ray replaces it once imported


def test_a_refused_or_damaged_checkpoint_is_named_in_one_line(tmp_path, model) -> None:
    garbage, evil, empty = tmp_path / "garbage.pt", tmp_path / "evil.pt", tmp_path / "empty.pt"
    garbage.write_bytes(b"garbage")
    torch.save({"x": _Evil()}, evil)
    empty.write_bytes(b"")
    for path, reason in (
            (garbage, "weights-only load refused: Unsupported operand 103"),
            (evil, "weights-only load refused: Unsupported global: GLOBAL math.hypot was not "
                   "an allowed global by default"),
            (empty, "EOFError")):
        with pytest.raises(CheckpointError) as info:
            load_checkpoint(path)
        assert str(info.value) == f"{path}: not a readable torch checkpoint ({reason})"
    save_checkpoint(model, tmp_path / "m.pt", {})
    payload = torch.load(tmp_path / "m.pt", weights_only=True)
    del payload["state_dict"]["head.2.bias"]
    payload["state_dict"]["extra"] = torch.zeros(1)
    torch.save(payload, tmp_path / "keys.pt")
    with pytest.raises(CheckpointError, match='Missing key.*"head.2.bias"') as info:
        load_checkpoint(tmp_path / "keys.pt")
    assert "\n" not in str(info.value) and "\t" not in str(info.value)


@pytest.mark.parametrize("change, message", [
    ({"hidden": 10**9}, "state_dict: embed.0.weight must be a tensor of shape "
                        "(hidden=1000000000, 25), got (8, 25)"),
    ({"state_dict": 3}, "state_dict must be a dict of weight tensors, got int"),
])
def test_weights_that_do_not_fit_hidden_are_refused_before_the_model_is_built(
        tmp_path, model, change, message) -> None:
    path = tmp_path / "m.pt"
    save_checkpoint(model, path, {})
    payload = torch.load(path, weights_only=True)
    payload.update(change)
    torch.save(payload, path)
    with pytest.raises(CheckpointError) as info:
        load_checkpoint(path)
    assert str(info.value) == f"{path}: {message}"


def test_log_without_beacons(model) -> None:
    with pytest.raises(BeaconLogError, match="no beacons"):
        localize(make_log(np.zeros((2, 2)), np.zeros((0, 2)), [], []), checkpoint=model)


def test_a_first_pass_of_other_nodes_is_refused(model, doi_sim) -> None:
    episode = prepare(doi_sim.finish())
    first = node_consensus(episode, np.flatnonzero(episode.covered)[:3])
    with pytest.raises(ValueError, match="covered nodes"):
        olstm_dvhop(episode, model, first)


@pytest.mark.parametrize("dtype", [torch.int64, torch.bool, torch.complex64])
def test_weights_that_are_not_floats_are_refused(tmp_path, model, dtype) -> None:
    # load_state_dict cast them (a complex weight lost its imaginary part) and the CLI exited 0
    path = tmp_path / "m.pt"
    save_checkpoint(model, path, {})
    payload = torch.load(path, weights_only=True)
    payload["state_dict"]["head.2.bias"] = payload["state_dict"]["head.2.bias"].to(dtype)
    torch.save(payload, path)
    with pytest.raises(CheckpointError, match=rf"head.2.bias must hold floating-point weights, "
                                              rf"got {dtype}"):
        load_checkpoint(path)
