"""Path arithmetic: beacon points along a travelled path and the odometer reading."""

from __future__ import annotations

import bisect
import math

import numpy as np

from aoass_env.validators import finite_array, positive, real

#: Paths of at most this many samples get the pure-Python odometer and beacons of
#: :func:`beacons_along` (one control period has ``physics_substeps + 1``); numpy is faster
#: on longer ones.
_SHORT_PATH = 64

def _xy_length(rows: list[list[float]]) -> float:
    """Length (m) of the polyline through rows ending in (x [m], y [m]) (plain floats), the
    segments summed in order: the same float as numpy's norm and cumsum."""
    total = 0.0
    for (*_, x0, y0), (*_, x1, y1) in zip(rows, rows[1:], strict=False):
        dx, dy = x1 - x0, y1 - y0
        total += math.sqrt(dx * dx + dy * dy)
    return total


def beacons_along(path: np.ndarray, start_distance: float,
                  interval: float) -> tuple[np.ndarray, float]:
    """Beacon broadcasts along one piece of the anchor's path.

    A beacon is sent each time the odometer passes a multiple of ``interval`` (m), at the exact
    point of the path where it does so (linear interpolation between the path samples, in time
    too).

    Args:
        path: (P, 3) samples (t [s], x [m], y [m]) of the path, in order; ``path[0]`` is where the
            odometer reads ``start_distance``.
        start_distance: odometer reading at ``path[0]`` (m).
        interval: beacon interval (m), > 0.

    Returns:
        ``(beacons, end_distance)``: (B, 3) rows (t, x, y) of the beacons whose odometer mark lies
        in ``(start_distance, end_distance]``, and the odometer reading at ``path[-1]``.
    """
    interval = positive("interval", interval, "m")
    start_distance = real("start_distance", start_distance, "m")
    p = finite_array("path", path, "(t [s], x [m], y [m])", shape=(None, 3))
    if len(p) <= _SHORT_PATH:   # fast path: most control periods pass no beacon mark
        rows = p.tolist()
        end = start_distance + _xy_length(rows)
        if math.floor(end / interval + 1e-9) <= math.floor(start_distance / interval + 1e-9):
            return np.zeros((0, 3)), end
        return _short_beacons(rows, start_distance, interval), end
    seg = np.linalg.norm(np.diff(p[:, 1:], axis=0), axis=1)
    odo = start_distance + np.r_[0.0, np.cumsum(seg)]
    end = float(odo[-1])
    first = np.floor(start_distance / interval + 1e-9) + 1
    last = np.floor(end / interval + 1e-9)
    marks = np.arange(first, last + 1) * interval
    if len(marks) == 0:
        return np.zeros((0, 3)), end
    # segment k runs from sample k to k+1; the mark falls in the first segment reaching it
    k = np.clip(np.searchsorted(odo, marks, side="left"), 1, len(p) - 1) - 1
    frac = np.clip((marks - odo[k]) / np.where(seg[k] > 0, seg[k], 1.0), 0.0, 1.0)
    out = p[k] + frac[:, None] * (p[k + 1] - p[k])
    return out, end


#: The beacons of a period that passes no beacon mark (shared, read-only).
NO_BEACONS = np.zeros((0, 3))
NO_BEACONS.flags.writeable = False


def beacons_of_rows(rows: list[tuple[float, float, float]], start_distance: float,
                    interval: float) -> tuple[np.ndarray, float]:
    """:func:`beacons_along` of a path given as rows (t [s], x [m], y [m]) of plain floats (the
    simulator's control period), the same beacons and odometer float: a short path stays in
    floats (no array, no second pass for its length), and one that passes no beacon mark
    returns :data:`NO_BEACONS`. ``interval`` (m) must be positive (ValueError naming it, as
    :func:`beacons_along` says; one comparison on the common path)."""
    if not interval > 0.0:
        positive("interval", interval, "m")
    if len(rows) > _SHORT_PATH:
        return beacons_along(np.array(rows), start_distance, interval)
    end = start_distance + _xy_length(rows)
    if math.floor(end / interval + 1e-9) <= math.floor(start_distance / interval + 1e-9):
        return NO_BEACONS, end
    return _short_beacons(rows, start_distance, interval), end


def _short_beacons(rows: list[list[float]], start_distance: float,
                   interval: float) -> np.ndarray:
    """The beacons of :func:`beacons_along` on a short path of rows (t, x, y) (plain floats)
    that passes a mark: its NumPy steps in floats, element by element (the odometer as
    ``start + cumsum``, ``searchsorted`` as ``bisect_left``, ``clip`` as min/max)."""
    odo, total = [start_distance + 0.0], 0.0
    seg = []
    for (_, x0, y0), (_, x1, y1) in zip(rows, rows[1:], strict=False):
        dx, dy = x1 - x0, y1 - y0
        seg.append(math.sqrt(dx * dx + dy * dy))
        total += seg[-1]
        odo.append(start_distance + total)
    first = math.floor(start_distance / interval + 1e-9) + 1
    last = math.floor(odo[-1] / interval + 1e-9)
    out = []
    for mark in range(first, last + 1):
        mark = float(mark) * interval
        k = min(max(bisect.bisect_left(odo, mark), 1), len(rows) - 1) - 1
        frac = min(max((mark - odo[k]) / (seg[k] if seg[k] > 0 else 1.0), 0.0), 1.0)
        a, b = rows[k], rows[k + 1]
        out.append((a[0] + frac * (b[0] - a[0]), a[1] + frac * (b[1] - a[1]),
                    a[2] + frac * (b[2] - a[2])))
    return np.array(out, dtype=np.float64).reshape(-1, 3)
