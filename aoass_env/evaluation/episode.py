"""One episode's rows of ``episodes.csv``: run a method, measure Eq. 16-19, localize (Eq. 15).

:func:`run_episode` plays the episode of an :class:`EpisodeKey` and returns one row per
localizer; :func:`localize_log` does the localization part for a saved beacon log. The episode
metrics are the same for every method: they are read from the finished simulator, with the
method's own obstacle-free planned path as the ideal of Eq. 19.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
import zipfile
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from aoass_env.beacon_log import BeaconLog
from aoass_env.config import AOASSConfig
from aoass_env.evaluation.methods import METHODS, MethodRun, RunOptions
from aoass_env.evaluation.store import EPISODE_FIELDS, KEY_FIELDS, EpisodeKey, EvaluationError
from aoass_env.localization import localize
from aoass_env.maps import load_map
from aoass_env.metrics import (
    energy_efficiency_ratio,
    energy_per_beacon,
    localization_rmse,
    trajectory_efficiency,
)

__all__ = ["episode_metrics", "localization_row", "localize_log", "log_key", "run_episode"]

#: Name of the beacon-log extra (a JSON string) that holds the episode's key and metrics.
EPISODE_EXTRA = "evaluation_episode"


def episode_metrics(run: MethodRun) -> dict[str, Any]:
    """The episode columns of ``episodes.csv`` from a finished run (all but ``wall_seconds``):
    coverage (Eq. 18), beacons, path length and its ideal (m), travel time and its ideal (s),
    eta_traj (Eq. 19), anchor contacts, E_total (J), E_norm (Eq. 16, J/beacon), EER (Eq. 17,
    beacons/J), whether the method ended the episode itself (1) or the step limit did (0), and
    the mean safety intervention (m/s)."""
    sim, net = run.sim, run.sim.network
    ideal_time = sim.path.nominal_time(sim.config.anchor_nominal_speed)
    return {"coverage": net.coverage_ratio, "beacons": net.beacons_sent,
            "path_length": net.distance_travelled, "ideal_length": sim.path.length,
            "travel_time": sim.world.time, "ideal_time": ideal_time,
            "eta_traj": trajectory_efficiency(sim.path.length, net.distance_travelled,
                                              ideal_time, sim.world.time),
            "collisions": sim.collisions,
            "collisions_static": sim.world.static_contacts + sim.world.wall_contacts,
            "collisions_moving": sim.world.moving_contacts,
            "energy_total": net.energy_total,
            "e_norm": energy_per_beacon(net.energy_total, net.beacons_sent),
            "eer": energy_efficiency_ratio(net.energy_total, net.beacons_sent),
            "path_complete": int(run.complete), "safety_intervention": run.safety_intervention}


def localization_row(log: BeaconLog, localizer: str) -> dict[str, Any]:
    """Eq. 15 RMSE (m) over the localized nodes, the localized fraction, and the wall time (s)
    of ``localizer`` on ``log``."""
    t0 = time.perf_counter()
    rmse, localized = localization_rmse(log.nodes, localize(log, localizer))
    return {"localizer": localizer, "rmse": rmse, "localized": localized,
            "localize_seconds": time.perf_counter() - t0}


def _log_name(key: EpisodeKey) -> str:
    return f"{key.method}/{Path(key.map).name.removesuffix('.txt')}_n{key.n_nodes}_s{key.seed}.npz"


def run_episode(key: EpisodeKey, localizers: tuple[str, ...], options: RunOptions,
                log_dir: Path | None = None) -> list[dict[str, Any]]:
    """Play the episode of ``key`` and return one ``episodes.csv`` row per localizer.

    The map is ``key.map`` (a shipped name or a map file), the random generator is seeded with
    ``key.seed`` only, and the config is the default one with the map's field size and
    ``key.n_nodes`` nodes. With ``log_dir``, the beacon log is saved to
    ``log_dir/<method>/<map>_n<N>_s<seed>.npz`` with the key and metrics as an extra.
    """
    t0 = time.perf_counter()
    obstacle_map = load_map(key.map)
    if not math.isclose(obstacle_map.width, key.field_size):
        raise EvaluationError(f"map {key.map} is {obstacle_map.width:g} m wide, the episode "
                              f"key says {key.field_size:g} m")
    config = AOASSConfig(field_size=key.field_size, n_nodes=key.n_nodes, map=key.map)
    run = METHODS[key.method].runner(config, obstacle_map, key.seed, options)
    episode = {**asdict(key), **episode_metrics(run), "wall_seconds": time.perf_counter() - t0}
    if log_dir is not None:
        path = log_dir / _log_name(key)
        path.parent.mkdir(parents=True, exist_ok=True)
        dataclasses.replace(run.log, extras={EPISODE_EXTRA: np.array(json.dumps(episode))}
                            ).save(path)
    return [{**episode, **localization_row(run.log, name)} for name in localizers]


def _saved_key(saved: dict[str, Any]) -> EpisodeKey:
    return EpisodeKey(**{k: saved[k] for k in KEY_FIELDS})


def _config_key(log: BeaconLog, path: Path) -> EpisodeKey:
    """The key of a log without the evaluation extra: method, seed (-1 if unknown), map
    (config, else the file name), field size, node count and the map's density (2 decimals)."""
    cfg = log.config
    seed = cfg.get("seed")
    return EpisodeKey(method=str(cfg.get("method")),
                      map=str(cfg.get("config", {}).get("map") or path.name.removesuffix(".npz")),
                      field_size=float(log.field[0]), n_nodes=log.n_nodes,
                      obstacle_density=round(log.obstacle_map.density, 2),
                      seed=-1 if seed is None else int(seed))


def log_key(path: Path) -> EpisodeKey:
    """The episode key of a saved beacon log: from the extra written by :func:`run_episode`
    (read alone, cheaply), else from the log's config.

    Raises:
        BeaconLogError: the file is not a valid beacon log.
    """
    if zipfile.is_zipfile(path):
        with np.load(path, allow_pickle=False) as data:
            if EPISODE_EXTRA in data.files:
                return _saved_key(json.loads(str(data[EPISODE_EXTRA])))
    return _config_key(BeaconLog.load(path), path)


def localize_log(path: Path, localizers: tuple[str, ...]) -> list[dict[str, Any]]:
    """``episodes.csv`` rows of a saved beacon log: its key, its episode metrics when the log
    holds them (logs of ``--save-logs``; else empty) and one localization per localizer."""
    log = BeaconLog.load(path)
    saved = json.loads(str(log.extras[EPISODE_EXTRA])) if EPISODE_EXTRA in log.extras else {}
    key = _saved_key(saved) if saved else _config_key(log, path)
    episode = {**dict.fromkeys(EPISODE_FIELDS), **saved, **asdict(key)}
    return [{**episode, **localization_row(log, name)} for name in localizers]
