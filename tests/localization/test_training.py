"""Training pipeline: map split, episode specs, examples, a tiny run lowers the loss."""

from __future__ import annotations

import numpy as np
import torch

from aoass_env.localization.episode import prepare
from aoass_env.localization.features import FEATURE_NAMES
from aoass_env.localization.olstm import OLSTM
from aoass_env.localization.training import (
    episode_specs,
    gaussian_nll,
    map_density,
    node_examples,
    pad_batch,
    validation_maps,
)
from aoass_env.maps import list_maps


def test_specs_use_training_maps_and_hold_out_validation_maps() -> None:
    names = list_maps("train")
    val = validation_maps(names)
    assert len(val) == len({map_density(n) for n in names})
    train = [n for n in names if n not in val]
    specs = episode_specs(40, train, seed=3)
    assert specs == episode_specs(40, train, seed=3)
    assert all(s.map_name in train and s.map_name.startswith("train/") for s in specs)
    assert {map_density(s.map_name)[1] for s in specs} == {100.0, 200.0}


def test_tiny_training_run_lowers_the_loss(small_log) -> None:
    torch.manual_seed(0)
    feats, targets = node_examples(prepare(small_log), np.random.default_rng(0), 10, 3.0)
    assert all(f.shape == (len(t), len(FEATURE_NAMES))
               for f, t in zip(feats, targets, strict=True))
    every = np.arange(len(feats))
    x, lengths = pad_batch(feats, every)
    y, _ = pad_batch(targets, every)
    mask = (torch.arange(x.shape[1])[None] < lengths[:, None]).float()
    model = OLSTM(hidden=8)
    optim = torch.optim.Adam(model.parameters(), lr=1e-2)
    losses = []
    for _ in range(30):
        loss = gaussian_nll(*model(x, lengths), y, mask)
        optim.zero_grad()
        loss.backward()
        optim.step()
        losses.append(float(loss.detach()))
    assert losses[-1] < losses[0] - 0.1
