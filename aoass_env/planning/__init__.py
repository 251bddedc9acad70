"""Path planning: the square spiral (Eq. 1-5), generic waypoint paths, the nominal path
follower, the anchor's own coverage map and the adaptive sweep that reads it, and the sweep
methods with what they need of a running sweep (:mod:`.sweep`: ``PlannedMethod`` and the
``Controller`` and ``SweepState`` protocols; planning knows nothing of the simulator)."""

from aoass_env.planning.adaptive import AdaptiveConfig, AdaptiveSweep, SweepKnobs
from aoass_env.planning.coverage import CoverageMap
from aoass_env.planning.follower import WaypointFollower
from aoass_env.planning.path import WaypointPath, polyline_path
from aoass_env.planning.square_spiral import (
    SquareSpiral,
    default_spacing,
    max_spacing,
    square_spiral,
)
from aoass_env.planning.sweep import Controller, PlannedMethod, SweepState

__all__ = ["AdaptiveConfig", "AdaptiveSweep", "Controller", "CoverageMap", "PlannedMethod",
           "SweepKnobs", "SquareSpiral", "SweepState", "WaypointFollower",
           "WaypointPath", "default_spacing", "max_spacing", "polyline_path", "square_spiral"]
