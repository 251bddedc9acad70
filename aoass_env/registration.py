"""Registration of the AOASS environments with Gymnasium.

* ``AOASS-v0`` (:func:`aoass_env.env.make_env`): the environment alone.
* ``AOASS-Safe-v0`` (:func:`aoass_env.wrappers.make_safe_env`): the full AOASS safety stack.
* ``AOASS-Train-v0`` (:func:`aoass_env.wrappers.make_training_env`): the shipped policy's
  training setup: the safety stack, each action held 16 periods, a ±15° heading residual, a
  shipped 100 m training map (density 0.1-0.4, 100 nodes) per episode.
* ``AOASS-Quick-v0`` (:func:`aoass_env.wrappers.make_safe_env`): the same agent on a generated
  50 m field of density 0.2 per episode: about a quarter of the episode, for quick experiments.
* ``AOASS-Adaptive-v0`` (:func:`aoass_env.wrappers.make_safe_env`): the safety stack with the
  adaptive action type (Eq. 6's residual and the coverage-aware sweep's three knobs,
  :class:`~aoass_env.action.AdaptiveAction`) and the coverage map's sectors in the observation;
  the zero action is the hand-written rule.
* ``AOASS-Adaptive-Train-v0`` (:func:`aoass_env.wrappers.make_training_env`): the adaptive
  policy's training setup (configs/aoass_adaptive.yml): ``AOASS-Adaptive-v0`` with the
  training setup's decisions, speed scale and maps, a ±5° heading residual, and the sweep's
  rule the shipped adaptive policy trained on (every field named, not ``AdaptiveConfig``'s
  defaults).

None has a ``reward_threshold``: Eq. 14 has no level at which the task counts as solved
(docs/env.md gives the reference returns instead).

Registration imports nothing of the environment: the entry points are strings that Gymnasium
imports at the first ``gymnasium.make``, so ``import aoass_env`` stays cheap
(benchmarks/import_time.py). The entry points wrap the environment in a ``TimeLimit`` of the
episode's own step limit (:func:`aoass_env.env.max_episode_steps`: it depends on the field size
and the spiral, so it cannot be one number fixed at registration), and ``env.spec`` reports it
(in agent steps under an action repeat). Every id carries
:class:`~aoass_env.env.EndOnTruncation` as its additional wrapper, outside the
``TimeLimit`` of ``gymnasium.make(..., max_episode_steps=N)``, so that such a truncation keeps
``info["episode_metrics"]``.
"""

from __future__ import annotations

import math

import gymnasium as gym
from gymnasium.envs.registration import WrapperSpec

__all__ = ["ADAPTIVE_ENV_ID", "ADAPTIVE_TRAIN_ENV_ID", "ENV_ID", "ENV_IDS", "QUICK_ENV_ID",
           "SAFE_ENV_ID", "TRAIN_ENV_ID", "register"]

ENV_ID = "AOASS-v0"
#: The full AOASS stack: AOASS-v0 -> Kalman tracker -> fuzzy + ORCA safety filter
#: (:func:`aoass_env.wrappers.make_safe_env`).
SAFE_ENV_ID = "AOASS-Safe-v0"
#: The shipped policy's training setup (configs/aoass.yml, section td3-lstm, key env).
TRAIN_ENV_ID = "AOASS-Train-v0"
#: The training setup's agent on a 50 m field: quick experiments.
QUICK_ENV_ID = "AOASS-Quick-v0"
#: The safety stack with the adaptive action type and the coverage sectors in the observation.
ADAPTIVE_ENV_ID = "AOASS-Adaptive-v0"
#: The adaptive policy's training setup (configs/aoass_adaptive.yml).
ADAPTIVE_TRAIN_ENV_ID = "AOASS-Adaptive-Train-v0"

#: What the shipped policy's agent sees: a decision every 16 control periods (8 s) and heading
#: corrections of at most ±π/12 rad (±15°), rounded as in configs/aoass.yml.
_AGENT = {"action_repeat": 16, "action_heading_scale": round(math.pi / 12, 4), "n_nodes": 100}
#: What makes a setup adaptive (configs/aoass_adaptive.yml).
_ADAPTIVE = {"action_type": "adaptive", "obs_coverage_sectors": 8}
#: The adaptive policy's heading corrections: at most ±π/36 rad (±5°), rounded as in
#: configs/aoass_adaptive.yml (every trained policy holds that entry at a bound, and the offset
#: it holds costs path: docs/adaptive.md).
_ADAPTIVE_HEADING = round(math.pi / 36, 4)
#: The sweep's rule the shipped adaptive policy trained on (configs/aoass_adaptive.yml's
#: ``adaptive``: the site tour), every field named so that AdaptiveConfig's defaults changing
#: later does not change it.
_ADAPTIVE_POLICY_RULE = {
    "prune": True, "prune_beacons": 6.0, "prune_spread": 2.0, "prune_error": 2.0,
    "sites": True, "site_need": 4, "reorder": True, "wide_passes": False, "skip_radius": 8.0,
    "skip_need": -0.25, "skip_localizing": False, "detour_need": -0.25,
    "detour_excess": 10000.0, "dense_above": 0.45,
    "dense_skip_need": 0.0, "dense_detour_need": 0.0, "dense_detour_excess": 20.0,
    "densify_need": 0.0, "cell_need": 0.0, "beyond_below": 0.92, "beyond_need": 0.5,
    "beyond_time": 0.8, "cell_sites": False, "cell_hop": 10000.0, "end_coverage": 0.995,
    "side_rate": 1000.0, "knob_step": 0.25, "knob_full": 0.9, "beacon_interval": None}

#: id -> (entry point, default keywords)
_IDS: dict[str, tuple[str, dict]] = {
    ENV_ID: ("aoass_env.env:make_env", {}),
    SAFE_ENV_ID: ("aoass_env.wrappers:make_safe_env", {}),
    TRAIN_ENV_ID: ("aoass_env.wrappers:make_training_env",
                   {"split": "train", "field_size": 100.0, "densities": [0.1, 0.4], **_AGENT}),
    QUICK_ENV_ID: ("aoass_env.wrappers:make_safe_env",
                   {"field_size": 50.0, "obstacle_density": 0.2, **_AGENT}),
    ADAPTIVE_ENV_ID: ("aoass_env.wrappers:make_safe_env", dict(_ADAPTIVE)),
    ADAPTIVE_TRAIN_ENV_ID: ("aoass_env.wrappers:make_training_env",
                            {"split": "train", "field_size": 100.0, "densities": [0.1, 0.4],
                             **_AGENT, "action_heading_scale": _ADAPTIVE_HEADING, **_ADAPTIVE,
                             "adaptive": dict(_ADAPTIVE_POLICY_RULE)}),
}
#: Every registered id.
ENV_IDS = tuple(_IDS)

_END_ON_TRUNCATION = WrapperSpec(name="EndOnTruncation",
                                 entry_point="aoass_env.env:EndOnTruncation", kwargs={})


def register() -> None:
    """Register every id of :data:`ENV_IDS` (once per process)."""
    for env_id, (entry_point, kwargs) in _IDS.items():
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=entry_point, kwargs=kwargs,
                         additional_wrappers=(_END_ON_TRUNCATION,))
