"""Path planning: the square spiral (Eq. 1-5) and the nominal path follower."""

from aoass_env.planning.follower import WaypointFollower
from aoass_env.planning.square_spiral import (
    SquareSpiral,
    default_spacing,
    max_spacing,
    square_spiral,
)

__all__ = ["SquareSpiral", "WaypointFollower", "default_spacing", "max_spacing", "square_spiral"]
