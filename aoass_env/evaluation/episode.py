"""One episode's rows of ``episodes.csv``: run a method, measure Eq. 16-19, localize (Eq. 15).

:func:`run_episode` plays the episode of an :class:`EpisodeKey` and returns one row per
localizer; :func:`localize_log` does the localization part for a saved beacon log. The episode
metrics are the same for every method: they are read from the finished simulator, with the
method's own obstacle-free planned path as the ideal of Eq. 19.

An episode's map is a shipped map name or a map file, or the name of a map generated for the
``robustness`` preset (``generated/d0.30_f100_r7``), which :func:`robustness_map` builds from
the name alone, so that a resumed sweep plays the same map.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import re
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from aoass_env.beacon_log import BeaconLog, BeaconLogError
from aoass_env.config import AOASSConfig
from aoass_env.evaluation.methods import METHODS, MethodRun, RunOptions
from aoass_env.evaluation.store import (
    EPISODE_FIELDS,
    KEY_FIELDS,
    NO_LOCALIZER,
    EpisodeKey,
    EvaluationError,
    checked_row,
)
from aoass_env.localization import localize
from aoass_env.maps import ObstacleMap, generate_map, load_map
from aoass_env.metrics import localization_rmse
from aoass_env.simulator import episode_summary
from aoass_env.validators import parse_json

__all__ = ["GENERATED_PREFIX", "ROBUSTNESS_MAP_SEED", "episode_map", "episode_metrics",
           "localization_row", "localize_log", "log_key", "log_name", "robustness_map",
           "robustness_map_name", "run_episode"]

#: Name of the beacon-log extra (a JSON string) that holds the episode's key and metrics.
EPISODE_EXTRA = "evaluation_episode"

#: First entry of the seed sequence of every generated map (used nowhere else in the project):
#: map ``s`` of density ``d`` is drawn by ``np.random.default_rng([ROBUSTNESS_MAP_SEED,
#: round(100 d), s])``.
ROBUSTNESS_MAP_SEED = 20261117
#: Prefix of the names of generated maps in the episode key (never a shipped map or a file).
GENERATED_PREFIX = "generated/"
_GENERATED = re.compile(r"generated/d(?P<d>\d+\.\d{2})_f(?P<f>\d+(?:\.\d+)?)_r(?P<s>\d+)")


def robustness_map_name(field_size: float, density: float, index: int) -> str:
    """The episode-key name of generated map ``index`` of ``density`` on a ``field_size`` m
    field, e.g. ``generated/d0.30_f100_r7``."""
    return f"{GENERATED_PREFIX}d{density:.2f}_f{field_size:g}_r{index}"


@functools.lru_cache(maxsize=8)
def robustness_map(name: str, clearance: float = 2.5) -> ObstacleMap:
    """The map of a :func:`robustness_map_name`: ``generate_map(F, d,
    default_rng([ROBUSTNESS_MAP_SEED, round(100 d), s]), clearance=clearance)``; the same map
    for the same name, in any process (cached: the methods of one episode share it).

    Raises:
        EvaluationError: ``name`` is not such a name.
    """
    match = _GENERATED.fullmatch(name)
    if match is None:
        raise EvaluationError(f"{name!r} is not a generated map name (e.g. "
                              f"{robustness_map_name(100.0, 0.3, 7)!r})")
    density, index = float(match["d"]), int(match["s"])
    rng = np.random.default_rng([ROBUSTNESS_MAP_SEED, round(100 * density), index])
    return generate_map(float(match["f"]), density, rng, clearance=clearance,
                        name=name.removeprefix(GENERATED_PREFIX))


def episode_map(key: EpisodeKey, clearance: float = 2.5) -> ObstacleMap:
    """The obstacle map of ``key``: a generated map (:func:`robustness_map`, whose density
    must be the key's), a shipped map or a map file; its width must be the key's field size.

    Raises:
        EvaluationError: the map disagrees with the key (MapError: it cannot be loaded).
    """
    generated = key.map.startswith(GENERATED_PREFIX)
    obstacle_map = robustness_map(key.map, clearance) if generated else load_map(key.map)
    if not math.isclose(obstacle_map.width, key.field_size):
        raise EvaluationError(f"map {key.map} is {obstacle_map.width:g} m wide, the episode "
                              f"key says {key.field_size:g} m")
    if generated and not math.isclose(round(obstacle_map.density, 2), key.obstacle_density):
        raise EvaluationError(f"map {key.map} has density {obstacle_map.density:.3f}, the "
                              f"episode key says {key.obstacle_density:g}")
    return obstacle_map


def episode_metrics(run: MethodRun) -> dict[str, Any]:
    """The episode columns of ``episodes.csv`` from a finished run (all but ``wall_seconds``):
    :func:`~aoass_env.simulator.episode_summary` and the mean safety intervention (m/s)."""
    return {**episode_summary(run.sim, run.complete),
            "safety_intervention": run.safety_intervention}


def localization_row(log: BeaconLog, localizer: str) -> dict[str, Any]:
    """Eq. 15 RMSE (m) over the localized nodes, the localized fraction, and the wall time (s)
    of ``localizer`` on ``log``; all empty (and 0 s) for :data:`NO_LOCALIZER`."""
    if localizer == NO_LOCALIZER:
        return {"localizer": localizer, "rmse": None, "localized": None, "localize_seconds": 0.0}
    t0 = time.perf_counter()
    rmse, localized = localization_rmse(log.nodes, localize(log, localizer))
    return {"localizer": localizer, "rmse": rmse, "localized": localized,
            "localize_seconds": time.perf_counter() - t0}


def log_name(key: EpisodeKey) -> str:
    """Where ``--save-logs`` saves the log of ``key``, relative to its logs folder."""
    return f"{key.method}/{Path(key.map).name.removesuffix('.txt')}_n{key.n_nodes}_s{key.seed}.npz"


def run_episode(key: EpisodeKey, localizers: tuple[str, ...], options: RunOptions,
                log_dir: Path | None = None) -> list[dict[str, Any]]:
    """Play the episode of ``key`` and return one ``episodes.csv`` row per localizer.

    The map is ``key.map`` (:func:`episode_map`: a shipped name, a map file or a generated
    map's name), the random generator is seeded with ``key.seed`` only, and the config is the
    default one with the map's field size and ``key.n_nodes`` nodes (and, but for a generated
    map, ``map=key.map``). With ``log_dir``, the beacon log is saved to
    ``log_dir/<method>/<map>_n<N>_s<seed>.npz`` with the key and metrics as an extra.
    """
    t0 = time.perf_counter()
    config = AOASSConfig(field_size=key.field_size, n_nodes=key.n_nodes)
    obstacle_map = episode_map(key, config.map_clearance)
    if not key.map.startswith(GENERATED_PREFIX):   # a generated map has no name to load by
        config = config.replace(map=key.map)
    run = METHODS[key.method].runner(config, obstacle_map, key.seed, options)
    episode = {**asdict(key), **episode_metrics(run), "wall_seconds": time.perf_counter() - t0}
    if log_dir is not None:
        path = log_dir / log_name(key)
        path.parent.mkdir(parents=True, exist_ok=True)
        dataclasses.replace(run.log, extras={EPISODE_EXTRA: np.array(json.dumps(episode))}
                            ).save(path)
    return [{**episode, **localization_row(run.log, name)} for name in localizers]


def _saved_key(saved: dict[str, Any]) -> EpisodeKey:
    return EpisodeKey(**{k: saved[k] for k in KEY_FIELDS})


def _saved_episode(text: Any, path: Path) -> dict[str, Any]:
    """The evaluation extra of a saved log, checked: a JSON object holding every key field
    with a value of the field's type; :class:`BeaconLogError` naming the file and the extra."""
    try:
        saved = parse_json(str(text))
    except ValueError as exc:
        raise BeaconLogError(f"not valid JSON ({exc})", EPISODE_EXTRA, path) from None
    if not isinstance(saved, dict):
        raise BeaconLogError("must be a JSON object", EPISODE_EXTRA, path)
    kinds = {f.name: f.type for f in dataclasses.fields(EpisodeKey)}
    for name in KEY_FIELDS:
        want = {"str": str, "int": int, "float": (int, float)}[str(kinds[name])]
        value = saved.get(name)
        if isinstance(value, bool) or not isinstance(value, want):
            raise BeaconLogError(f"{name} must be a {kinds[name]}, got {value!r}",
                                 EPISODE_EXTRA, path)
    episode = {name: saved.get(name) for name in (*KEY_FIELDS, *EPISODE_FIELDS)}
    try:        # the values a row of episodes.csv may hold (it used to take any)
        checked_row(episode)
    except (TypeError, ValueError) as exc:
        raise BeaconLogError(str(exc), EPISODE_EXTRA, path) from None
    return episode


def _config_key(log: BeaconLog, path: Path) -> EpisodeKey:
    """The key of a log without the evaluation extra: method, seed (-1 if unknown), map
    (config, else the file name), field size, node count and the map's density (2 decimals)."""
    cfg = log.config
    seed, config = cfg.get("seed"), cfg.get("config", {})
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int)):
        raise BeaconLogError(f"its seed must be an integer or null, got {seed!r}",
                             "config_json", path)
    if not isinstance(config, dict):
        raise BeaconLogError(f"its config must be a JSON object, got {config!r}",
                             "config_json", path)
    key = EpisodeKey(method=str(cfg.get("method")),
                     map=str(config.get("map") or path.name.removesuffix(".npz")),
                     field_size=float(log.field[0]), n_nodes=log.n_nodes,
                     obstacle_density=round(log.obstacle_map.density, 2),
                     seed=-1 if seed is None else int(seed))
    try:        # a key episodes.csv could not hold failed after the localization, in a traceback
        checked_row(asdict(key))
    except ValueError as exc:
        raise BeaconLogError(f"its episode key does not fit episodes.csv ({exc})",
                             "config_json", path) from None
    return key


def log_key(path: Path) -> EpisodeKey:
    """The episode key of a saved beacon log: from the extra written by :func:`run_episode`,
    checked against the log, else from the log's config.

    Raises:
        BeaconLogError: the file is not a valid beacon log (the whole log is read: a file
            holding the extra alone used to pass), or its extra does not fit it.
    """
    return _log_episode(BeaconLog.load(path), path)[0]


def _log_episode(log: BeaconLog, path: Path) -> tuple[EpisodeKey, dict[str, Any]]:
    """(key, episode columns of the extra, empty without one) of a loaded log (:func:`log_key`)."""
    if EPISODE_EXTRA not in log.extras:
        return _config_key(log, path), {}
    saved = _saved_episode(log.extras[EPISODE_EXTRA], path)
    key = _saved_key(saved)
    field = float(log.field[0])
    if key.n_nodes != log.n_nodes or key.field_size != field:
        raise BeaconLogError(f"its key is N = {key.n_nodes} on a {key.field_size:g} m field, "
                             f"but the log holds {log.n_nodes} nodes on a {field:g} m field",
                             EPISODE_EXTRA, path)
    return key, saved


def localize_log(path: Path, localizers: tuple[str, ...]) -> list[dict[str, Any]]:
    """``episodes.csv`` rows of a saved beacon log: its key, its episode metrics when the log
    holds them (logs of ``--save-logs``; else empty) and one localization per localizer."""
    log = BeaconLog.load(path)
    key, saved = _log_episode(log, path)
    episode = {**dict.fromkeys(EPISODE_FIELDS), **saved, **asdict(key)}
    return [{**episode, **localization_row(log, name)} for name in localizers]
