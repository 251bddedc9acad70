"""Validated configurations of the safety stack's wrappers, like :class:`AOASSConfig`: each
field's meaning, unit and valid range are metadata, checked on construction; unknown keywords get
a did-you-mean error; docs/safety.md's tables are :meth:`~ValidatedConfig.markdown` (a test
keeps them true).

* :class:`TrackerConfig`: the Kalman tracker of the moving obstacles
  (:class:`~aoass_env.wrappers.KalmanObstacleTracker`).
* :class:`SafetyConfig`: the fuzzy + ORCA velocity filter
  (:class:`~aoass_env.wrappers.FuzzyORCASafety`).

``gymnasium.make("AOASS-Safe-v0", tracker=..., safety=...)``, :func:`aoass_env.make_safe_env`
and the ``env`` section of configs/aoass.yml take either the dataclass or a mapping of its
keywords. What the agent's action means is the environment's (``action_speed_scale``,
``action_heading_scale``), not the filter's.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from aoass_env.validators import ValidatedConfig, param

__all__ = ["SafetyConfig", "TrackerConfig"]


@dataclass(frozen=True)
class TrackerConfig(ValidatedConfig):
    """The Kalman tracker of the moving obstacles (docs/safety.md)."""

    KEYWORD: ClassVar[str] = "tracker keyword"

    horizon: float = param(2.0, "how far ahead the tracks' predicted positions are appended to "
                           "the observation", unit="s", low=0.0, high=60.0, low_open=True)
    process_noise: float = param(
        0.5, "std of the white acceleration of the constant-velocity model", unit="m/s^2",
        low=0.0, high=100.0, low_open=True)
    gate: float = param(0.99, "probability of the chi-square gate that associates a detection "
                        "with a track", low=0.0, high=1.0, low_open=True, high_open=True)
    birth_hits: int = param(2, "detections that confirm a new track", low=1, high=100,
                            kind="int")
    max_misses: int = param(3, "consecutive misses that delete a track", low=1, high=100,
                            kind="int")
    maneuver_speed: float = param(
        2.0, "std of a track's sudden velocity change in the maneuver stage (2 m/s: a U-turn at "
        "the default top obstacle speed of 1 m/s; about twice the top speed for faster "
        "obstacles)", unit="m/s", low=0.0, high=100.0, low_open=True)


@dataclass(frozen=True)
class SafetyConfig(ValidatedConfig):
    """The fuzzy + ORCA velocity filter (docs/safety.md)."""

    KEYWORD: ClassVar[str] = "safety keyword"

    time_horizon: float = param(4.0, "ORCA horizon against the moving obstacles", unit="s",
                                low=0.0, high=60.0, low_open=True)
    time_horizon_obst: float = param(
        2.5, "ORCA horizon against the static obstacles (at least anchor_max_speed / "
        "anchor_max_accel lets the anchor brake in time)", unit="s", low=0.0, high=60.0,
        low_open=True)
    margin: float = param(0.2, "safety margin added to the anchor's radius (ORCA and the "
                          "braking envelope)", unit="m", low=0.0, high=5.0)
    moving_margin: float = param(
        1.0, "further margin added to the moving obstacles' radius (they do not avoid the "
        "anchor and turn at random)", unit="m", low=0.0, high=10.0)
    covariance_sigma: float = param(
        2.0, "standard deviations of a track's position estimate added to the moving "
        "obstacle's radius (ORCA and the look-ahead; 0: the radius alone)", low=0.0, high=10.0)
    look_ahead: bool = param(
        True, "roll candidate commands out against the tracks' prediction and the static "
        "edges, and escape toward free space when ORCA's velocity falls short of "
        "look_ahead_clearance (False: ORCA alone against the moving obstacles)", kind="bool")
    look_ahead_horizon: float | None = param(
        None, "how far ahead the look-ahead rolls out; None = one period + a full stop from "
        "top speed + a half turn (4.5 s with the defaults)", unit="s", low=0.0, high=60.0,
        low_open=True, optional=True)
    look_ahead_clearance: float = param(
        0.2, "gap the look-ahead keeps between the anchor and a moving obstacle's grown disc",
        unit="m", low=0.0, high=10.0)
    maneuver_share: float = param(
        0.5, "how fast a moving obstacle's disc grows in the look-ahead, as a fraction of its "
        "speed (room for a turn toward the anchor; 1: its whole reachable disc)", low=0.0,
        high=1.0)

    look_ahead_react: float | None = param(
        None, "the look-ahead starts an escape only when ORCA's velocity falls short of the "
        "clearance within this time (or touches an obstacle's bare disc within the horizon), "
        "and keeps escaping until it is clear over the whole horizon; None = one period + a "
        "full stop from top speed (2.5 s with the defaults)", unit="s", low=0.0, high=60.0,
        low_open=True, optional=True)
    progress_weight: float = param(
        2.0, "price the look-ahead puts on a candidate that makes no headway along the "
        "sweep's direction against one running at top speed along it for the whole horizon "
        "(m x steps of clearance shortfall)", low=0.0, high=100.0)
    escape_budget: float = param(
        15.0, "seconds of escaping (refilled at half a second per second without) after "
        "which the look-ahead yields to the sweep until half of it is back: it then escapes "
        "only from the obstacles' discs grown by their covariance, with the headway priced "
        "yield_progress_weight", unit="s", low=0.0, high=1e4, low_open=True)
    yield_progress_weight: float = param(
        10.0, "progress_weight while yielding to the sweep", low=0.0, high=100.0)
    shortfall_tolerance: float | None = param(
        1.0, "the look-ahead's prices on walls, headway, preference and turning choose only "
        "among candidates whose clearance shortfall is within this of the least (m x steps; "
        "None: they compete with the shortfall on one cost)", low=0.0, high=1e4,
        optional=True)
    yield_shortfall_tolerance: float | None = param(
        None, "shortfall_tolerance while yielding to the sweep (m x steps; None: the prices "
        "compete with the shortfall on one cost, so the headway priced yield_progress_weight "
        "can take the anchor out of a pocket an obstacle holds it in)", low=0.0, high=1e4,
        optional=True)

    @classmethod
    def orca_only(cls, **kwargs: object) -> SafetyConfig:
        """The filter before the look-ahead (issue 4's stack): ORCA alone against the moving
        obstacles, radii not inflated by the track covariance; ``kwargs`` change further
        fields. Benchmarks run it on the same seeds as the defaults."""
        return cls.from_kwargs(**{"covariance_sigma": 0.0, "look_ahead": False, **kwargs})
