"""OLSTM model, checkpoints and OLSTM-DV-Hop inference."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from aoass_env.beacon_log import BeaconLogError
from aoass_env.localization import localize
from aoass_env.localization.features import FEATURE_NAMES
from aoass_env.localization.olstm import (
    OLSTM,
    CheckpointError,
    load_checkpoint,
    save_checkpoint,
)
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


def test_padding_does_not_change_predictions(model) -> None:
    x = torch.randn(1, 6, len(FEATURE_NAMES))
    d1, v1 = model(x, torch.tensor([6]))
    padded = torch.cat([x, torch.randn(1, 4, len(FEATURE_NAMES))], dim=1)
    d2, v2 = model(padded, torch.tensor([6]))
    torch.testing.assert_close(d1, d2[:, :6])
    torch.testing.assert_close(v1, v2[:, :6])


@pytest.mark.parametrize("change, match", [
    ({"feature_names": ["dx", "dy"]}, "feature set"),
    ({"feature_version": 99}, "feature set"),
    ({"version": 99}, "version 99"),
    ({"format": "other"}, "not an"),
])
def test_mismatched_checkpoint(tmp_path, model, change, match) -> None:
    path = tmp_path / "m.pt"
    save_checkpoint(model, path, {})
    payload = torch.load(path, weights_only=True)
    payload.update(change)
    torch.save(payload, path)
    with pytest.raises(CheckpointError, match=match):
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


def test_log_without_beacons(model) -> None:
    with pytest.raises(BeaconLogError, match="no beacons"):
        localize(make_log(np.zeros((2, 2)), np.zeros((0, 2)), [], []), checkpoint=model)
