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
* :class:`AdaptiveAction`: the same residual and three knobs of the coverage-aware adaptive
  sweep (skip, detour, densify; :mod:`aoass_env.planning.adaptive`); the zero action is the
  hand-written rule.

``gymnasium.make(..., action_type="residual" | "adaptive")`` picks one by name
(:data:`ACTION_TYPES`). Their spaces are :class:`ActionBox`es: Gymnasium Boxes whose ``sample()``
draws the same numbers as ``Box.sample`` without its generic machinery.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from aoass_env.config import AOASSConfig
from aoass_env.planning.adaptive import SweepKnobs
from aoass_env.validators import positive
from aoass_env.world import wrap_angle

__all__ = ["ACTION_TYPES", "ActionBox", "ActionType", "AdaptiveAction", "ResidualAction",
           "action_type_named", "checked_action"]

#: A command: (speed [m/s], heading [rad], world frame).
Command = tuple[float, float]

#: the dtypes :func:`checked_action` reads without conversion
_FLOAT_DTYPES = (np.dtype(np.float32), np.dtype(np.float64))


def _unit_clip(x: float) -> float:
    """``x`` clipped to [-1, 1] as ``np.clip`` clips a float (signed zeros and NaN kept)."""
    return -1.0 if x < -1.0 else 1.0 if x > 1.0 else x


def checked_action(action: Any, names: tuple[str, ...] = ("dv", "dtheta")) -> list[float]:
    """The entries of an action with one entry per name, clipped to [-1, 1]; ValueError for a
    wrong shape, non-numbers (strings, complex numbers, booleans, None, ...), NaN or infinite
    values."""
    if (type(action) is np.ndarray and action.shape == (len(names),)
            and action.dtype in _FLOAT_DTYPES):
        # a float array, as a Gymnasium Box samples it: the checks and the clip below in
        # Python floats (a float32 converts to float64 exactly; min/max clip as np.clip,
        # signed zeros included); NaN and infinities go on to the checked path's error
        values = action.tolist()
        for x in values:
            if not -1.0 <= x <= 1.0:     # outside the box, or NaN
                break
        else:
            return values                # inside: the clip changes nothing
        if all(-math.inf < x < math.inf for x in values):
            return [_unit_clip(x) for x in values]
    layout = f"[{', '.join(names)}]"
    try:
        if np.iscomplexobj(action) or np.asarray(action).dtype.kind in "SUMmVbO":
            raise TypeError("not real numbers")
        if isinstance(action, (list, tuple)) and any(
                isinstance(x, (bool, np.bool_)) for x in action):
            raise TypeError("a boolean entry")   # numpy read [True, 0.5] as [1.0, 0.5]
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"action must be {len(names)} numbers {layout}, got {action!r}") from exc
    if a.shape != (len(names),):
        raise ValueError(f"action must have shape ({len(names)},) = {layout}, got shape "
                         f"{a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"action must be finite, got {a.tolist()} (NaN or infinite)")
    return np.clip(a, -1.0, 1.0).tolist()


class ActionBox(spaces.Box):
    """A Gymnasium ``Box`` whose :meth:`sample` returns the numbers ``Box.sample`` returns for
    the same seed, several times faster.

    For a box of floats bounded on every side, ``Box.sample`` draws ``Generator.uniform(low,
    high)``, that is ``low + (high - low) * u`` in float64 with ``u`` the generator's next
    doubles in C order, then casts to the dtype; this computes that formula directly, without
    ``Box.sample``'s interval masks and ``uniform``'s broadcasting (about 20 µs of a random
    AOASS-v0 step, ``benchmarks/step_speedup.py``). Any other box (an unbounded side, integers,
    a scalar shape, a bound range that overflows) and any ``mask`` or ``probability`` go to
    ``Box.sample`` itself. Which of the two draws a box takes is decided at construction, as
    the Box's own ``bounded_below`` and ``bounded_above`` are; the bounds are read at every
    draw.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        with np.errstate(over="ignore"):
            width = self.high.astype(np.float64) - self.low.astype(np.float64)
        self._uniform = (self.dtype.kind == "f" and len(self.shape) > 0
                         and bool(self.is_bounded("both")) and bool(np.isfinite(width).all()))

    def sample(self, mask: None = None, probability: None = None) -> np.ndarray:
        """A uniform draw from the box, as ``Box.sample`` draws it (class docstring)."""
        if probability is not None:      # Gymnasium 1.0's Box.sample has no such argument
            return super().sample(mask, probability)
        if not self._uniform or mask is not None:
            return super().sample(mask)
        low = self.low.astype(np.float64)
        return (low + (self.high - low) * self.np_random.random(self.shape)).astype(self.dtype)


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
    def action(self, speed: float, heading: float, nominal: Command,
               knobs: SweepKnobs | None = None) -> np.ndarray:
        """The action (clipped to the space) that commands (``speed``, ``heading``) when the
        nominal follower commands ``nominal`` (and sets ``knobs``, for a type that has them):
        the inverse of :meth:`command` within reach."""

    def knobs(self, action: Any) -> SweepKnobs | None:
        """The adaptive sweep's knobs that ``action`` sets; None for a type without them."""
        return None

    def decode(self, action: Any, nominal: Command) -> tuple[Command, SweepKnobs | None]:
        """(:meth:`command`, :meth:`knobs`) of ``action``, validated once (an environment's
        step)."""
        return self.command(action, nominal), self.knobs(action)

    @classmethod
    @abstractmethod
    def from_config(cls, config: AOASSConfig) -> ActionType:
        """What an agent's action means under ``config``."""

    @classmethod
    @abstractmethod
    def full_range(cls, config: AOASSConfig) -> ActionType:
        """The same type reaching every speed and heading from any nominal command: what a
        safety filter sends its inner environment."""


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

    NAMES: ClassVar[tuple[str, ...]] = ("dv", "dtheta")

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
    def space(self) -> ActionBox:
        return ActionBox(-1.0, 1.0, (2,), np.float32)

    def command(self, action: Any, nominal: Command) -> Command:
        return self._residual(*checked_action(action, self.NAMES)[:2], nominal)

    def _residual(self, dv: float, dtheta: float, nominal: Command) -> Command:
        speed, heading = nominal
        return (min(max(speed + dv * self.speed_scale, 0.0), self.max_speed),
                heading + dtheta * self.heading_scale)

    def action(self, speed: float, heading: float, nominal: Command,
               knobs: SweepKnobs | None = None) -> np.ndarray:
        speed_nom, heading_nom = nominal
        # np.clip's float64 values in Python floats (min/max as np.clip, NaN kept), cast once
        dv = (speed - speed_nom) / self.speed_scale
        dtheta = wrap_angle(heading - heading_nom) / self.heading_scale
        return np.array([_unit_clip(dv), _unit_clip(dtheta)], dtype=np.float32)


@dataclass(frozen=True)
class AdaptiveAction(ResidualAction):
    """Eq. 6's residual [Δv, Δθ] (as :class:`ResidualAction`) followed by the adaptive sweep's
    three knobs [skip, detour, densify] in [-1, 1] (:class:`~aoass_env.planning.adaptive.
    SweepKnobs`): the environment drives the anchor with the coverage-aware
    :class:`~aoass_env.planning.adaptive.AdaptiveSweep` and the knobs shift its thresholds.
    The zero action is the hand-written rule."""

    NAMES: ClassVar[tuple[str, ...]] = ("dv", "dtheta", *SweepKnobs._fields)

    @property
    def space(self) -> ActionBox:
        return ActionBox(-1.0, 1.0, (len(self.NAMES),), np.float32)

    def knobs(self, action: Any) -> SweepKnobs:
        return SweepKnobs(*checked_action(action, self.NAMES)[2:])

    def decode(self, action: Any, nominal: Command) -> tuple[Command, SweepKnobs]:
        dv, dtheta, *knobs = checked_action(action, self.NAMES)
        return self._residual(dv, dtheta, nominal), SweepKnobs(*knobs)

    def action(self, speed: float, heading: float, nominal: Command,
               knobs: SweepKnobs | None = None) -> np.ndarray:
        residual = super().action(speed, heading, nominal)
        return np.concatenate([residual, np.clip(knobs or SweepKnobs(), -1.0, 1.0)]
                              ).astype(np.float32)


#: The action types by name: ``gymnasium.make(..., action_type="adaptive")``.
ACTION_TYPES: dict[str, type[ResidualAction]] = {"residual": ResidualAction,
                                                  "adaptive": AdaptiveAction}


def action_type_named(name: Any) -> type[ResidualAction]:
    """The action type called ``name``; ValueError naming ``action_type`` and the valid
    names otherwise."""
    if not isinstance(name, str) or name not in ACTION_TYPES:
        raise ValueError(f"action_type={name!r} is not one of {sorted(ACTION_TYPES)} (or an "
                         f"aoass_env.action.ActionType)")
    return ACTION_TYPES[name]
