"""Sweep methods and what planning needs of a running sweep, declared here so that planning
knows nothing of the simulator.

* :class:`PlannedMethod`: a method that runs in the simulator without the Gymnasium
  environment (a classical path or a reconstructed baseline): its planned path and, for
  methods that decide online, the factory of its controller.
* :class:`Controller`: what drives the anchor, one (speed, heading) command per control period
  (the nominal :class:`~aoass_env.planning.follower.WaypointFollower`, or a baseline's online
  controller).
* :class:`SweepState`: what an online controller may read of the episode it drives: the
  config, the map and its detour planner, the paths, and what the anchor itself learns while it
  sweeps (the radio's receivers of a beacon, which nodes are covered, the distance travelled,
  the track so far). :class:`~aoass_env.simulator.Simulator` provides it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from aoass_env.config import AOASSConfig
from aoass_env.maps import ObstacleMap
from aoass_env.planning.detour import DetourPlanner
from aoass_env.planning.path import WaypointPath
from aoass_env.planning.square_spiral import SquareSpiral

__all__ = ["Controller", "PlannedMethod", "SweepState"]


class Controller(Protocol):
    """What drives the anchor in :meth:`Simulator.run <aoass_env.simulator.Simulator.run>`.
    ``done`` turns True when the method has finished its sweep."""

    @property
    def done(self) -> bool: ...

    def command(self, position: np.ndarray, heading: float, dt: float) -> tuple[float, float]:
        """(speed [m/s], heading [rad]) for the next control period of ``dt`` seconds."""
        ...


class _Receivers(Protocol):
    def receivers(self, position: np.ndarray) -> np.ndarray:
        """Indices of the nodes that hear a beacon sent at ``position`` (m)."""
        ...


class _Coverage(Protocol):
    @property
    def covered(self) -> np.ndarray:
        """(N,) bool: nodes covered under Eq. 18 so far."""
        ...

    @property
    def distance_travelled(self) -> float:
        """Distance (m) the anchor has travelled so far."""
        ...


class _Track(Protocol):
    @property
    def path_points(self) -> np.ndarray:
        """(P, 2) the anchor's positions (m) recorded so far."""
        ...


class SweepState(Protocol):
    """The episode an online controller drives (see the module docstring)."""

    config: AOASSConfig
    map: ObstacleMap
    nodes: np.ndarray
    spiral: SquareSpiral
    path: SquareSpiral | WaypointPath
    radio: _Receivers
    network: _Coverage
    recorder: _Track

    @property
    def planner(self) -> DetourPlanner: ...


@dataclass(frozen=True)
class PlannedMethod:
    """A sweep method that runs in the AOASS simulator without the Gymnasium environment: a
    classical path or a reconstructed baseline.

    Attributes:
        name: the method's command-line name (``"scan"``, ``"m-anchoro"``, ...).
        label: its name in tables and figures; reconstructions say so ("OHM (reconstructed)").
        source: the publication it follows (authors, venue, year, doi where known).
        plan: ``(obstacle_map, config) -> WaypointPath``, the path the simulator is built with
            (the anchor starts on its first free waypoint).
        controller: ``SweepState -> Controller`` for methods that decide online (the episode's
            :class:`~aoass_env.planning.sweep.SweepState`); None: the nominal
            follower tracks the planned path, detouring around static obstacles (the common
            obstacle rule).
        reconstructed: True when no code was published and the method was rebuilt from its
            paper (docs/baselines.md says which parts).
    """

    name: str
    label: str
    source: str
    plan: Callable[[ObstacleMap, AOASSConfig], WaypointPath]
    controller: Callable[[SweepState], Controller] | None = None
    reconstructed: bool = False
