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

Every key is checked (:mod:`agents.sections`): unknown keys (with a did-you-mean suggestion),
keys given twice and values of the wrong type or range raise :class:`HyperparameterError`
naming the file, the section and the key. Files are read with a safe loader: no Python objects,
no ``eval`` of strings.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from agents.checkpoints import TD3, PolicyFileError, validate_record
from agents.recurrent_td3 import RecurrentTD3
from agents.sections import (
    EXTRA_KEYS,
    HyperparameterError,
    action_noise,
    check_section,
    read_yaml,
)

__all__ = ["ALGORITHMS", "EXTRA_KEYS", "HyperparameterError", "action_noise", "check_section",
           "load_hyperparams", "read_run_record", "read_yaml"]

#: Algorithm name on the command line -> SB3 class.
ALGORITHMS: dict[str, type] = {cls.algo_name: cls for cls in (RecurrentTD3, TD3)}


def load_hyperparams(path: str | Path, algo: str) -> dict[str, Any]:
    """The section ``algo`` of the YAML file ``path``, validated (:func:`check_section`).

    Raises:
        HyperparameterError: a missing file or section, unknown keys, bad values.
    """
    path = Path(path)
    if algo not in ALGORITHMS:
        raise HyperparameterError(f"algo {algo!r} is not one of {sorted(ALGORITHMS)}")
    data = read_yaml(path)
    if not isinstance(data, Mapping) or algo not in data:
        found = sorted(map(str, data)) if isinstance(data, Mapping) else type(data).__name__
        raise HyperparameterError(f"{path}: no section {algo!r} (found {found})")
    return check_section(data[algo], ALGORITHMS[algo], f"{path}: {algo}")


def read_run_record(path: str | Path) -> dict[str, Any]:
    """The ``run.yml`` at ``path`` of any algorithm, validated
    (:func:`agents.checkpoints.validate_record`).

    Raises:
        PolicyFileError: a missing or malformed record, naming the file and the key.
    """
    try:
        record = read_yaml(path, "run record")
    except HyperparameterError as exc:
        raise PolicyFileError(str(exc)) from None
    algo = record.get("algo") if isinstance(record, Mapping) else None
    if algo not in ALGORITHMS:
        raise PolicyFileError(f"{path}: algo: {algo!r} is not one of {sorted(ALGORITHMS)}")
    return validate_record(record, ALGORITHMS[algo], path)


