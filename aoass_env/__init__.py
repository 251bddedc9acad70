"""AOASS: a single mobile anchor sweeping a sensor field along a square spiral.

The simulation core: configuration, obstacle maps, the pymunk world, the square spiral, radio,
network state, beacon logs and the episode simulator that wires them together; and the
Gymnasium environment ``AOASS-v0`` and the full safety stack ``AOASS-Safe-v0``
(:func:`make_safe_env`), registered on import.
"""

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
from aoass_env.registration import ENV_ID, SAFE_ENV_ID, register
from aoass_env.simulator import Simulator
from aoass_env.world import World
from aoass_env.wrappers import FuzzyORCASafety, KalmanObstacleTracker, MapSampler, make_safe_env

register()

__all__ = [
    "AOASSConfig", "AOASSEnv", "BeaconLog", "BeaconLogError", "BeaconLogRecorder",
    "ConfigError", "ENV_ID", "FuzzyORCASafety", "KalmanObstacleTracker", "MapError",
    "MapFormatError", "MapSampler", "Network", "ObstacleMap", "Radio", "SAFE_ENV_ID",
    "Simulator", "World", "generate_map", "list_maps", "load_map", "make_safe_env", "read_map",
    "write_map",
]
