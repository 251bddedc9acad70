"""AOASS: a single mobile anchor sweeping a sensor field along a square spiral.

The simulation core: configuration, obstacle maps, the pymunk world, the square spiral, radio,
network state, beacon logs and the episode simulator that wires them together; and the
Gymnasium environment ``AOASS-v0`` and the full safety stack ``AOASS-Safe-v0``
(:func:`make_safe_env`), registered on import.

``import aoass_env`` only registers the environments: the names below are imported from their
modules on first use (PEP 562), as Gymnasium and HighwayEnv do, so the import stays cheap
(``python3 benchmarks/import_time.py``).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from aoass_env.registration import ENV_ID, SAFE_ENV_ID, register

if TYPE_CHECKING:
    from aoass_env.beacon_log import BeaconLog, BeaconLogError, BeaconLogRecorder
    from aoass_env.config import AOASSConfig, ConfigError
    from aoass_env.env import AOASSEnv
    from aoass_env.maps import (
        MapError,
        MapFormatError,
        ObstacleMap,
        generate_map,
        list_maps,
        load_map,
        read_map,
        write_map,
    )
    from aoass_env.network import Network
    from aoass_env.radio import Radio
    from aoass_env.simulator import Simulator
    from aoass_env.world import World
    from aoass_env.wrappers import (
        FuzzyORCASafety,
        KalmanObstacleTracker,
        MapSampler,
        make_safe_env,
    )

#: Public name -> the module that defines it.
_EXPORTS = {
    "BeaconLog": "beacon_log", "BeaconLogError": "beacon_log", "BeaconLogRecorder": "beacon_log",
    "AOASSConfig": "config", "ConfigError": "config",
    "AOASSEnv": "env",
    "MapError": "maps", "MapFormatError": "maps", "ObstacleMap": "maps",
    "generate_map": "maps", "list_maps": "maps", "load_map": "maps", "read_map": "maps",
    "write_map": "maps",
    "Network": "network", "Radio": "radio", "Simulator": "simulator", "World": "world",
    "FuzzyORCASafety": "wrappers", "KalmanObstacleTracker": "wrappers", "MapSampler": "wrappers",
    "make_safe_env": "wrappers",
}

__all__ = ["AOASSConfig", "AOASSEnv", "BeaconLog", "BeaconLogError", "BeaconLogRecorder",
           "ConfigError", "ENV_ID", "FuzzyORCASafety", "KalmanObstacleTracker", "MapError",
           "MapFormatError", "MapSampler", "Network", "ObstacleMap", "Radio", "SAFE_ENV_ID",
           "Simulator", "World", "generate_map", "list_maps", "load_map", "make_safe_env",
           "read_map", "write_map"]


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'aoass_env' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"aoass_env.{module}"), name)
    globals()[name] = value          # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_EXPORTS})


register()
