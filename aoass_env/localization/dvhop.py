"""Classical DV-Hop with a mobile anchor: HopSize (Eq. 11), hop distances, Eq. 13.

Every beacon position is a virtual anchor. Its HopSize (Eq. 11) is the summed distance to every
other beacon within the flooding limit divided by the summed hop counts to them. A node's
distance to a beacon is ``hops x HopSize`` of that beacon, and its position is the Eq. 13
least-squares fit to all beacons within the flooding limit (unit weights), started from the
centroid of the beacons it heard.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from aoass_env.localization.multilateration import multilaterate
from aoass_env.localization.ragged import pad_rows

if TYPE_CHECKING:
    from aoass_env.localization.episode import Episode

__all__ = ["dvhop", "hop_size"]


def hop_size(beacon_xy: np.ndarray, beacon_hops: np.ndarray) -> np.ndarray:
    """Eq. 11: HopSize_i = sum_j |b_i - b_j| / sum_j h_ij over beacons j != i within reach.

    Args:
        beacon_xy: (B, 2) beacon positions [m].
        beacon_hops: (B, B) hop counts between beacons (``inf``: beyond the flooding limit).

    Returns:
        (B,) HopSize [m/hop]. A beacon that reaches no other beacon gets the network-wide
        ratio (all reachable pairs pooled); NaN if no pair is reachable at all.
    """
    xy = np.asarray(beacon_xy, dtype=np.float64)
    h = np.asarray(beacon_hops, dtype=np.float64)
    if xy.ndim != 2 or xy.shape[1] != 2 or h.shape != (len(xy), len(xy)):
        raise ValueError(f"beacon_xy must be (B, 2) and beacon_hops (B, B); got {xy.shape}, "
                         f"{h.shape}")
    i, j = np.nonzero(np.isfinite(h) & (h > 0))
    num = np.bincount(i, weights=np.hypot(*(xy[i] - xy[j]).T), minlength=len(xy))
    den = np.bincount(i, weights=h[i, j], minlength=len(xy))
    pooled = num.sum() / den.sum() if len(i) else np.nan
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / den, pooled)


def dvhop(episode: Episode) -> np.ndarray:
    """Classical DV-Hop estimates (N, 2) [m]; NaN for nodes not covered under Eq. 18."""
    out = np.full((episode.log.n_nodes, 2), np.nan)
    nodes = np.flatnonzero(episode.covered)
    if len(nodes) == 0:
        return out
    hops = episode.hops.beacon_node[:, nodes].T  # (S, B)
    size = episode.hop_size
    rows, beacons = np.nonzero(np.isfinite(hops) & np.isfinite(size)[None, :])
    idx, _ = pad_rows(rows, beacons, len(nodes))
    valid = idx >= 0
    safe = np.where(valid, idx, 0)
    distances = np.where(valid, hops[np.arange(len(nodes))[:, None], safe] * size[safe], 0.0)
    out[nodes] = multilaterate(episode.beacon_xy[safe], distances, valid.astype(np.float64),
                               episode.heard_centroid[nodes], episode.field)
    return out
