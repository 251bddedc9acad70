"""Classical DV-Hop with a mobile anchor: hop distances and Eq. 13.

Every beacon position is a virtual anchor. Its HopSize (Eq. 11,
:func:`~aoass_env.localization.hops.hop_size`) is the summed distance to every
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

__all__ = ["dvhop"]


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
