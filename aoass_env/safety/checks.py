"""Compiled finiteness checks for the per-call input checks of the safety stack's library
functions (:func:`~aoass_env.safety.unicycle.unicycle_command`,
:class:`~aoass_env.safety.unicycle.BrakingEnvelope`,
:func:`~aoass_env.safety.lookahead.escape_velocity`, :func:`~aoass_env.safety.lookahead.rollout`):
a NaN or an infinity in their arrays would otherwise come out as a silently wrong command; and
the velocity filter's check of its moving discs. One call checks one or two arrays of any shape
in a fraction of a microsecond; ``np.isfinite(a).all()`` on small arrays costs a few."""

from __future__ import annotations

import math

import numpy as np

from aoass_env.jit import njit

__all__ = ["all_finite", "finite"]


@njit
def finite(a: np.ndarray) -> bool:
    """Whether every entry of the float array ``a`` is finite (no NaN, no infinity)."""
    for x in a.flat:
        if not math.isfinite(x):
            return False
    return True


@njit
def all_finite(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether every entry of the float arrays ``a`` and ``b`` is finite (no NaN, no
    infinity)."""
    return finite(a) and finite(b)
