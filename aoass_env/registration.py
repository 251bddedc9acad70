"""Registration of AOASS-v0 and AOASS-Safe-v0 with Gymnasium.

Registration imports nothing of the environment: the entry points are strings
(``aoass_env.env:make_env``, ``aoass_env.wrappers:make_safe_env``) that Gymnasium imports at
the first ``gymnasium.make``, so ``import aoass_env`` stays cheap (benchmarks/import_time.py).
:func:`~aoass_env.env.make_env` wraps the environment in a ``TimeLimit`` of the episode's own
step limit (:func:`aoass_env.env.max_episode_steps`: it depends on the field size and the
spiral, so it cannot be one number fixed at registration); ``env.spec.max_episode_steps``
reports the limit of the configuration that was made, and the environment truncates at the same
step itself, so that its last ``info`` carries the episode metrics.
"""

from __future__ import annotations

import gymnasium as gym

__all__ = ["ENV_ID", "SAFE_ENV_ID", "register"]

ENV_ID = "AOASS-v0"
#: The full AOASS stack: AOASS-v0 -> Kalman tracker -> fuzzy + ORCA safety filter
#: (:func:`aoass_env.wrappers.make_safe_env`).
SAFE_ENV_ID = "AOASS-Safe-v0"


def register() -> None:
    """Register ``AOASS-v0`` and ``AOASS-Safe-v0`` (once per process)."""
    if ENV_ID not in gym.registry:
        gym.register(id=ENV_ID, entry_point="aoass_env.env:make_env")
    if SAFE_ENV_ID not in gym.registry:
        gym.register(id=SAFE_ENV_ID, entry_point="aoass_env.wrappers:make_safe_env")
