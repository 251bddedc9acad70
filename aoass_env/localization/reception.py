"""Learned reception model (Eq. 12): what hearing and not hearing say about the anchor's range.

With radio irregularity the anchor hears a node in direction theta (world frame, from beacon to
node) up to R K(theta), where K is one closed random walk over the 360 degrees, shared by every
beacon of the episode and bounded by [1 - DOI, 1 + DOI] (:mod:`aoass_env.radio`). The pattern is
never in the log, but the log's record says a lot about it once the nodes are roughly placed: a
heard (beacon, node) pair in direction theta at distance d says K(theta) >= d / R, an unheard pair
in sight says K(theta) < d / R, unless a moving obstacle was in the way.

:func:`pair_statistics` turns first-stage node estimates into that record and
:func:`pair_histograms` into per-degree features: a histogram of the normalised distance
``z = (d / R - 1) / DOI`` of the heard pairs and one of the unheard pairs in sight of the
estimate. The OLSTM (:mod:`~aoass_env.localization.olstm`) reads the 360 degrees as a circular
sequence and predicts per degree a Gaussian over ``z_K = (K - 1) / DOI``.

:func:`range_band` gives the band the consensus scores with: hearing is *certain* within
R (1 + DOI (mu - a sigma)) and *possible* within R (1 + DOI (mu + a sigma)), per degree.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from aoass_env.localization.episode import Episode

__all__ = ["FEATURE_NAMES", "FEATURE_VERSION", "HIST_BINS", "N_FEATURES", "Z_RANGE", "PairRecord",
           "pair_histograms", "pair_statistics", "range_band"]

#: Histogram bins of z = (d / R - 1) / DOI per degree, over [-Z_RANGE, Z_RANGE].
HIST_BINS = 12
Z_RANGE = 1.5
#: Per-degree features: log(1 + count) of heard and of unheard-in-sight pairs per z bin, and
#: 10 DOI.
FEATURE_NAMES = (*(f"heard_z{i}" for i in range(HIST_BINS)),
                 *(f"unheard_z{i}" for i in range(HIST_BINS)), "doi")
N_FEATURES = len(FEATURE_NAMES)
#: Bumped whenever the meaning of a feature changes; checkpoints record it.
FEATURE_VERSION = 4


@dataclass(frozen=True)
class PairRecord:
    """(beacon, node) pairs near the range circle of one episode, from node estimates.

    Attributes:
        degree: (P,) direction from beacon to node estimate, whole degrees in [0, 360).
        z: (P,) (distance / R - 1) / DOI of the pair.
        heard: (P,) the node received the beacon.
        node: (P,) node index of the pair.
        doi: the episode's DOI bound.
    """

    degree: np.ndarray
    z: np.ndarray
    heard: np.ndarray
    node: np.ndarray
    doi: float


def pair_statistics(episode: Episode, nodes: np.ndarray, estimates: np.ndarray) -> PairRecord:
    """The pairs of ``nodes`` (S,) at ``estimates`` (S, 2) [m] with every beacon whose z is in
    [-Z_RANGE, Z_RANGE]: all heard ones, and the unheard ones in sight of the estimate (exact
    line of sight; every unheard one when the episode's radio ignores obstacles,
    ``line_of_sight`` false). Needs ``DOI > 0``."""
    log, doi = episode.log, episode.config.doi
    if doi <= 0:
        raise ValueError("pair statistics need radio irregularity (DOI > 0)")
    radius = log.radio_range
    xy = episode.beacon_xy
    lo, hi = radius * (1 - Z_RANGE * doi), radius * (1 + Z_RANGE * doi)
    lists = cKDTree(estimates).query_ball_point(xy, hi)
    counts = np.fromiter((len(x) for x in lists), dtype=np.int64, count=len(lists))
    beacon = np.repeat(np.arange(len(xy)), counts)
    row = np.concatenate([np.asarray(x, dtype=np.int64) for x in lists]) if counts.sum() \
        else np.zeros(0, np.int64)
    off = estimates[row] - xy[beacon]
    dist = np.hypot(off[:, 0], off[:, 1])
    keep = dist >= lo
    beacon, row, off, dist = beacon[keep], row[keep], off[keep], dist[keep]
    node = np.asarray(nodes, dtype=np.int64)[row]
    heard_keys = np.sort(log.receptions[:, 0] * log.n_nodes + log.receptions[:, 1])
    keys = beacon * log.n_nodes + node
    pos = np.minimum(np.searchsorted(heard_keys, keys), max(len(heard_keys) - 1, 0))
    heard = heard_keys[pos] == keys if len(heard_keys) else np.zeros(len(keys), dtype=bool)
    unheard = np.flatnonzero(~heard)
    sight = np.ones(len(keys), dtype=bool)
    if episode.config.line_of_sight:    # else an obstacle blocks nothing (it used to drop them)
        sight[unheard] = ~episode.line_of_sight.blocked(estimates[row[unheard]],
                                                        xy[beacon[unheard]])
    degree = np.rint(np.degrees(np.arctan2(off[:, 1], off[:, 0]))).astype(np.int64) % 360
    z = (dist / radius - 1) / doi
    return PairRecord(degree[sight], z[sight], heard[sight], node[sight], float(doi))


def pair_histograms(record: PairRecord, keep: np.ndarray | None = None) -> np.ndarray:
    """(360, N_FEATURES) float32 per-degree features of ``record`` (``keep``: mask of pairs)."""
    sel = slice(None) if keep is None else keep
    degree, z, heard = record.degree[sel], record.z[sel], record.heard[sel]
    b = np.clip(((z + Z_RANGE) / (2 * Z_RANGE) * HIST_BINS).astype(np.int64), 0, HIST_BINS - 1)
    hist = np.zeros((2, 360 * HIST_BINS))
    np.add.at(hist, (np.where(heard, 0, 1), degree * HIST_BINS + b), 1.0)
    feats = np.log1p(hist.reshape(2, 360, HIST_BINS)).transpose(1, 0, 2).reshape(360, -1)
    return np.concatenate([feats, np.full((360, 1), 10.0 * record.doi)], axis=1).astype(
        np.float32)


def range_band(mean: np.ndarray, std: np.ndarray, doi: float,
               width: float) -> tuple[np.ndarray, np.ndarray]:
    """Range factors (certain, possible) (360,) per degree: 1 + DOI (mean -/+ width std),
    clipped to [1 - DOI, 1 + DOI]."""
    lo = np.clip(1 + doi * (mean - width * std), 1 - doi, 1 + doi)
    hi = np.clip(1 + doi * (mean + width * std), 1 - doi, 1 + doi)
    return lo, hi
