"""The training environments of ``python train.py``: the full safety stack on the shipped
training maps (never maps/test), one map per episode."""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from aoass_env.maps import list_maps, validation_split
from aoass_env.wrappers import MapSampler, make_safe_env

__all__ = ["TRAINING_SPLITS", "make_training_env"]

#: Where training environments take their maps from: the maps to fit on, or the held-out ones.
TRAINING_SPLITS = ("train", "validation")


def make_training_env(*, split: str = "train", field_size: float = 100.0,
                      densities: tuple[float, float] = (0.1, 0.4), cycle: bool = False,
                      safety: dict[str, Any] | None = None, tracker: dict[str, Any] | None = None,
                      **config: Any) -> gym.Env:
    """The full safety stack on shipped training maps with ``field_size`` (m) and density in
    ``densities``, one map per episode (drawn, or in turn with ``cycle``): ``split="train"``
    takes the maps to fit on, ``"validation"`` the ones held out for model selection
    (:func:`aoass_env.maps.validation_split`); maps/test is never used. ``config``: further
    AOASS-v0 keywords (e.g. ``n_nodes``)."""
    if split not in TRAINING_SPLITS:
        raise ValueError(f"split={split!r} must be one of {TRAINING_SPLITS} (maps/test is for "
                         f"reported results only)")
    fit, held_out = validation_split(list_maps("train", field_size=field_size,
                                               densities=tuple(densities)))
    maps = fit if split == "train" else held_out
    if not maps:
        raise ValueError(f"no shipped {split} maps with field_size={field_size} and densities "
                         f"in {list(densities)}")
    env = make_safe_env(field_size=field_size, tracker=tracker, safety=safety, **config)
    return MapSampler(env, maps, cycle=cycle)
