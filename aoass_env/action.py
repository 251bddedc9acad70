"""Action types: what an agent's action means, in one place (HighwayEnv's ``ActionType``).

An action type owns its Gymnasium space, its scales, and the mapping from an action to the
(speed [m/s], heading [rad]) command the anchor executes, given the nominal follower's command
for the step. AOASS-v0 decodes its actions with its ``action_type``; the safety filter decodes the
agent's action with the agent's type and encodes the command it lets through with the inner
environment's type (:meth:`ActionType.action`), so the meaning of an action is written once.

* :class:`ResidualAction`: Eq. 6's a = [Δv, Δθ], a residual on the nominal path follower
  (the zero action follows the spiral). Built from the config's ``action_speed_scale`` and
  ``action_heading_scale`` (:meth:`ResidualAction.from_config`), or reaching every speed and
  heading (:meth:`ResidualAction.full_range`, the inner environment of the safety stack).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces

from aoass_env.config import AOASSConfig
from aoass_env.validators import positive
from aoass_env.world import wrap_angle

__all__ = ["ActionType", "ResidualAction", "checked_action"]

#: A command: (speed [m/s], heading [rad], world frame).
Command = tuple[float, float]


def checked_action(action: Any) -> tuple[float, float]:
    """(dv, dtheta) of an action [dv, dtheta] clipped to [-1, 1]; ValueError for a wrong shape,
    non-numbers (strings, complex numbers, ...), NaN or infinite values."""
    try:
        if np.iscomplexobj(action) or np.asarray(action).dtype.kind in "SUMmV":
            raise TypeError("not real numbers")
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"action must be 2 numbers [dv, dtheta], got {action!r}") from exc
    if a.shape != (2,):
        raise ValueError(f"action must have shape (2,) = [dv, dtheta], got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"action must be finite, got {a.tolist()} (NaN or infinite)")
    dv, dtheta = np.clip(a, -1.0, 1.0).tolist()
    return dv, dtheta


class ActionType(ABC):
    """What an action means: its space, and its mapping to and from commands."""

    @property
    @abstractmethod
    def space(self) -> spaces.Box:
        """The Gymnasium action space."""

    @abstractmethod
    def command(self, action: Any, nominal: Command) -> Command:
        """The (speed [m/s], heading [rad]) that ``action`` commands when the nominal follower
        commands ``nominal``; ValueError naming the action for a malformed one."""

    @abstractmethod
    def action(self, speed: float, heading: float, nominal: Command) -> np.ndarray:
        """The action (clipped to the space) that commands (``speed``, ``heading``) when the
        nominal follower commands ``nominal``: the inverse of :meth:`command` within reach."""


@dataclass(frozen=True)
class ResidualAction(ActionType):
    """Eq. 6's residual a = [Δv, Δθ] in [-1, 1]^2 on the nominal follower: speed = nominal
    speed + Δv x ``speed_scale`` clipped to [0, ``max_speed``], heading = nominal heading +
    Δθ x ``heading_scale``.

    Attributes:
        speed_scale: the speed change of Δv = ±1 (m/s).
        heading_scale: the heading change of Δθ = ±1 (rad).
        max_speed: the anchor's speed limit (m/s).
    """

    speed_scale: float
    heading_scale: float
    max_speed: float

    def __post_init__(self) -> None:
        positive("speed_scale", self.speed_scale, "m/s")
        positive("heading_scale", self.heading_scale, "rad", high=math.pi)
        positive("max_speed", self.max_speed, "m/s")

    @classmethod
    def from_config(cls, config: AOASSConfig) -> ResidualAction:
        """The residual of ``config``'s ``action_speed_scale`` and ``action_heading_scale``."""
        return cls(config.action_speed_scale, config.action_heading_scale,
                   config.anchor_max_speed)

    @classmethod
    def full_range(cls, config: AOASSConfig) -> ResidualAction:
        """A residual that reaches every speed and heading from any nominal command (speed
        scale ``anchor_max_speed``, heading scale π): what a safety filter sends its inner
        environment."""
        return cls(config.anchor_max_speed, math.pi, config.anchor_max_speed)

    @property
    def reaches_every_command(self) -> bool:
        """Whether every (speed, heading) is one action away from any nominal command."""
        return self.speed_scale >= self.max_speed and self.heading_scale == math.pi

    @property
    def space(self) -> spaces.Box:
        return spaces.Box(-1.0, 1.0, (2,), np.float32)

    def command(self, action: Any, nominal: Command) -> Command:
        dv, dtheta = checked_action(action)
        speed, heading = nominal
        return (min(max(speed + dv * self.speed_scale, 0.0), self.max_speed),
                heading + dtheta * self.heading_scale)

    def action(self, speed: float, heading: float, nominal: Command) -> np.ndarray:
        speed_nom, heading_nom = nominal
        return np.clip([(speed - speed_nom) / self.speed_scale,
                        wrap_angle(heading - heading_nom) / self.heading_scale],
                       -1.0, 1.0).astype(np.float32)
