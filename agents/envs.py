"""The training environments of ``python train.py``: the full safety stack on the shipped
training maps (never maps/test), one map per episode; defined in :mod:`aoass_env.wrappers`
(registered as ``AOASS-Train-v0``) and re-exported here for the training machinery."""

from __future__ import annotations

from aoass_env.wrappers import POLICY_STACK_KEYS, TRAINING_SPLITS, make_training_env

__all__ = ["POLICY_STACK_KEYS", "TRAINING_SPLITS", "make_training_env"]
