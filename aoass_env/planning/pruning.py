"""The spiral pruned ahead on the static map: the free waypoints the anchor can leave out while
every cell the whole spiral would cover stays covered, or a tour through beacon sites that
covers the same cells (issue 19).

Sent through every free waypoint in order, the square spiral spends most of its path at
densities 0.2-0.4 on detours to waypoints beside and behind obstacle clusters, ring after ring
(on the maps/train fitting split the planner's way through them is 1.3-3x the ideal spiral's
776 m, and the follower drives it to within 2 %). With the radio range R well above the pass
spacing, the beacons sent elsewhere already cover most of what those waypoints add. The anchor
knows its static map, R, the DOI bound and its beacon interval, so it can tell which ones before
it moves:

1. **The full plan.** The free waypoints from the start on, in spiral order (those the planner
   cannot reach from the previous one are left out, as the follower gives them up), joined by
   the planner's ways. Beacons are placed every ``beacon_interval`` metres along each way from
   its start, and heard by the coverage map's virtual nodes (:mod:`aoass_env.planning.coverage`:
   guaranteed range and line of sight). The cells this plan covers (Eq. 18) are the
   *reference*.
2. **Greedy pruning.** A waypoint is removed when the planner's way from its predecessor to its
   successor is shorter (by more than :data:`MIN_GAIN`) than the way through it, and every
   reference cell stays covered with the beacons of the new way instead of the two old ones;
   the largest gain first. Then runs of 2-12 consecutive waypoints are tried the same way, in
   spiral order (a stub into a pocket and back, a corner cut across), and the two passes repeat
   while they remove anything (at most :data:`ROUNDS` times).

3. **A site tour** (:func:`plan_sites`, the rule's ``sites``). The spiral's waypoints are not
   where the beacons are needed: at densities 0.3-0.4 the pruned spiral still rides the rings
   round the obstacle clusters. The site tour keeps the spiral's reference and drops its
   waypoints: sites on a 4 m lattice of the planner's free cells (of the main region) are
   chosen by greedy set multicover until every reference cell hears ``need`` of them
   (guaranteed range and sight), joined from the spiral's start by a nearest-neighbour tour on
   the planner's costs, improved by 2-opt. Its planned beacons are then measured as above;
   where they leave reference cells uncovered (too few beacons, or collinear ones), sites of a
   1 m lattice are inserted (:func:`_repair`): each candidate, after the kept site where the
   planner's costs say it adds least, its new ways' beacons measured; the one that covers the
   most such cells per metre added goes in first. With an error limit, the tour's wide
   classes are split next (:func:`_split`): the cells that hear the same planned beacons form
   a class a range-free localizer cannot tell apart, and where a reference cell's class is
   wider (:func:`class_error`) than the larger of the limit and the whole spiral's, sites that
   part of the class hears are inserted, the most class error removed per metre first. Last,
   the tour is pruned as in 2 (with the reorder), keeping what it covers of the reference with
   the margin (and, with the limit, no class wider than the split tour's or the limit).
   Reference cells it could not cover are the cells phase's. With the limit, the plan marks
   its *localizing* points (``PrunedPlan.localizing``): those whose removal would keep the
   reference covered but break a class cap; the adaptive sweep's online skips leave them.

The plan is a plan: the beacons the anchor really sends fall at other points of its odometer,
moving obstacles push it aside, and the follower cuts corners. The adaptive sweep's densify
phase (:mod:`aoass_env.planning.adaptive`) revisits what the execution leaves uncovered.

A cell's Eq. 18 test needs only its beacons' count, sums and sums of products, so removing a way
subtracts its beacons' statistics and adding one adds them: a trial costs the cells the ways
reach. Beacon positions are snapped to a :data:`SNAP` metre lattice for the receivers' lookup
(which is cached), so ways that cross the same ground share it. Plans are cached per map and
settings (maps are immutable), so the episodes on one map share them; a fresh 100 m map takes a
few seconds.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy import sparse
from scipy.spatial import cKDTree

from aoass_env.network import lambda_min
from aoass_env.planning.detour import DetourPlanner
from aoass_env.radio import Radio

__all__ = ["MIN_GAIN", "PrunedPlan", "beacon_weight", "class_error",
           "plan_sites", "prune_spiral"]

#: A removal must shorten the plan by more than this (m).
MIN_GAIN = 0.3
#: Lengths of the runs of consecutive waypoints tried after the single ones.
RUN_LENGTHS = (2, 3, 4, 6, 8, 12)
#: Rounds of single and run pruning, at most.
ROUNDS = 3
#: Passes of 2-opt over the visiting order, at most.
REORDER_PASSES = 10
#: Lattice (m) the planned beacons are snapped to for the receivers' lookup.
SNAP = 0.25
#: Round-off allowance (m) of a way's length against the straight distance of its ends.
STRAIGHT_SLACK = 1e-9
#: Spacing (m) of the candidate beacon sites of a site tour (the planner's free cells, thinned).
SITE_STEP = 4.0
#: Spacing (m) of the candidate sites of a site tour's repair.
REPAIR_STEP = 1.0
#: Rounds of a site tour's repair: sites added where its planned beacons leave reference cells
#: uncovered (Eq. 18's spread, not only the count).
REPAIR_ROUNDS = 4
#: Candidate sites of a repair round (those the most uncovered reference cells hear).
REPAIR_CANDIDATES = 40
#: Sites a site tour's class split inserts, at most (one per round).
SPLIT_ROUNDS = 30
#: Classes whose candidates a round of the split tries (those with the most excess).
SPLIT_CLASSES = 6
#: Candidate sites per class (those nearest the tour).
SPLIT_CANDIDATES = 8
#: A candidate site tells a class's cells apart when at least this share of them hears it and
#: at least this share does not.
SPLIT_SHARE = 0.2
#: A split's insertion must remove at least this excess per metre it adds (m^2/m).
SPLIT_MIN_RATE = 0.05


@dataclass(frozen=True)
class PrunedPlan:
    """A pruned spiral, or a tour through beacon sites.

    Attributes:
        points: (P, 2) the plan's candidate points (m): the spiral's waypoints, or the spiral's
            start followed by the candidate beacon sites (:func:`plan_sites`).
        kept: (P,) bool: the points the plan visits (free, from the start on, reachable).
        order: the kept points' indices in visiting order (spiral order unless reordered).
        length: the planner's way through the kept points (m).
        full_length: the planner's way through every reachable free spiral waypoint (m).
        reference: (C,) bool: the coverage map's cells the full spiral plan covers; a pruned
            spiral covers each of them too (with its planned beacons), a site tour each it
            could (the cells phase goes for the others).
        localizing: (len(order),) bool, in visiting order: the kept points the plan's class
            limit needs (planned with an error limit): without one of them every reference
            cell stays covered, but some cell's :func:`class_error` rises above its cap. An
            online skip that judges coverage alone would undo them (docs/adaptive.md).
    """

    points: np.ndarray
    kept: np.ndarray
    order: np.ndarray
    length: float
    full_length: float
    reference: np.ndarray
    localizing: np.ndarray


_MASK = (1 << 64) - 1


class _Way(NamedTuple):
    """A planner's way between two waypoints and what its planned beacons give the cells."""

    length: float            # m
    cells: np.ndarray        # (K,) the cells that hear at least one of its beacons
    stats: np.ndarray        # (K, 6) their beacons' count, sums and sums of products
    signature: np.ndarray    # (K,) uint64: their beacons' summed weights


def beacon_weight(key: tuple[int, int]) -> int:
    """A pseudo-random 64-bit weight of the beacon point with lattice ``key`` (splitmix64 of
    it, offset so that no key weighs 0): the wrapped sum of the weights of the beacons a cell
    hears names its heard multiset (two different ones share a sum with a chance of about
    2^-64)."""
    z = (key[0] * 0xD1B54A32D192ED03 + key[1] * 0xABC98388FB8FAC03 + 0x9E3779B97F4A7C15) & _MASK
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _MASK
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _MASK
    return z ^ (z >> 31)


def class_error(signature: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """Squared distance (m^2) of every cell's centre to the mean centre of the cells that hear
    the same beacons (the same ``signature``): a range-free localizer cannot tell the cells of
    one class apart, so this is the error of a node placed at its class's centre."""
    _, inverse, counts = np.unique(signature, return_inverse=True, return_counts=True)
    cx = np.bincount(inverse, centres[:, 0]) / counts
    cy = np.bincount(inverse, centres[:, 1]) / counts
    return (centres[:, 0] - cx[inverse]) ** 2 + (centres[:, 1] - cy[inverse]) ** 2


class _Ways:
    """The planner's ways between waypoints with their planned beacons' per-cell statistics
    (count, sum x, sum y, sum xx, sum xy, sum yy) and heard-set signatures (the wrapped sums of
    :func:`beacon_weight`), cached per pair."""

    def __init__(self, waypoints: np.ndarray, planner: DetourPlanner, radio: Radio,
                 n_cells: int, interval: float) -> None:
        self.waypoints = waypoints
        self.planner = planner
        self.radio = radio
        self.n_cells = n_cells
        self.interval = interval
        self._ways: dict[tuple[int, int], _Way | None] = {}
        self._heard: dict[tuple[int, int], tuple[np.ndarray, np.uint64]] = {}

    def _hear(self, keys: list[tuple[int, int]]) -> None:
        """Cache the cells and weight of the lattice points ``keys`` not cached yet, the
        radio's line of sight tested for all of them at once."""
        new = list(dict.fromkeys(k for k in keys if k not in self._heard))
        if new:
            points = np.array(new, dtype=np.float64) * SNAP
            for key, cells in zip(new, self.radio.receivers_many(points), strict=True):
                self._heard[key] = (cells, np.uint64(beacon_weight(key)))

    def get(self, a: int, b: int) -> _Way | None:
        """(length m, cells, their (K, 6) statistics, their (K,) signature sums) of the way
        between waypoints ``a`` and ``b`` (the planner's from the lower index to the higher,
        either way round); None when the planner finds none."""
        key = (min(a, b), max(a, b))
        if key not in self._ways:
            way = self.planner.path(self.waypoints[key[0]], self.waypoints[key[1]])
            self._ways[key] = None if way is None else self._measure(way)
        return self._ways[key]

    def _measure(self, way: np.ndarray) -> _Way:
        """The way's length and what its beacons (every ``interval`` m from its start, snapped
        to the lattice) give the cells: their statistics summed beacon by beacon in order
        (``np.bincount`` adds in the order of its input, so the floats are those of adding
        the beacons one after the other) and their weights' wrapped sums."""
        steps = np.linalg.norm(np.diff(way, axis=0), axis=1)
        along = np.r_[0.0, np.cumsum(steps)]
        length = float(along[-1])
        marks = np.arange(self.interval, length + 1e-9, self.interval)
        xs, ys = np.interp(marks, along, way[:, 0]), np.interp(marks, along, way[:, 1])
        keys = list(zip(np.rint(xs / SNAP).astype(np.int64).tolist(),
                        np.rint(ys / SNAP).astype(np.int64).tolist(), strict=True))
        self._hear(keys)
        heard = [self._heard[k] for k in keys]
        sizes = np.array([len(cells) for cells, _ in heard], dtype=np.int64)
        cells = (np.concatenate([c for c, _ in heard]) if heard
                 else np.zeros(0, dtype=np.int64))
        snapped = np.array(keys, dtype=np.float64).reshape(-1, 2) * SNAP
        x, y = np.repeat(snapped[:, 0], sizes), np.repeat(snapped[:, 1], sizes)
        stats = np.stack([np.bincount(cells, weights=w, minlength=self.n_cells) for w in
                          (np.ones(len(cells)), x, y, x * x, x * y, y * y)], axis=1)
        stats = stats.astype(np.float64, copy=False)    # bincount of nothing gives int64
        signature = np.zeros(self.n_cells, dtype=np.uint64)
        np.add.at(signature, cells, np.repeat(
            np.array([w for _, w in heard], dtype=np.uint64), sizes))
        touched = np.flatnonzero(stats[:, 0])
        return _Way(length, touched, stats[touched], signature[touched])


def _covered(stats: np.ndarray, tol: float, beacons: float = 3) -> np.ndarray:
    """Eq. 18 from (K, 6) beacon statistics: at least ``beacons`` (3) beacons whose scatter's
    smallest eigenvalue is at least ``tol`` squared (:class:`~aoass_env.network.Network`'s
    test)."""
    n = stats[:, 0]
    safe = np.maximum(n, 1.0)
    mx, my = stats[:, 1] / safe, stats[:, 2] / safe
    scatter = np.stack([stats[:, 3] - n * mx * mx, stats[:, 4] - n * mx * my,
                        stats[:, 5] - n * my * my], axis=1)
    return (n >= beacons) & (lambda_min(scatter) >= tol * tol * (1.0 - 1e-9))


class _Pruner:
    """The greedy pruning of the module docstring, on a doubly linked list of waypoints."""

    def __init__(self, ways: _Ways, stops: list[int], tol: float, margin: tuple[float, float],
                 error_limit: float | None = None, costs: _Costs | None = None) -> None:
        self.ways = ways
        self.tol = tol
        self.margin = margin
        self.next = dict(zip(stops[:-1], stops[1:], strict=True))
        self.prev = dict(zip(stops[1:], stops[:-1], strict=True))
        self.first = stops[0]
        self.total = np.zeros((ways.n_cells, 6))
        self.signature = np.zeros(ways.n_cells, dtype=np.uint64)    # the cells' classes
        for a, b in zip(stops[:-1], stops[1:], strict=True):
            way = ways.get(a, b)
            self.total[way.cells] += way.stats
            self.signature[way.cells] += way.signature
        self.reference = _covered(self.total, tol)
        self.robust = self._robust(self.total)
        self.costs = costs          # the planner's costs between the points, when searched
        self.cap = None
        if error_limit is not None:
            full = class_error(self.signature, ways.radio.nodes)
            self.cap = np.where(self.reference, np.maximum(full, error_limit**2), np.inf)

    def _robust(self, stats: np.ndarray) -> np.ndarray:
        return _covered(stats, self.margin[1] * self.tol, self.margin[0])

    def order(self) -> list[int]:
        """The kept waypoints in order."""
        out = [self.first]
        while out[-1] in self.next:
            out.append(self.next[out[-1]])
        return out

    def length(self) -> float:
        """The way through the kept waypoints (m)."""
        stops = self.order()
        return sum(self.ways.get(a, b).length
                   for a, b in zip(stops[:-1], stops[1:], strict=True))

    def try_remove(self, run: list[int], min_gain: float) -> bool:
        """Remove the consecutive kept waypoints ``run`` when that shortens the plan by more
        than ``min_gain`` (m) and keeps every reference cell covered."""
        a, b = self.prev.get(run[0]), self.next.get(run[-1])
        if a is None or b is None:
            return False
        chain = [a, *run, b]
        old = [self.ways.get(x, y) for x, y in zip(chain[:-1], chain[1:], strict=True)]
        through = sum(w.length for w in old)
        # the planner's way from a to b is at least their distance (it ends at both): when
        # even that gains too little (less 1 nm of round-off), the way is not searched
        ends = self.ways.waypoints[b] - self.ways.waypoints[a]
        if through - (math.hypot(ends[0], ends[1]) - STRAIGHT_SLACK) <= min_gain:
            return False
        shortcut = self.ways.get(a, b)
        if shortcut is None or through - shortcut.length <= min_gain:
            return False
        if not self._exchange(old, [shortcut]):
            return False
        for x in run:
            del self.next[x], self.prev[x]
        self.next[a], self.prev[b] = b, a
        return True

    def _trial(self, old: list[_Way], new: list[_Way]) -> tuple[np.ndarray, np.ndarray, bool]:
        """(cells, their statistics, whether every reference cell among them stays covered and
        keeps its margin) with the ways ``new`` driven instead of ``old``."""
        cells = np.unique(np.concatenate([w.cells for w in old + new]))
        trial = self.total[cells]
        for way in old:
            trial[np.searchsorted(cells, way.cells)] -= way.stats
        for way in new:
            trial[np.searchsorted(cells, way.cells)] += way.stats
        keeps = not (np.any(self.reference[cells] & ~_covered(trial, self.tol))
                     or np.any(self.robust[cells] & ~self._robust(trial)))
        return cells, trial, keeps

    def _signature(self, old: list[_Way], new: list[_Way]) -> np.ndarray:
        """Every cell's signature with the ways ``new`` driven instead of ``old`` (a copy)."""
        whole = self.signature.copy()
        for way in old:
            whole[way.cells] -= way.signature
        for way in new:
            whole[way.cells] += way.signature
        return whole

    def _exchange(self, old: list[_Way], new: list[_Way]) -> bool:
        """Drive the ways ``new`` instead of ``old`` when every reference cell stays covered,
        keeps its margin and (with an error limit) its class error under its cap; whether it
        did."""
        cells, trial, keeps = self._trial(old, new)
        if not keeps:
            return False
        whole = self._signature(old, new)
        if self.cap is not None and np.any(class_error(whole, self.ways.radio.nodes) > self.cap):
            return False
        self.signature = whole
        self.total[cells] = trial
        return True

    def _around(self, site: int, after: int) -> tuple[list[_Way], list[_Way | None]]:
        """(old, new): the way from ``after`` to its successor (none at the end), and the ways
        through ``site`` instead."""
        b = self.next.get(after)
        if b is None:
            return [], [self.ways.get(after, site)]
        return [self.ways.get(after, b)], [self.ways.get(after, site), self.ways.get(site, b)]

    def insertion(self, site: int, after: int, target: np.ndarray
                  ) -> tuple[float, np.ndarray] | None:
        """(extra length m, the ``target`` cells it covers that are not covered now) of visiting
        ``site`` right after the kept point ``after``; None when the planner finds no way or a
        reference cell would lose its cover."""
        old, new = self._around(site, after)
        if any(w is None for w in new):
            return None
        cells, trial, keeps = self._trial(old, new)
        if not keeps:
            return None
        gained = cells[target[cells] & _covered(trial, self.tol)
                       & ~_covered(self.total[cells], self.tol)]
        return sum(w.length for w in new) - sum(w.length for w in old), gained

    def excess(self, cap: np.ndarray, signature: np.ndarray | None = None) -> np.ndarray:
        """(C,) every cell's :func:`class_error` above its ``cap`` (m^2; 0 below it), under the
        plan's signatures or ``signature``."""
        error = class_error(self.signature if signature is None else signature,
                            self.ways.radio.nodes)
        return np.maximum(error - cap, 0.0)

    def split(self, site: int, after: int, cap: np.ndarray) -> tuple[float, float] | None:
        """(extra length m, the summed :meth:`excess` then, m^2) of visiting ``site`` right
        after the kept point ``after``; None when the planner finds no way or a reference cell
        would lose its cover."""
        old, new = self._around(site, after)
        if any(w is None for w in new) or not self._trial(old, new)[2]:
            return None
        return (sum(w.length for w in new) - sum(w.length for w in old),
                float(self.excess(cap, self._signature(old, new)).sum()))

    def insert(self, site: int, after: int) -> None:
        """Visit ``site`` right after ``after`` (:meth:`insertion` or :meth:`split` said it
        may); the cells it covers join the reference."""
        b = self.next.get(after)
        old, new = self._around(site, after)
        cells, trial, _ = self._trial(old, new)
        self.signature = self._signature(old, new)
        self.total[cells] = trial
        self.reference[cells] |= _covered(trial, self.tol)
        self.next[after], self.prev[site] = site, after
        if b is not None:
            self.next[site], self.prev[b] = b, site

    def localizing(self) -> np.ndarray:
        """(kept points,) bool in visiting order: whether leaving the point out (its two ways
        replaced by the way between its neighbours; the last point's way dropped) keeps every
        reference cell covered with its margin but puts some cell's class error above the cap
        (all False without an error limit, and for the first point and those the planner
        cannot bypass)."""
        order = self.order()
        out = np.zeros(len(order), dtype=bool)
        if self.cap is None:
            return out
        for i, k in enumerate(order[1:], start=1):
            a, b = self.prev[k], self.next.get(k)
            old = [self.ways.get(a, k)] + ([self.ways.get(k, b)] if b is not None else [])
            new = [self.ways.get(a, b)] if b is not None else []
            if any(w is None for w in new) or not self._trial(old, new)[2]:
                continue
            error = class_error(self._signature(old, new), self.ways.radio.nodes)
            out[i] = bool(np.any(error > self.cap))
        return out

    def gain(self, k: int) -> float:
        """How much shorter (m) the plan gets without waypoint ``k`` (-inf when it cannot)."""
        a, b = self.prev.get(k), self.next.get(k)
        if a is None or b is None:
            return -math.inf
        shortcut = self.ways.get(a, b)
        if shortcut is None:
            return -math.inf
        return self.ways.get(a, k).length + self.ways.get(k, b).length - shortcut.length

    def singles(self, min_gain: float) -> bool:
        """Remove single waypoints, the largest gain first; whether any went."""
        heap = [(-g, k) for k in self.order() if (g := self.gain(k)) > min_gain]
        heapq.heapify(heap)
        removed = False
        while heap:
            neg, k = heapq.heappop(heap)
            if k not in self.prev:
                continue
            g = self.gain(k)
            if g <= min_gain:
                continue
            if g < -neg - 1e-9:               # stale: its neighbours changed
                heapq.heappush(heap, (-g, k))
                continue
            a, b = self.prev[k], self.next[k]
            if self.try_remove([k], min_gain):
                removed = True
                for j in (a, b):
                    if (gj := self.gain(j)) > min_gain:
                        heapq.heappush(heap, (-gj, j))
        return removed

    def reorder(self, min_gain: float) -> bool:
        """2-opt on the visiting order: reverse a stretch of kept waypoints when joining its ends
        the other way round shortens the plan by more than ``min_gain`` (m) and keeps every
        reference cell covered (the stretch's own ways are the same ways driven backwards).
        Moves are proposed on the planner's costs between every two kept waypoints, checked on
        the ways' lengths. Whether the order changed."""
        order = self.order()
        n = len(order)
        if n < 4:
            return False
        if self.costs is not None:          # the rows already searched, the same costs
            cost = np.array([self.costs.row(k)[order] for k in order])
        else:
            points = self.ways.waypoints[order]
            cost = np.array([self.ways.planner.costs(p, points) for p in points])
        cost = np.minimum(cost, cost.T)
        row = {k: r for r, k in enumerate(order)}
        changed, improved, passes = False, True, 0
        while improved and passes < REORDER_PASSES:
            improved, passes = False, passes + 1
            for i in range(1, n - 1):
                for j in range(i + 1, n):
                    a, b, c = row[order[i - 1]], row[order[i]], row[order[j]]
                    d = row[order[j + 1]] if j + 1 < n else None
                    delta = cost[a, c] - cost[a, b]
                    if d is not None:
                        delta += cost[b, d] - cost[c, d]
                    if delta < -min_gain and self._swap(order, i, j, min_gain):
                        changed = improved = True
        if changed:
            self.next = dict(zip(order[:-1], order[1:], strict=True))
            self.prev = dict(zip(order[1:], order[:-1], strict=True))
        return changed

    def _swap(self, order: list[int], i: int, j: int, min_gain: float) -> bool:
        """Reverse ``order[i:j + 1]`` in place when that shortens the plan by more than
        ``min_gain`` and keeps every reference cell covered."""
        a, b, c = order[i - 1], order[i], order[j]
        d = order[j + 1] if j + 1 < len(order) else None
        old = [self.ways.get(a, b)] + ([self.ways.get(c, d)] if d is not None else [])
        new = [self.ways.get(a, c)] + ([self.ways.get(b, d)] if d is not None else [])
        if any(w is None for w in new):
            return False
        if sum(w.length for w in old) - sum(w.length for w in new) <= min_gain:
            return False
        if not self._exchange(old, new):
            return False
        order[i:j + 1] = order[i:j + 1][::-1]
        return True

    def runs(self, length: int, min_gain: float) -> bool:
        """Remove runs of ``length`` consecutive waypoints, in spiral order; whether any went."""
        removed = False
        for k in self.order():
            if k not in self.prev:
                continue
            run = [k]
            while len(run) < length and run[-1] in self.next:
                run.append(self.next[run[-1]])
            if len(run) == length and self.try_remove(run, min_gain):
                removed = True
        return removed


def _stops(ways: _Ways, blocked: np.ndarray, start: int) -> list[int]:
    """The full plan's waypoints: the free ones from ``start`` on, in order, less those the
    planner cannot reach from the previous one (the follower gives them up)."""
    free = [int(i) for i in np.flatnonzero(~np.asarray(blocked, dtype=bool)) if i >= start]
    stops = free[:1]
    for k in free[1:]:
        if ways.get(stops[-1], k) is not None:
            stops.append(k)
    return stops


def _prune(pruner: _Pruner, reorder: bool, min_gain: float) -> None:
    """The greedy passes (module docstring), repeated while they change anything."""
    for _ in range(ROUNDS):
        changed = pruner.singles(min_gain)
        for length in RUN_LENGTHS:
            changed = pruner.runs(length, min_gain) or changed
        if reorder:
            changed = pruner.reorder(min_gain) or changed
        if not changed:
            break


def _plan(points: np.ndarray, pruner: _Pruner, full: float,
          reference: np.ndarray) -> PrunedPlan:
    order = np.array(pruner.order(), dtype=np.int64)
    kept = np.zeros(len(points), dtype=bool)
    kept[order] = True
    return PrunedPlan(points, kept, order, pruner.length(), full, reference,
                      pruner.localizing())


def prune_spiral(waypoints: np.ndarray, blocked: np.ndarray, start: int,
                 planner: DetourPlanner, radio: Radio, n_cells: int, beacon_interval: float,
                 collinearity_tol: float, margin: tuple[float, float] = (3, 1.0),
                 reorder: bool = False, min_gain: float = MIN_GAIN,
                 error_limit: float | None = None) -> PrunedPlan:
    """Prune the spiral ``waypoints`` (W, 2) (m) with ``blocked`` (W,) from waypoint ``start``
    on (module docstring).

    Args:
        planner: the detour planner of the map (the ways between waypoints).
        radio: the coverage map's radio of its ``n_cells`` virtual nodes.
        beacon_interval: metres between planned beacons.
        collinearity_tol: Eq. 18's spread (m).
        margin: (beacons, spread factor): a cell the full plan covers with at least that many
            beacons spread that many times ``collinearity_tol`` keeps that margin in the
            pruned plan (the execution's beacons fall elsewhere than the plan's).
        min_gain: a removal must shorten the plan by more than this (m).
        error_limit: when given (m), a reference cell's :func:`class_error` under the kept
            plan's beacons must stay at most the larger of its square and the full plan's (the
            kept plan must not make the cells harder to tell apart than that).
    """
    points = np.asarray(waypoints, dtype=np.float64)
    ways = _Ways(points, planner, radio, n_cells, beacon_interval)
    pruner = _Pruner(ways, _stops(ways, blocked, start), collinearity_tol, margin, error_limit)
    full = pruner.length()
    _prune(pruner, reorder, min_gain)
    return _plan(points, pruner, full, pruner.reference)


def _multicover(heard: sparse.csr_matrix, need: np.ndarray) -> list[int]:
    """Greedy set multicover: sites (rows of ``heard``, sites x cells, 1 where the cell hears a
    beacon from the site), each next the one heard by the most cells still in need (the lowest
    index among ties), until no site left serves a cell in need. ``need`` (cells,) counts
    down in place."""
    chosen: list[int] = []
    taken = np.zeros(heard.shape[0], dtype=bool)
    while True:
        gains = heard @ (need > 0).astype(np.int64)
        gains[taken] = -1
        site = int(np.argmax(gains))
        if gains[site] <= 0:
            return chosen
        chosen.append(site)
        taken[site] = True
        cells = heard.indices[heard.indptr[site]:heard.indptr[site + 1]]
        need[cells] = np.maximum(need[cells] - 1, 0)


class _Costs:
    """The planner's costs (m) from candidate points to all of them, one search per row,
    cached, made symmetric by the smaller of the two ways round."""

    def __init__(self, points: np.ndarray, planner: DetourPlanner) -> None:
        self.points = points
        self.planner = planner
        self._rows: dict[int, np.ndarray] = {}

    def row(self, a: int) -> np.ndarray:
        if a not in self._rows:
            self._rows[a] = self.planner.costs(self.points[a], self.points)
        return self._rows[a]

    def __call__(self, a: int, b: int) -> float:
        return float(min(self.row(a)[b], self.row(b)[a]))


def _tour(stops: list[int], cost: _Costs) -> list[int]:
    """An open tour from ``stops[0]`` through all ``stops``: nearest neighbour, then 2-opt
    (reversals that shorten it by more than 1 mm) until none is left."""
    first, left = stops[0], set(stops[1:])
    order = [first]
    while left:
        here = cost.row(order[-1])
        nxt = min(left, key=lambda k: (min(here[k], cost.row(k)[order[-1]]), k))
        order.append(nxt)
        left.remove(nxt)
    n = len(order)
    pairs = {(a, b): cost(a, b) for a in order for b in order}
    improved = True
    while improved:
        improved = False
        for i in range(1, n - 1):
            for j in range(i + 1, n):
                a, b, c = order[i - 1], order[i], order[j]
                delta = pairs[a, c] - pairs[a, b]
                if j + 1 < n:
                    d = order[j + 1]
                    delta += pairs[b, d] - pairs[c, d]
                if delta < -1e-3:
                    order[i:j + 1] = order[i:j + 1][::-1]
                    improved = True
    return order


def _heard_by(radio: Radio, sites: np.ndarray, n_cells: int) -> sparse.csr_matrix:
    """(sites x cells) 1 where the cell's virtual node hears a beacon sent from the site."""
    found = radio.receivers_many(sites)
    rows = np.repeat(np.arange(len(sites)), [len(c) for c in found])
    cols = np.concatenate(found) if found else rows
    return sparse.csr_matrix((np.ones(len(rows), dtype=np.int64), (rows, cols)),
                             shape=(len(sites), n_cells))


def plan_sites(waypoints: np.ndarray, blocked: np.ndarray, start: int,
               planner: DetourPlanner, radio: Radio, n_cells: int, beacon_interval: float,
               collinearity_tol: float, margin: tuple[float, float] = (3, 1.0),
               site_step: float = SITE_STEP, need: int = 3, reorder: bool = True,
               min_gain: float = MIN_GAIN, error_limit: float | None = None) -> PrunedPlan:
    """A tour through beacon sites that covers the spiral's reference (module docstring, 3):
    ``waypoints``, ``blocked`` and ``start`` are the spiral's (they give the reference and the
    tour's first point), the other arguments as :func:`prune_spiral`'s; every reference cell
    hears ``need`` sites of the set cover, whose candidates lie ``site_step`` (m) apart, and
    the repair's :data:`REPAIR_STEP` (the planner's free cells of its main region, thinned).
    The plan's points are the spiral's start followed by every repair candidate (a lattice
    the set cover's candidates are part of). With ``error_limit`` the repaired tour's wide
    classes are split (:func:`_split`: sites inserted where a reference cell's
    :func:`class_error` exceeds the larger of ``error_limit`` squared and the whole spiral
    plan's), and the last pruning keeps every reference cell's class error at most the larger
    of ``error_limit`` squared and the split tour's."""
    spiral = _Ways(np.asarray(waypoints, dtype=np.float64), planner, radio, n_cells,
                   beacon_interval)
    stops = _stops(spiral, blocked, start)
    whole = _Pruner(spiral, stops, collinearity_tol, margin)
    reference, full = whole.reference, whole.length()
    fine = max(1, round(REPAIR_STEP / planner.res))
    coarse = max(fine, fine * round(site_step / (fine * planner.res)))
    cells = planner.main_cells(fine)
    points = np.vstack([spiral.waypoints[stops[0]][None], cells])
    ij = np.rint(cells / planner.res - 0.5).astype(np.int64)
    lattice = 1 + np.flatnonzero((ij[:, 0] % coarse == 0) & (ij[:, 1] % coarse == 0))
    cost = _Costs(points, planner)
    # set cover on the coarse lattice: every reference cell hears `need` sites
    heard = _heard_by(radio, points[lattice], n_cells)
    chosen = [int(lattice[k]) for k in _multicover(heard, np.where(reference, need, 0))]
    order = _tour([0, *(k for k in chosen if np.isfinite(cost(0, k)))], cost)
    # repair on the fine lattice (every point but the start is a candidate site)
    ways = _Ways(points, planner, radio, n_cells, beacon_interval)
    pruner = _Pruner(ways, order, collinearity_tol, margin)
    listeners = Radio(points, radio.obstacle_map, radio.radio_range,
                      line_of_sight=radio.line_of_sight)
    _repair(pruner, reference, cost, listeners)

    def kept(order: list[int]) -> _Pruner:
        """The tour ``order``: it keeps what it covers of the spiral's reference (the rest
        is the cells phase's)."""
        tour = _Pruner(ways, order, collinearity_tol, margin, error_limit, cost)
        tour.reference &= reference
        tour.robust &= reference
        return tour

    pruner = kept(pruner.order())
    if error_limit is not None:     # no wider classes than the whole spiral's, or the limit
        spiral_error = class_error(whole.signature, radio.nodes)
        _split(pruner, np.where(reference, np.maximum(spiral_error, error_limit**2), np.inf),
               cost, listeners)
        pruner = kept(pruner.order())       # the split tour's classes are the cap
    _prune(pruner, reorder, min_gain)
    return _plan(points, pruner, full, reference)


def _repair(pruner: _Pruner, reference: np.ndarray, cost: _Costs, listeners: Radio) -> None:
    """Insert sites where the tour's planned beacons leave ``reference`` cells uncovered: the
    candidates are the points (``listeners``' nodes) these cells hear, the
    :data:`REPAIR_CANDIDATES` heard by the most of them (nearest the tour among ties); each
    is tried after the kept point where the planner's costs say it adds the least, and the
    insertion that covers the most such cells per metre added goes in (its way's beacons
    measured, no reference cell lost), again while one covers any, :data:`REPAIR_ROUNDS`
    rounds of candidates at most."""
    radio = pruner.ways.radio
    for _ in range(REPAIR_ROUNDS):
        short = reference & ~pruner.reference
        if not short.any():
            return
        cells = np.flatnonzero(short)
        found = listeners.receivers_many(radio.nodes[cells])    # range and sight are symmetric
        heard = np.bincount(np.concatenate(found), minlength=len(listeners.nodes)) if found \
            else np.zeros(len(listeners.nodes), dtype=np.int64)
        order = pruner.order()
        heard[order] = 0
        candidates = np.flatnonzero(heard)
        near, _ = cKDTree(listeners.nodes[order]).query(listeners.nodes[candidates])
        candidates = candidates[np.lexsort((near, -heard[candidates]))][:REPAIR_CANDIDATES]
        inserted = False
        while True:
            best, pick = 0.0, None
            order = pruner.order()
            for site in candidates:
                site = int(site)
                after = _cheapest_after(pruner, order, site, cost)
                if after is None:
                    continue
                tried = pruner.insertion(site, after, short)
                if tried is None or not len(tried[1]):
                    continue
                rate = len(tried[1]) / max(tried[0], 1.0)
                if rate > best:
                    best, pick = rate, (site, after)
            if pick is None:
                break
            pruner.insert(*pick)
            short &= ~pruner.reference
            inserted = True
        if not inserted:
            return


def _cheapest_after(pruner: _Pruner, order: list[int], site: int, cost: _Costs) -> int | None:
    """The kept point (of ``order``, the tour) after which visiting ``site`` adds the least to
    the planner's costs; None when ``site`` is kept already or unreachable."""
    if site in pruner.prev or site == pruner.first or not np.isfinite(cost(order[0], site)):
        return None
    # cost(a, site) + (cost(site, b) - cost(a, b)) for each kept a and its successor b (cost(a,
    # site) + 0.0 for the last), on arrays: the same floats (min of two costs, then the sums)
    at = np.array(order)
    to_site = np.minimum(np.array([cost.row(a)[site] for a in order]), cost.row(site)[at])
    legs = np.array([cost(a, b) for a, b in zip(order, order[1:], strict=False)])
    extra = to_site + np.append(to_site[1:] - legs, 0.0)
    return order[int(np.argmin(extra))]


def _split(pruner: _Pruner, cap: np.ndarray, cost: _Costs, listeners: Radio) -> None:
    """Insert sites where the tour's planned beacons leave cells in wide classes: a range-free
    localizer cannot tell apart the cells that hear the same beacons, so a cell's
    :func:`class_error` above its ``cap`` (m^2; inf: not judged) is error it cannot avoid.
    Per round, the :data:`SPLIT_CLASSES` classes with the most such excess (summed over their
    cells) give the candidates: the points (``listeners``' nodes) that between
    :data:`SPLIT_SHARE` and 1 - :data:`SPLIT_SHARE` of the class's cells hear, the
    :data:`SPLIT_CANDIDATES` nearest the tour. Each is tried after the kept point where the
    planner's costs say it adds the least, its new ways' beacons measured (no reference cell
    lost); the one that removes the most excess per metre added goes in while that is at
    least :data:`SPLIT_MIN_RATE`, :data:`SPLIT_ROUNDS` times at most."""
    nodes = pruner.ways.radio.nodes
    for _ in range(SPLIT_ROUNDS):
        excess = pruner.excess(cap)
        wide = np.flatnonzero(excess > 0.0)
        if not len(wide):
            return
        now = float(excess.sum())
        classes: dict[int, list[int]] = {}
        for cell, signature in zip(wide.tolist(), pruner.signature[wide].tolist(),
                                   strict=True):
            classes.setdefault(signature, []).append(cell)
        order = pruner.order()
        tour = cKDTree(listeners.nodes[order])
        candidates: list[int] = []
        for members in sorted(classes.values(), key=lambda m: -excess[m].sum())[:SPLIT_CLASSES]:
            heard = np.bincount(np.concatenate(listeners.receivers_many(nodes[members])),
                                minlength=len(listeners.nodes)) / len(members)
            points = np.flatnonzero((heard >= SPLIT_SHARE) & (heard <= 1.0 - SPLIT_SHARE))
            if len(points):
                near, _ = tour.query(listeners.nodes[points])
                candidates += points[np.argsort(near, kind="stable")][:SPLIT_CANDIDATES].tolist()
        best, pick = 0.0, None
        for site in dict.fromkeys(candidates):
            after = _cheapest_after(pruner, order, site, cost)
            tried = None if after is None else pruner.split(site, after, cap)
            if tried is not None and (rate := (now - tried[1]) / max(tried[0], 1.0)) > best:
                best, pick = rate, (site, after)
        if pick is None or best < SPLIT_MIN_RATE:
            return
        pruner.insert(*pick)
