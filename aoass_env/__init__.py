"""AOASS: a single mobile anchor sweeping a sensor field along a square spiral.

The simulation core: configuration, obstacle maps, the pymunk world, the square spiral, radio,
network state, beacon logs and the episode simulator that wires them together.
"""

from aoass_env.beacon_log import BeaconLog, BeaconLogError, BeaconLogRecorder
from aoass_env.config import AOASSConfig, ConfigError
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

__all__ = [
    "AOASSConfig", "BeaconLog", "BeaconLogError", "BeaconLogRecorder", "ConfigError",
    "MapError", "MapFormatError", "Network", "ObstacleMap", "Radio", "Simulator", "World",
    "generate_map", "list_maps", "load_map", "read_map", "write_map",
]
