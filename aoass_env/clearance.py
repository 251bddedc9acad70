"""Clearance certificates: cheap proofs that a swept query cannot reach the static obstacles.

:class:`ClearanceCertificates` remembers, for each tracked body, one point and its exact distance
(m) to the static obstacles and the field border. By the triangle inequality every point within
``d - |p - c|`` of a query point p is at least as far from them as that, so a query whose whole
reach lies within that distance of p provably misses every static shape and need not be run. A
body keeps its certificate while it moves a little; a failed check measures the distance anew at
the body's position (one nearest-shape query), which starts a fresh certificate.

The world uses it to skip pymunk's swept-disc queries that would return no hit, so results stay
exactly what the queries would give.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from aoass_env.validators import integer

__all__ = ["MARGIN", "ClearanceCertificates"]

#: Slack (m) of the proofs: a query is skipped only when it stays this much clear of every
#: static shape (far above the round-off of the distance and of the swept queries).
MARGIN = 1e-6


class ClearanceCertificates:
    """Remembered clearances (m) of a few bodies from the static obstacles and the border.

    Args:
        distance: ``distance(x, y)``: the exact distance (m) from (x, y) (m) to the nearest
            static obstacle or the field border, negative inside one; it may return any value
            up to the true distance (a cap) when nothing is nearer than that.
        slots: how many bodies keep a certificate (slot ``0 .. slots - 1``).
    """

    def __init__(self, distance: Callable[[float, float], float], slots: int) -> None:
        self._distance = distance
        # (centre x, centre y, clearance) per slot; NaN centres force a first measurement
        self._certs = [(math.nan, math.nan, -math.inf)] * integer("slots", slots, low=0)

    def clear(self, slot: int, x: float, y: float, reach: float) -> bool:
        """Whether every point within ``reach`` (m) of (x, y) (m) is provably more than
        :data:`MARGIN` away from every static obstacle and the field border."""
        cx, cy, d = self._certs[slot]
        free = d - reach - MARGIN
        dx, dy = x - cx, y - cy
        if free > 0.0 and dx * dx + dy * dy < free * free:
            return True
        d = self._distance(x, y)
        self._certs[slot] = (x, y, d)
        return d - reach - MARGIN > 0.0
