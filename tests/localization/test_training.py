"""Training pipeline: map split, episode specs, examples, a tiny run lowers the loss."""

from __future__ import annotations

import numpy as np
import torch

from aoass_env.localization.episode import prepare
from aoass_env.localization.olstm import OLSTM
from aoass_env.localization.training import (
    augment,
    episode_specs,
    example,
    gaussian_nll,
    map_density,
)
from aoass_env.maps import list_maps, validation_split


def test_specs_use_training_maps_and_hold_out_validation_maps() -> None:
    fit, val = validation_split(list_maps("train"))
    assert val and not set(fit) & set(val)
    specs = episode_specs(100, fit, seed=3)
    assert specs == episode_specs(100, fit, seed=3)
    assert all(s.map_name in fit and s.map_name.startswith("train/") for s in specs)
    assert {s.doi for s in specs} == {0.0, 0.05, 0.1, 0.15, 0.2}
    assert {map_density(s.map_name)[1] for s in specs} == {100.0, 200.0}


def test_example_target_and_augmentation(doi_sim) -> None:
    ex = example(prepare(doi_sim.finish()), doi_sim.radio.anchor_pattern)
    assert ex.target.shape == (360,) and float(np.abs(ex.target).max()) <= 1.0
    np.testing.assert_allclose(1 + 0.15 * ex.target, doi_sim.radio.anchor_pattern, atol=1e-6)
    x, y = augment(ex, np.random.default_rng(0))
    assert x.shape == (360, 25)
    assert any(np.array_equal(y, np.roll(ex.target, s)) for s in range(360))


def test_tiny_training_run_lowers_the_loss(doi_sim) -> None:
    torch.manual_seed(0)
    ex = example(prepare(doi_sim.finish()), doi_sim.radio.anchor_pattern)
    rng = np.random.default_rng(0)
    model = OLSTM(hidden=8)
    optim = torch.optim.Adam(model.parameters(), lr=1e-2)
    losses = []
    for _ in range(30):
        pairs = [augment(ex, rng) for _ in range(4)]
        x = torch.from_numpy(np.stack([p[0] for p in pairs]))
        y = torch.from_numpy(np.stack([p[1] for p in pairs]))
        loss = gaussian_nll(*model(x), y)
        optim.zero_grad()
        loss.backward()
        optim.step()
        losses.append(float(loss.detach()))
    assert np.mean(losses[-5:]) < losses[0] - 0.1
