"""Path planning: the square spiral (Eq. 1-5), generic waypoint paths and the nominal path
follower."""

from aoass_env.planning.follower import WaypointFollower
from aoass_env.planning.path import PlannedMethod, WaypointPath, polyline_path
from aoass_env.planning.square_spiral import (
    SquareSpiral,
    default_spacing,
    max_spacing,
    square_spiral,
)

__all__ = ["PlannedMethod", "SquareSpiral", "WaypointFollower", "WaypointPath", "default_spacing",
           "max_spacing", "polyline_path", "square_spiral"]
