"""Validation of one algorithm's hyperparameters (a section of ``configs/*.yml`` or of a
``run.yml``) and the safe YAML reader of :mod:`agents.hyperparams` and :mod:`agents.checkpoints`.

Every key is checked, ``eval``, ``env`` (with ``safety`` and ``tracker``) and
``policy_kwargs`` included: unknown keys (with a did-you-mean suggestion), keys given twice and
values of the wrong type or range raise :class:`HyperparameterError` naming the file, the
section and the key. Files are read with a safe loader: no Python objects, no ``eval`` of
strings.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import re
from collections.abc import Hashable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from stable_baselines3.common.noise import (
    ActionNoise,
    NormalActionNoise,
    OrnsteinUhlenbeckActionNoise,
)

from agents.envs import make_training_env
from agents.policies import check_net_arch
from aoass_env.config import AOASSConfig, unknown_key_message
from aoass_env.planning import AdaptiveConfig
from aoass_env.safety.config import SafetyConfig, TrackerConfig
from aoass_env.validators import integer, one_line, real
from aoass_env.wrappers import make_safe_env

__all__ = ["EXTRA_KEYS", "HyperparameterError", "action_noise", "check_section", "env_keys",
           "key_value", "model_kwargs", "override_section", "policy_name", "read_yaml",
           "section_keys", "yaml_problem"]

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
    "stats_window_size": (int, 1, math.inf, True),
    "target_policy_noise": (float, 0.0, math.inf, True),
    "target_noise_clip": (float, 0.0, math.inf, True), "n_timesteps": (int, 1, math.inf, True),
    "checkpoint_freq": (int, 1, math.inf, True), "burn_in": (int, 0, math.inf, True),
    "train_length": (int, 1, math.inf, True), "n_steps": (int, 1, math.inf, True),
    "critic_warmup": (int, 0, math.inf, True),
    "actor_bound_penalty": (float, 0.0, math.inf, True),
}


#: Keys that take True or False: of a section, of its policy_kwargs, of its replay_buffer_kwargs.
_FLAGS = {"": ("optimize_memory_usage",),
          "policy_kwargs": ("normalize_images", "share_features_extractor", "current_features"),
          "replay_buffer_kwargs": ("handle_timeout_termination",)}
#: policy_kwargs that take a Python class, which a YAML file cannot name.
_CLASSES = ("activation_fn", "features_extractor_class", "optimizer_class")
#: The replay buffer keywords a section may set (the algorithm sets the others).
_BUFFER_KEYS = ["handle_timeout_termination"]


class HyperparameterError(ValueError):
    """A hyperparameter file that cannot be used; the message names the file and the key."""


#: The keys of ``eval``: env steps between evaluations, episodes per evaluation.
_EVAL: dict[str, tuple[type, float, float, bool]] = {
    "freq": (int, 1, math.inf, True), "episodes": (int, 1, math.inf, True)}


def _check_number(where: str, key: str, value: Any,
                  spec: tuple[type, float, float, bool] | None = None) -> int | float:
    """``value`` of ``where.key`` as an int or a float checked against ``spec`` (default: the
    key's :data:`_NUMERIC` entry); :class:`HyperparameterError` naming ``where.key``."""
    kind, low, high, low_incl = spec or _NUMERIC[key]
    top = None if high == math.inf else high
    if kind is int:
        return integer(f"{where}.{key}", value, low=low, high=top, error=HyperparameterError)
    return real(f"{where}.{key}", value, low=low, high=top, low_open=not low_incl,
                error=HyperparameterError)


class _UniqueKeyLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that refuses a mapping with a key given twice (merge keys, ``<<:
    *base``, keep their meaning: a key of the mapping itself overrides a merged one)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen = set()
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                continue                    # SafeLoader's flatten_mapping merges these
            key = self.construct_object(key_node, deep=deep)
            if not isinstance(key, Hashable):
                raise yaml.constructor.ConstructorError(
                    None, None, "a key must be a scalar, not a list or a mapping",
                    key_node.start_mark)
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"key {key!r} is given twice", key_node.start_mark)
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


# YAML 1.2's exponent floats without a point (1e-4, 3E5): YAML 1.1, PyYAML's, reads them as
# strings, and "learning_rate: 1e-4" was refused as "'1e-4' must be a number"
_UniqueKeyLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float", re.compile(r"^[-+]?[0-9][0-9_]*[eE][-+]?[0-9]+$"),
    list("-+0123456789"))


def read_yaml(path: str | Path, what: str = "hyperparameter file") -> Any:
    """The YAML document at ``path``, read safely (no Python objects; a key given twice is an
    error); :class:`HyperparameterError` naming the file for a missing, unreadable or invalid
    one."""
    path = Path(path)
    try:
        return yaml.load(path.read_text(encoding="utf-8"), Loader=_UniqueKeyLoader)
    except FileNotFoundError:
        raise HyperparameterError(f"{path}: no such {what}") from None
    except (IsADirectoryError, PermissionError, UnicodeDecodeError) as exc:
        raise HyperparameterError(f"{path}: not a readable {what} ({one_line(exc)})") from None
    except yaml.YAMLError as exc:
        raise HyperparameterError(f"{path}: not valid YAML ({yaml_problem(exc)})") from None


def yaml_problem(exc: yaml.YAMLError) -> str:
    """PyYAML's error ``exc`` on one line: ``line L, column C: <problem>`` (1-based, where the
    problem is), without the marks and caret lines of its own text."""
    if isinstance(exc, yaml.reader.ReaderError):
        code = exc.character if isinstance(exc.character, int) else ord(exc.character)
        return f"character {exc.position + 1}: unacceptable character #x{code:04x}: {exc.reason}"
    problem = getattr(exc, "problem", None)
    if not problem:
        return one_line(exc)
    mark = getattr(exc, "problem_mark", None)
    where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
    return f"{where}{one_line(problem)}"


def key_value(text: str, flag: str) -> tuple[str, Any]:
    """``(key, value)`` of a command line's ``key:value`` (RL Zoo's ``--hyperparams``), the
    value read as YAML with the safe loader (numbers, strings, lists and mappings; never Python
    objects); :class:`HyperparameterError` naming ``flag`` otherwise."""
    key, sep, value = text.partition(":")
    if not sep or not key.isidentifier():
        raise HyperparameterError(f"{flag}: must be key:value, got {text!r}")
    try:     # the files' loader: no Python objects, no key given twice, 1e-4 a float
        return key, yaml.load(value, Loader=_UniqueKeyLoader)
    except yaml.YAMLError as exc:
        raise HyperparameterError(f"{flag} {text!r}: the value is not valid YAML "
                                  f"({yaml_problem(exc)})") from None


def _check_keys(where: str, section: Mapping[str, Any], valid: list[str]) -> None:
    for key in section:
        if key not in valid:
            raise HyperparameterError(f"{where}.{key}: {unknown_key_message(key, valid, 'key')}")


def _keywords(func: Any, *reserved: str) -> list[str]:
    """Keyword names of ``func`` less ``self`` and ``reserved``."""
    return [n for n, p in inspect.signature(func).parameters.items()
            if n not in ("self", *reserved) and p.kind is not p.VAR_KEYWORD]


def policy_name(hp: Mapping[str, Any], cls: type) -> str:
    """The SB3 policy name of a validated section (default: ``cls.default_policy``)."""
    return hp.get("policy", cls.default_policy)


def model_kwargs(hp: Mapping[str, Any]) -> dict[str, Any]:
    """The constructor keywords of a validated section (``train_freq`` lists as tuples)."""
    kwargs = {k: v for k, v in hp.items() if k not in EXTRA_KEYS}
    if isinstance(kwargs.get("train_freq"), list):
        kwargs["train_freq"] = tuple(kwargs["train_freq"])
    return kwargs


def check_section(section: Any, cls: type, where: str) -> dict[str, Any]:
    """A validated copy of the hyperparameters of algorithm class ``cls`` (a section of a
    hyperparameter file, or of a run.yml), every key checked: constructor keywords,
    ``policy_kwargs`` against the policy's keywords, ``env`` (with its ``safety`` and
    ``tracker``) against the training environment's keywords, ``eval`` and ``action_noise``;
    the environment and the policy are built once, so that a bad value fails here. Errors name
    ``where`` and the key."""
    if not isinstance(section, Mapping):
        raise HyperparameterError(f"{where}: must be a mapping of keys to values")
    _check_keys(where, section, section_keys(cls))
    numbers = {key: _check_number(where, key, value) for key, value in section.items()
               if key in _NUMERIC}
    if numbers.get("gradient_steps") == 0:
        raise HyperparameterError(f"{where}.gradient_steps=0 would never train: must be an "
                                  f"integer >= 1, or -1 (as many as the env steps collected)")
    for key in ("env", "eval", "policy_kwargs", "replay_buffer_kwargs"):
        if key in section and not isinstance(section[key], Mapping):
            raise HyperparameterError(f"{where}.{key}: must be a mapping, got "
                                      f"{type(section[key]).__name__}")
    _check_keys(f"{where}.replay_buffer_kwargs", section.get("replay_buffer_kwargs", {}),
                _BUFFER_KEYS)
    for sub, keys in _FLAGS.items():
        for key in keys:
            value = (section.get(sub, {}) if sub else section).get(key, False)
            if not isinstance(value, bool):
                raise HyperparameterError(f"{where}.{f'{sub}.' if sub else ''}{key}={value!r} "
                                          f"must be true or false")
    if section.get("optimize_memory_usage") and section.get(
            "replay_buffer_kwargs", {}).get("handle_timeout_termination", True):
        raise HyperparameterError(f"{where}.optimize_memory_usage: true needs "
                                  f"replay_buffer_kwargs.handle_timeout_termination: false")
    if "action_noise" in section:
        _check_noise(where, section["action_noise"])
    if "train_freq" in section:
        tf = section["train_freq"]
        n, unit = (tf[0], tf[1]) if isinstance(tf, list) and len(tf) == 2 else (tf, None)
        if unit not in (None, "step", "episode"):
            raise HyperparameterError(f"{where}.train_freq: must be a positive integer or "
                                      f"[n, step|episode], got {tf!r}")
        n = integer(f"{where}.train_freq", n, "steps or episodes", low=1,
                    error=HyperparameterError)
        numbers["train_freq"] = n if unit is None else [n, unit]
    policy = policy_name(section, cls)
    if not isinstance(policy, str) or policy not in cls.policy_aliases:
        raise HyperparameterError(f"{where}.policy: {policy!r} is not one of "
                                  f"{sorted(cls.policy_aliases)}")
    evaluation = section.get("eval", {})
    _check_keys(f"{where}.eval", evaluation, list(_EVAL))
    checked_eval = {key: _check_number(f"{where}.eval", key, value, _EVAL[key])
                    for key, value in evaluation.items()}
    hp = {**section, **numbers}       # integers written as 32.0 reach SB3 as ints
    if "eval" in hp:
        hp["eval"] = checked_eval
    _check_stack(where, cls, policy, hp)
    return hp


def section_keys(cls: type) -> list[str]:
    """The keys a section of algorithm class ``cls`` may hold."""
    return sorted(set(_keywords(cls.__init__, *RESERVED)) | set(EXTRA_KEYS))


def env_keys() -> list[str]:
    """The keys of a section's ``env``: the training environment's keywords."""
    return sorted({*_keywords(make_training_env, "config"),
                   *_keywords(make_safe_env, "config", "kwargs", "tracker", "safety"),
                   *(f.name for f in dataclasses.fields(AOASSConfig))}
                  - {"render_mode", "split"})     # train.py sets the split of each env


def override_section(hp: Mapping[str, Any], cls: type, where: str, *,
                     hyperparams: Mapping[str, Any], env: Mapping[str, Any]) -> dict[str, Any]:
    """The validated section ``hp`` with the command line's overrides: ``hyperparams`` replace
    section keys (``--hyperparams``), ``env`` replaces keys of its ``env`` (``--env-kwargs``).
    An unknown key is a :class:`HyperparameterError` naming the flag; a bad value names
    ``where``."""
    for flag, given, valid in (("--hyperparams", hyperparams, section_keys(cls)),
                               ("--env-kwargs", env, env_keys())):
        for key in given:
            if key not in valid:
                raise HyperparameterError(f"{flag} {key}: "
                                          f"{unknown_key_message(key, valid, 'key')}")
    merged = {**hp, **hyperparams}
    if env:
        merged["env"] = {**merged.get("env", {}), **env}
    return check_section(merged, cls, where)


def _check_stack(where: str, cls: type, policy: str, hp: Mapping[str, Any]) -> None:
    """Check ``env`` and ``policy_kwargs`` key by key, then build the environment and the
    policy once so that a bad value fails with ``where`` and its section."""
    env_kwargs = hp.get("env", {})
    _check_keys(f"{where}.env", env_kwargs, env_keys())
    for key, config in (("safety", SafetyConfig), ("tracker", TrackerConfig),
                        ("adaptive", AdaptiveConfig)):
        sub = env_kwargs.get(key, {})
        if not isinstance(sub, Mapping):
            raise HyperparameterError(f"{where}.env.{key}: must be a mapping, got "
                                      f"{type(sub).__name__}")
        _check_keys(f"{where}.env.{key}", sub, [f.name for f in dataclasses.fields(config)])
    policy_class = cls.policy_aliases[policy]
    policy_kwargs = hp.get("policy_kwargs", {})
    _check_keys(f"{where}.policy_kwargs", policy_kwargs, _keywords(
        policy_class.__init__, "observation_space", "action_space", "lr_schedule"))
    for key in _CLASSES:
        if key in policy_kwargs and not isinstance(policy_kwargs[key], type):
            raise HyperparameterError(f"{where}.policy_kwargs.{key}: must be a Python class, "
                                      f"which a YAML file cannot name (got "
                                      f"{policy_kwargs[key]!r}); leave it out for the default")
    try:
        check_net_arch(policy_kwargs.get("net_arch"), f"{where}.policy_kwargs.net_arch")
    except ValueError as exc:
        raise HyperparameterError(str(exc)) from None
    if "n_critics" in policy_kwargs:    # SB3's TD3 policy said only "an empty parameter list"
        integer(f"{where}.policy_kwargs.n_critics", policy_kwargs["n_critics"], "critics",
                low=1, error=HyperparameterError)
    try:
        env = make_training_env(split="validation", **env_kwargs)
    except (ValueError, TypeError) as exc:
        raise HyperparameterError(f"{where}.env: {one_line(exc)}") from None
    try:
        policy_class(env.observation_space, env.action_space, lambda _: 1e-3, **policy_kwargs)
    except (ValueError, TypeError, RuntimeError) as exc:
        raise HyperparameterError(f"{where}.policy_kwargs: {one_line(exc)}") from None
    finally:
        env.close()
    try:        # the algorithm's own checks, without building its networks and buffer
        cls(policy, None, device="cpu", _init_setup_model=False, **model_kwargs(hp))
    except (ValueError, TypeError) as exc:
        raise HyperparameterError(f"{where}: {one_line(exc)}") from None


def _check_noise(where: str, spec: Any) -> None:
    if not isinstance(spec, Mapping) or set(spec) - {"kind", "sigma"} \
            or spec.get("kind") not in ("normal", "ornstein-uhlenbeck"):
        raise HyperparameterError(
            f"{where}.action_noise: must be {{kind: normal | ornstein-uhlenbeck, sigma: "
            f"number}}, got {spec!r}")
    real(f"{where}.action_noise.sigma", spec.get("sigma", 0.1), low=0.0, high=10.0,
         high_open=True, error=HyperparameterError)


def action_noise(spec: Mapping[str, Any] | None, n_actions: int) -> ActionNoise | None:
    """The SB3 action noise of a validated ``action_noise`` mapping (None: no noise)."""
    if spec is None:
        return None
    mean, sigma = np.zeros(n_actions), float(spec.get("sigma", 0.1)) * np.ones(n_actions)
    if spec["kind"] == "normal":
        return NormalActionNoise(mean, sigma)
    return OrnsteinUhlenbeckActionNoise(mean, sigma)
