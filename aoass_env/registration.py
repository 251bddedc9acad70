"""Registration of AOASS-v0 with Gymnasium.

``gymnasium.make("AOASS-v0", **keywords)`` calls :func:`make_env`, which builds the environment
and wraps it in a ``TimeLimit`` of the episode's own step limit
(:func:`aoass_env.env.max_episode_steps`: it depends on the field size and the spiral, so it
cannot be one number fixed at registration). ``env.spec.max_episode_steps`` therefore reports
the limit of the configuration that was made; the environment truncates at the same step itself,
so that its last ``info`` carries the episode metrics.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
from gymnasium.wrappers import TimeLimit

from aoass_env.env import AOASSEnv

ENV_ID = "AOASS-v0"
#: The full AOASS stack: AOASS-v0 -> Kalman tracker -> fuzzy + ORCA safety filter
#: (:func:`aoass_env.wrappers.make_safe_env`).
SAFE_ENV_ID = "AOASS-Safe-v0"


class EpisodeTimeLimit(TimeLimit):
    """A ``TimeLimit`` that takes each episode's own limit at ``reset``: a map given with
    ``reset(options={"map": ...})`` brings its own field size and so its own limit."""

    def reset(self, **kwargs: Any) -> Any:
        out = super().reset(**kwargs)
        self._max_episode_steps = self.env.unwrapped.max_episode_steps
        return out


def make_env(**kwargs: Any) -> gym.Env:
    """An :class:`AOASSEnv` built from ``kwargs`` in a ``TimeLimit`` of its own step limit."""
    env = AOASSEnv(**kwargs)
    return EpisodeTimeLimit(env, env.max_episode_steps)


make_env.metadata = AOASSEnv.metadata  # lets gymnasium.make check render modes


def register() -> None:
    """Register ``AOASS-v0`` and ``AOASS-Safe-v0`` (once per process)."""
    if ENV_ID not in gym.registry:
        gym.register(id=ENV_ID, entry_point=make_env)
    if SAFE_ENV_ID not in gym.registry:
        gym.register(id=SAFE_ENV_ID, entry_point="aoass_env.wrappers:make_safe_env")
