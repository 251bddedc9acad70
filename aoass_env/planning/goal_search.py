"""A compiled shortest-path search to one goal that says whether its path is *forced*.

The detour planner (:mod:`aoass_env.planning.detour`) answers with the path of scipy's
``dijkstra`` trees, whose ties (two neighbours giving a cell the same distance) its heap
settles. Distances do not depend on the heap: in floats a cell's distance is the least
left-to-right sum over the graph paths to it (adding a positive weight is monotone), whatever
order the cells are settled in. So when every cell of a path but its start has exactly one
neighbour ``u`` with ``dist[u] + w(u, v) == dist[v]``, every correct search that reaches the
goal traces that path, scipy's included: the path is *forced*. :func:`forced_path` finds such a
path with its own binary heap and gives the goal's distance; only for a tie on the path does
the planner run a scipy search.

The search is A*: a cell's key is its distance plus ``slope`` times its straight-line distance
(m) to the goal, and it stops when the goal is settled. With ``slope`` below the least weight
per metre of every edge by a margin (the caller's 0.1 %, far above the rounding of these sums),
the key grows strictly along every shortest path, so a cell is settled with its exact distance,
and every cell that could give a path cell its distance (a neighbour ``u`` with ``dist[u] +
w(u, v) == dist[v]``) has a smaller key than the goal and is settled before it. A neighbour not
settled yet cannot meet that equality (its tentative distance would make it a cell that does),
so the test of a path cell reads only final distances where it matters. ``slope = 0`` is
Dijkstra's search.
"""

from __future__ import annotations

import math

import numpy as np

from aoass_env.jit import njit

__all__ = ["FORCED", "TIE", "UNREACHABLE", "forced_path"]

#: What :func:`forced_path` found: a forced path, a tie on the path, or no path.
FORCED, TIE, UNREACHABLE = 0, 1, 2


@njit
def _weight(data: np.ndarray, k: int, scaled: bool, near: np.ndarray, factor: float, row: int,
            col: int) -> float:
    """Weight of entry ``k`` (row ``row``, column ``col``) of the CSR graph, times ``factor``
    once for each end in ``near`` when ``scaled``: ``(w * f_row) * f_col``, the floats of the
    detour planner's reweighted keep-out graph."""
    w = data[k]
    if scaled:
        w = (w * (factor if near[row] else 1.0)) * (factor if near[col] else 1.0)
    return w


@njit
def _search(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, xy: np.ndarray,
            slope: float, near: np.ndarray, factor: float, s: int,
            g: int) -> tuple[int, np.ndarray, float]:
    n = len(indptr) - 1
    scaled = len(near) > 0
    gx, gy = xy[g, 0], xy[g, 1]
    dist = np.full(n, np.inf)
    pred = np.empty(n, dtype=np.int64)
    settled = np.zeros(n, dtype=np.bool_)
    # binary min-heap of (key, cell), stale entries skipped when popped, grown by doubling
    keys = np.empty(1024)
    cells = np.empty(1024, dtype=np.int64)
    keys[0], cells[0], size = 0.0, s, 1
    dist[s] = 0.0
    found = False
    while size > 0:
        v = cells[0]
        size -= 1
        if size > 0:                      # sift the last entry down from the root
            last_key, last_cell, i = keys[size], cells[size], 0
            while True:
                c = 2 * i + 1
                if c >= size:
                    break
                if c + 1 < size and keys[c + 1] < keys[c]:
                    c += 1
                if keys[c] >= last_key:
                    break
                keys[i], cells[i], i = keys[c], cells[c], c
            keys[i], cells[i] = last_key, last_cell
        if settled[v]:
            continue                      # a stale entry: v was settled at a smaller key
        settled[v] = True
        if v == g:
            found = True
            break
        d = dist[v]
        for k in range(indptr[v], indptr[v + 1]):
            u = indices[k]
            if settled[u]:
                continue
            nd = d + _weight(data, k, scaled, near, factor, v, u)
            if nd < dist[u]:
                dist[u], pred[u] = nd, v
                key = nd + slope * math.hypot(xy[u, 0] - gx, xy[u, 1] - gy)
                if size == len(keys):
                    keys = np.concatenate((keys, np.empty(size)))
                    cells = np.concatenate((cells, np.empty(size, dtype=np.int64)))
                i = size                  # sift the new entry up
                size += 1
                while i > 0:
                    p = (i - 1) // 2
                    if keys[p] <= key:
                        break
                    keys[i], cells[i], i = keys[p], cells[p], p
                keys[i], cells[i] = key, u
    if not found:
        return UNREACHABLE, np.empty(0, dtype=np.int64), np.inf
    length = 1
    v = g
    while v != s:
        v = pred[v]
        length += 1
    path = np.empty(length, dtype=np.int64)
    path[0] = g
    for j in range(1, length):
        path[j] = pred[path[j - 1]]
    for j in range(length - 1):           # every cell but the start: one way in
        v = path[j]
        ways = 0
        for k in range(indptr[v], indptr[v + 1]):
            u = indices[k]
            if dist[u] + _weight(data, k, scaled, near, factor, v, u) == dist[v]:
                ways += 1
        if ways != 1:
            return TIE, np.empty(0, dtype=np.int64), dist[g]
    return FORCED, path, dist[g]


def forced_path(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, s: int, g: int, *,
                xy: np.ndarray | None = None, slope: float = 0.0,
                near: np.ndarray | None = None,
                factor: float = 1.0) -> tuple[int, np.ndarray, float]:
    """Search the CSR graph (``indptr``, ``indices``, ``data``: positive weights, both
    directions of every edge with the same weight) from cell ``s`` to cell ``g``.

    Args:
        xy: (cells, 2) positions (m) of the cells, for the A* key; needed when ``slope`` > 0.
        slope: the key's weight per metre of straight-line distance to the goal; every edge
            (u, v) must weigh more than ``slope * |xy[u] - xy[v]|`` by a margin far above the
            rounding (0 for Dijkstra's search).
        near: optional (cells,) mask; the weight of an entry (i, j) is then multiplied by
            ``factor`` (>= 1 when ``slope`` > 0) once for each of i and j in the mask,
            ``(w * f_i) * f_j`` in floats.

    Returns:
        ``(status, cells, distance)``: ``(FORCED, the forced path's cells (g first, s last),
        d)``, ``(TIE, [], d)`` when some cell of the path has two ways in, with ``d`` the
        goal's distance (scipy's ``dijkstra``'s, to the bit), or ``(UNREACHABLE, [], inf)``.
    """
    n = len(indptr) - 1
    positions = np.zeros((n, 2)) if xy is None else xy
    mask = np.zeros(0, dtype=np.bool_) if near is None else near
    status, cells, distance = _search(indptr, indices, data, positions, float(slope), mask,
                                      float(factor), int(s), int(g))
    return int(status), cells, float(distance)
