"""Hop counts between virtual anchors (beacon positions) and nodes over the radio graph.

With a single mobile anchor every beacon position is a *virtual anchor*. A beacon starts a
hop-count flood: the nodes that received it are one hop from it, and nodes pass the flood on to
the nodes they hear (``node_links``). Only nodes pass a flood on: a virtual anchor is the
anchor at another time, which broadcasts its own beacon and relays no other. The radio graph is
therefore directed, with two vertices per beacon: a source with an edge to each node that
received it, and a sink with an edge from each such node; nodes are linked both ways. Hop
counts are breadth-first distances from each source, computed for all beacons at once with
:func:`scipy.sparse.csgraph.dijkstra` on unit weights, stopped at a flooding limit: a beacon's
flood travels at most ``flood_limit`` hops, farther vertices count as unreachable (``inf``).

Beacon-to-beacon hop counts (Eq. 11) come out of the same search, at the sinks: two beacons
heard by one node are two hops apart (beacon -> node -> beacon); :func:`hop_size` turns them
into each beacon's HopSize (Eq. 11).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph

from aoass_env.beacon_log import BeaconLog, BeaconLogError
from aoass_env.validators import float_array, integer

__all__ = ["DEFAULT_FLOOD_LIMIT", "HopCounts", "hop_counts", "hop_size", "radio_graph",
           "require_beacons"]

#: Default flooding limit in hops. The paper is silent; 3 hops reach about 3R = 75 m, most of a
#: 100 m field, and keep the all-beacon search fast (docs/localization.md).
DEFAULT_FLOOD_LIMIT = 3


@dataclass(frozen=True)
class HopCounts:
    """Minimum hop counts of one episode (``inf`` beyond the flooding limit).

    Attributes:
        beacon_node: (B, N) float32, hops from each beacon to each node (1 = heard directly).
        beacon_beacon: (B, B) float32, hops between beacons (0 on the diagonal).
        flood_limit: the flooding limit used [hops].
    """

    beacon_node: np.ndarray
    beacon_beacon: np.ndarray
    flood_limit: int


def require_beacons(log: BeaconLog) -> None:
    """Raise :class:`BeaconLogError` naming ``beacons`` when the log holds no beacon."""
    if not isinstance(log, BeaconLog):
        raise TypeError(f"log must be a BeaconLog, got {type(log).__name__}")
    if log.n_beacons == 0:
        raise BeaconLogError("the log holds no beacons: nothing to localize from", "beacons")


def radio_graph(log: BeaconLog) -> sp.csr_matrix:
    """Directed radio graph as an (N + 2B) square CSR matrix: the N nodes, then each beacon's
    source, then each beacon's sink. Entries are 1: source -> node and node -> sink for a
    reception (beacon, node), node -> node both ways for a node link. No edge leaves a sink, so
    no path passes through another beacon."""
    n, b = log.n_nodes, log.n_beacons
    rec, links = log.receptions, log.node_links
    rows = np.concatenate([rec[:, 0] + n, rec[:, 1], links[:, 0], links[:, 1]])
    cols = np.concatenate([rec[:, 1], rec[:, 0] + n + b, links[:, 1], links[:, 0]])
    graph = sp.coo_matrix((np.ones(len(rows)), (rows, cols)),
                          shape=(n + 2 * b, n + 2 * b)).tocsr()
    graph.data[:] = 1.0  # duplicate receptions must not add up to a longer edge
    return graph


def check_flood_limit(flood_limit: object) -> int:
    """``flood_limit`` as an int; ValueError naming it unless it is a whole number >= 2 (hops;
    ``32.0`` is 32, as for every integer parameter). Two beacons are at least two hops apart
    (beacon, node, beacon), so with one hop no HopSize (Eq. 11) exists and DV-Hop would
    silently return the heard beacons' centroid."""
    return integer("flood_limit", flood_limit, "hops", low=2)


def hop_counts(log: BeaconLog, flood_limit: int = DEFAULT_FLOOD_LIMIT) -> HopCounts:
    """Hop counts from every beacon to every node and beacon, up to ``flood_limit`` hops.

    Raises:
        BeaconLogError: the log holds no beacons.
        ValueError: ``flood_limit`` is not an integer >= 2.
    """
    require_beacons(log)
    check_flood_limit(flood_limit)
    n, b = log.n_nodes, log.n_beacons
    dist = csgraph.dijkstra(radio_graph(log), directed=True, unweighted=True,
                            indices=np.arange(n, n + b), limit=float(flood_limit))
    beacon_node = np.ascontiguousarray(dist[:, :n], dtype=np.float32)
    beacon_beacon = np.ascontiguousarray(dist[:, n + b:], dtype=np.float32)
    np.fill_diagonal(beacon_beacon, 0.0)     # a beacon is 0 hops from itself, not 2
    beacon_node.flags.writeable = False
    beacon_beacon.flags.writeable = False
    return HopCounts(beacon_node, beacon_beacon, int(flood_limit))


def hop_size(beacon_xy: np.ndarray, beacon_hops: np.ndarray) -> np.ndarray:
    """Eq. 11: HopSize_i = sum_j |b_i - b_j| / sum_j h_ij over beacons j != i within reach.

    Args:
        beacon_xy: (B, 2) beacon positions [m].
        beacon_hops: (B, B) hop counts between beacons (``inf``: beyond the flooding limit).

    Returns:
        (B,) HopSize [m/hop]. A beacon that reaches no other beacon gets the network-wide
        ratio (all reachable pairs pooled); NaN if no pair is reachable at all.
    """
    xy, h = float_array("beacon_xy", beacon_xy), float_array("beacon_hops", beacon_hops)
    if xy.ndim != 2 or xy.shape[1] != 2 or h.shape != (len(xy), len(xy)):
        raise ValueError(f"beacon_xy must be (B, 2) and beacon_hops (B, B); got {xy.shape}, "
                         f"{h.shape}")
    if not np.all(np.isfinite(xy)):
        raise ValueError("beacon_xy must be finite")
    if not np.all(h >= 0):  # NaN fails too; inf (beyond the flooding limit) is fine
        raise ValueError("beacon_hops must be hop counts >= 0 (inf: unreachable)")
    i, j = np.nonzero(np.isfinite(h) & (h > 0))
    num = np.bincount(i, weights=np.hypot(*(xy[i] - xy[j]).T), minlength=len(xy))
    den = np.bincount(i, weights=h[i, j], minlength=len(xy))
    pooled = num.sum() / den.sum() if len(i) else np.nan
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / den, pooled)
