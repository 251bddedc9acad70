"""Hyperparameter files of ``python train.py`` (RL-Zoo style YAML, loaded safely).

A file has one section per algorithm (``td3-lstm``, ``td3``). A section holds the algorithm's
constructor keywords (SB3's names: ``learning_rate``, ``buffer_size``, ``batch_size``, ...) plus:

* ``n_timesteps``: default training budget (env steps);
* ``policy``: SB3 policy name;
* ``action_noise``: ``{kind: normal | ornstein-uhlenbeck, sigma: float}`` (a mapping, never a
  string to evaluate);
* ``env``: keywords of :func:`agents.training.make_training_env` (``maps``, ``field_size``,
  ``n_nodes``, densities, ...);
* ``eval``: ``{freq: env steps, episodes: int}`` of the evaluation on the validation maps;
* ``checkpoint_freq``: env steps between checkpoints.

Unknown keys and values of the wrong type or range raise :class:`HyperparameterError` naming the
file, the section and the key. Files are read with ``yaml.safe_load``: no Python objects, no
``eval`` of strings.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from stable_baselines3 import TD3
from stable_baselines3.common.noise import (
    ActionNoise,
    NormalActionNoise,
    OrnsteinUhlenbeckActionNoise,
)

from agents.recurrent_td3 import RecurrentTD3

__all__ = ["ALGORITHMS", "HyperparameterError", "action_noise", "load_hyperparams"]

#: Algorithm name on the command line -> SB3 class.
ALGORITHMS: dict[str, type] = {"td3-lstm": RecurrentTD3, "td3": TD3}

#: Keys of a section that are not constructor keywords.
EXTRA_KEYS = ("n_timesteps", "policy", "action_noise", "env", "eval", "checkpoint_freq")
#: Constructor keywords the training script sets itself.
RESERVED = ("self", "env", "policy", "tensorboard_log", "verbose", "seed", "device",
            "_init_setup_model", "action_noise", "replay_buffer_class")

# (type, low, high, low inclusive) of the common numeric keywords
_NUMERIC: dict[str, tuple[type, float, float, bool]] = {
    "learning_rate": (float, 0.0, 1.0, False), "buffer_size": (int, 1, math.inf, True),
    "learning_starts": (int, 0, math.inf, True), "batch_size": (int, 1, math.inf, True),
    "tau": (float, 0.0, 1.0, False), "gamma": (float, 0.0, 1.0, False),
    "gradient_steps": (int, -1, math.inf, True), "policy_delay": (int, 1, math.inf, True),
    "target_policy_noise": (float, 0.0, math.inf, True),
    "target_noise_clip": (float, 0.0, math.inf, True), "n_timesteps": (int, 1, math.inf, True),
    "checkpoint_freq": (int, 1, math.inf, True), "burn_in": (int, 0, math.inf, True),
    "train_length": (int, 1, math.inf, True), "n_steps": (int, 1, math.inf, True),
    "critic_warmup": (int, 0, math.inf, True),
}


class HyperparameterError(ValueError):
    """A hyperparameter file that cannot be used; the message names the file and the key."""


def _check_number(where: str, key: str, value: Any) -> None:
    kind, low, high, low_incl = _NUMERIC[key]
    ok_type = isinstance(value, (int, float)) and not isinstance(value, bool)
    if kind is int:
        ok_type = ok_type and float(value).is_integer()
    if not ok_type or not math.isfinite(value) or value > high \
            or (value < low if low_incl else value <= low):
        bound = f"{'[' if low_incl else '('}{low}, {high}]"
        what = "an integer" if kind is int else "a number"
        raise HyperparameterError(f"{where}.{key}: must be {what} in {bound}, got {value!r}")


def load_hyperparams(path: str | Path, algo: str) -> dict[str, Any]:
    """The section ``algo`` of the YAML file ``path``, validated.

    Raises:
        HyperparameterError: a missing file or section, unknown keys, bad values.
    """
    path = Path(path)
    if algo not in ALGORITHMS:
        raise HyperparameterError(f"algo {algo!r} is not one of {sorted(ALGORITHMS)}")
    try:
        data = yaml.safe_load(path.read_text())
    except FileNotFoundError:
        raise HyperparameterError(f"{path}: no such hyperparameter file") from None
    except yaml.YAMLError as exc:
        raise HyperparameterError(f"{path}: not valid YAML ({exc})") from None
    if not isinstance(data, Mapping) or algo not in data:
        found = sorted(data) if isinstance(data, Mapping) else type(data).__name__
        raise HyperparameterError(f"{path}: no section {algo!r} (found {found})")
    section = data[algo]
    where = f"{path}: {algo}"
    if not isinstance(section, Mapping):
        raise HyperparameterError(f"{where}: must be a mapping of keys to values")
    params = inspect.signature(ALGORITHMS[algo].__init__).parameters
    valid = sorted((set(params) - set(RESERVED)) | set(EXTRA_KEYS))
    for key, value in section.items():
        if key not in valid:
            raise HyperparameterError(f"{where}.{key}: unknown key; valid keys: {valid}")
        if key in _NUMERIC:
            _check_number(where, key, value)
    for key in ("env", "eval", "policy_kwargs"):
        if key in section and not isinstance(section[key], Mapping):
            raise HyperparameterError(f"{where}.{key}: must be a mapping, got "
                                      f"{type(section[key]).__name__}")
    if "action_noise" in section:
        _check_noise(where, section["action_noise"])
    if "train_freq" in section:
        tf = section["train_freq"]
        ok = (isinstance(tf, int) and not isinstance(tf, bool) and tf > 0) or (
            isinstance(tf, list) and len(tf) == 2 and isinstance(tf[0], int) and tf[0] > 0
            and tf[1] in ("step", "episode"))
        if not ok:
            raise HyperparameterError(f"{where}.train_freq: must be a positive integer or "
                                      f"[n, step|episode], got {tf!r}")
    # integers written as 32.0 reach SB3 as ints
    return {k: int(v) if k in _NUMERIC and _NUMERIC[k][0] is int else v
            for k, v in section.items()}


def _check_noise(where: str, spec: Any) -> None:
    if not isinstance(spec, Mapping) or set(spec) - {"kind", "sigma"} \
            or spec.get("kind") not in ("normal", "ornstein-uhlenbeck"):
        raise HyperparameterError(
            f"{where}.action_noise: must be {{kind: normal | ornstein-uhlenbeck, sigma: "
            f"number}}, got {spec!r}")
    sigma = spec.get("sigma", 0.1)
    if isinstance(sigma, bool) or not isinstance(sigma, (int, float)) or not 0 <= sigma < 10:
        raise HyperparameterError(f"{where}.action_noise.sigma: must be a number in [0, 10), "
                                  f"got {sigma!r}")


def action_noise(spec: Mapping[str, Any] | None, n_actions: int) -> ActionNoise | None:
    """The SB3 action noise of a validated ``action_noise`` mapping (None: no noise)."""
    if spec is None:
        return None
    mean, sigma = np.zeros(n_actions), float(spec.get("sigma", 0.1)) * np.ones(n_actions)
    if spec["kind"] == "normal":
        return NormalActionNoise(mean, sigma)
    return OrnsteinUhlenbeckActionNoise(mean, sigma)
