"""Range-free localization from beacon logs: classical DV-Hop, visibility consensus, OLSTM-DV-Hop.

``localize(log, method)`` returns (N, 2) position estimates [m], NaN for the nodes that are not
covered under Eq. 18 (fewer than three non-collinear beacons heard). See docs/localization.md.

Modules: :mod:`.hops` (hop counts), :mod:`.dvhop` (Eq. 11, classical DV-Hop),
:mod:`.consensus` (map-aware visibility consensus), :mod:`.multilateration` (Eq. 13),
:mod:`.reception` (the reception record, OLSTM input), :mod:`.olstm` (model, checkpoints, Eq. 12
as a learned reception model), :mod:`.training` (training pipeline), :mod:`.cli` (folder of
logs).
"""

from __future__ import annotations

import os
from functools import lru_cache
from typing import TYPE_CHECKING, Any

import numpy as np

from aoass_env.beacon_log import BeaconLog
from aoass_env.localization.episode import Episode, prepare
from aoass_env.localization.hops import DEFAULT_FLOOD_LIMIT, check_flood_limit

if TYPE_CHECKING:
    from aoass_env.localization.olstm import OLSTM, CheckpointError

__all__ = ["METHODS", "CheckpointError", "Episode", "localize", "prepare"]

#: Localization methods accepted by :func:`localize`.
METHODS = ("dvhop", "consensus", "olstm-dvhop")


def __getattr__(name: str) -> Any:
    """``CheckpointError`` from :mod:`.olstm`, imported (with torch) on first use."""
    if name == "CheckpointError":
        from aoass_env.localization.olstm import CheckpointError
        return CheckpointError
    raise AttributeError(f"module 'aoass_env.localization' has no attribute {name!r}")


@lru_cache(maxsize=4)
def _cached_model(path: str, mtime: float) -> OLSTM:
    from aoass_env.localization.olstm import load_checkpoint
    return load_checkpoint(path)


def localize(log: BeaconLog | Episode, method: str = "olstm-dvhop", *,
             checkpoint: str | os.PathLike[str] | OLSTM | None = None,
             flood_limit: int | None = None) -> np.ndarray:
    """Estimate every node's position from one episode's beacon log.

    Args:
        log: the beacon log (or an :class:`Episode` already prepared from one).
        method: ``"dvhop"`` (classical DV-Hop, the baseline), ``"consensus"`` (the map-aware
            visibility consensus alone) or ``"olstm-dvhop"`` (the consensus with the OLSTM's
            learned reception range in place of the DOI bound); docs/localization.md.
        checkpoint: OLSTM checkpoint path (default: the shipped one,
            :data:`~aoass_env.localization.olstm.DEFAULT_CHECKPOINT`), or a loaded model
            (``"olstm-dvhop"`` only).
        flood_limit: hop-count flooding limit [hops] (``"dvhop"`` only); default
            :data:`~aoass_env.localization.hops.DEFAULT_FLOOD_LIMIT`, or a prepared episode's
            own (another value is refused for a prepared episode: it floods only once).

    Returns:
        (N, 2) estimates [m]; NaN rows for nodes not covered under Eq. 18.

    Raises:
        ValueError: unknown method, a ``checkpoint`` for a method that reads none, a
            ``flood_limit`` for a method other than DV-Hop (only its hop counts flood), or a
            bad ``flood_limit``.
        TypeError: ``checkpoint`` is neither a path nor an :class:`OLSTM`.
        BeaconLogError: the log holds no beacons or is otherwise invalid.
        CheckpointError: the checkpoint is missing or does not match this code.
    """
    if method not in METHODS:
        raise ValueError(f"method={method!r} must be one of {METHODS}")
    if checkpoint is not None and method != "olstm-dvhop":
        raise ValueError(f"checkpoint is read by method='olstm-dvhop' only, not {method!r}")
    if flood_limit is not None and method != "dvhop":   # the others flood nothing: it was ignored
        raise ValueError(f"flood_limit is read by method='dvhop' only, not {method!r}")
    if isinstance(log, Episode):
        if flood_limit is not None:
            check_flood_limit(flood_limit)
            if flood_limit != log.flood_limit:
                raise ValueError(f"flood_limit={flood_limit!r} differs from the prepared "
                                 f"episode's flood_limit={log.flood_limit}; pass the log, or "
                                 f"prepare it with this flood_limit")
        episode = log
    else:
        episode = prepare(log, DEFAULT_FLOOD_LIMIT if flood_limit is None else flood_limit)
    if method == "dvhop":
        from aoass_env.localization.dvhop import dvhop
        return dvhop(episode)
    from aoass_env.localization.consensus import consensus
    if method == "consensus":
        return consensus(episode)
    from aoass_env.localization.olstm import DEFAULT_CHECKPOINT, OLSTM, olstm_dvhop
    if isinstance(checkpoint, OLSTM):
        model = checkpoint
    elif checkpoint is not None and not isinstance(checkpoint, (str, os.PathLike)):
        raise TypeError(f"checkpoint must be a path or a loaded OLSTM, got "
                        f"{type(checkpoint).__name__}")
    else:
        path = os.fspath(DEFAULT_CHECKPOINT if checkpoint is None else checkpoint)
        model = _cached_model(path, os.path.getmtime(path) if os.path.isfile(path) else -1.0)
    return olstm_dvhop(episode, model)
