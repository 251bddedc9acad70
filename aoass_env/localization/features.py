"""Per-node beacon sequences and their features, the input of the OLSTM (Eq. 12).

For each node to localize, the sequence holds the beacons within a window around a *reference
point* (the node's visibility-consensus estimate, :mod:`~aoass_env.localization.consensus`), in
broadcast (time) order. The window radius is the distance from the reference to the farthest
heard beacon plus ``margin``, so every heard beacon is in it together with the unheard beacons
just beyond the node's range: not hearing a beacon that passed close by is information too.
Sequences longer than ``max_len`` keep the beacons nearest the reference.

Features per (node, beacon) step, lengths in units of the radio range R:

==========  ==========================================================================
name        meaning
==========  ==========================================================================
dx, dy      beacon position minus the reference point, / R
range       distance from the reference point to the beacon, / R
heard       1 if the node received the beacon directly (hop count 1), else 0
clear       1 if no obstacle blocks the segment from the reference point to the beacon
            (1 for heard beacons: a reception needs line of sight)
hops        hop count from the beacon to the node, capped at flood limit + 1, / that cap
hop_size    the beacon's HopSize (Eq. 11), / R
step        straight-line distance from the previous beacon of the sequence, / R (<= 2)
travel      distance the anchor travelled since the previous beacon of the sequence
            (index difference x beacon interval), / R (<= 4)
degree      log(1 + number of neighbour nodes of the node) / 4
spread      RMS radius of the node's consensus region (its best cells), / R
==========  ==========================================================================
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from aoass_env.localization.episode import Episode
from aoass_env.localization.ragged import pad_rows

__all__ = ["FEATURE_NAMES", "FEATURE_VERSION", "MAX_LEN", "WINDOW_MARGIN", "Sequences",
           "build_sequences"]

FEATURE_NAMES = ("dx", "dy", "range", "heard", "clear", "hops", "hop_size", "step", "travel",
                 "degree", "spread")
#: Bumped whenever the meaning of a feature changes; checkpoints record it.
FEATURE_VERSION = 3
#: Window margin beyond the farthest heard beacon [m].
WINDOW_MARGIN = 10.0
#: Longest sequence [beacons].
MAX_LEN = 256
_STEP_CAP, _TRAVEL_CAP, _DEGREE_SCALE = 2.0, 4.0, 4.0


@dataclass(frozen=True)
class Sequences:
    """Padded beacon sequences of S nodes.

    Attributes:
        nodes: (S,) node index of each sequence.
        beacons: (S, L) beacon indices in time order, -1 after the end.
        lengths: (S,) sequence lengths (>= 1).
        features: (S, L, F) float32 features (``FEATURE_NAMES``), 0 after the end.
    """

    nodes: np.ndarray
    beacons: np.ndarray
    lengths: np.ndarray
    features: np.ndarray

    @property
    def mask(self) -> np.ndarray:
        """(S, L) True on real steps."""
        return self.beacons >= 0


def _windows(beacon_xy: np.ndarray, refs: np.ndarray, radius: np.ndarray,
             max_len: int) -> tuple[np.ndarray, np.ndarray]:
    """(sequence, beacon) pairs: beacons within ``radius`` of each reference, at most
    ``max_len`` nearest per sequence, grouped by sequence and in time order."""
    lists = cKDTree(beacon_xy).query_ball_point(refs, radius, return_sorted=True)
    counts = np.fromiter((len(x) for x in lists), dtype=np.int64, count=len(lists))
    beacons = (np.concatenate([np.asarray(x, dtype=np.int64) for x in lists]) if counts.sum()
               else np.zeros(0, np.int64))
    seq = np.repeat(np.arange(len(refs)), counts)
    if counts.max(initial=0) > max_len:
        dist = np.hypot(*(beacon_xy[beacons] - refs[seq]).T)
        order = np.lexsort((dist, seq))
        rank = np.arange(len(seq)) - np.repeat(np.cumsum(counts) - counts, counts)
        keep = np.sort(order[rank < max_len])  # original order is by sequence, then time
        seq, beacons = seq[keep], beacons[keep]
    return seq, beacons


def build_sequences(episode: Episode, nodes: np.ndarray, refs: np.ndarray, spread: np.ndarray,
                    *, margin: float = WINDOW_MARGIN, max_len: int = MAX_LEN) -> Sequences:
    """Feature sequences of ``nodes`` around the reference points ``refs`` (S, 2) [m], whose
    consensus regions have RMS radius ``spread`` (S,) [m].

    Every node must have heard at least one beacon (its window is sized by them).

    Raises:
        ValueError: a node heard no beacon, or the shapes disagree.
    """
    log = episode.log
    nodes = np.asarray(nodes, dtype=np.int64)
    refs = np.asarray(refs, dtype=np.float64)
    spread = np.asarray(spread, dtype=np.float64)
    if nodes.ndim != 1 or refs.shape != (len(nodes), 2) or not np.all(np.isfinite(refs)) \
            or spread.shape != (len(nodes),):
        raise ValueError(f"nodes must be (S,), refs finite (S, 2) and spread (S,); got "
                         f"{nodes.shape}, {refs.shape}, {spread.shape}")
    r_unit = log.radio_range
    xy = episode.beacon_xy
    seq_of = np.full(log.n_nodes, -1, dtype=np.int64)
    seq_of[nodes] = np.arange(len(nodes))
    rec_b, rec_s = log.receptions[:, 0], seq_of[log.receptions[:, 1]]
    rec_b, rec_s = rec_b[rec_s >= 0], rec_s[rec_s >= 0]
    far = np.full(len(nodes), -np.inf)
    np.maximum.at(far, rec_s, np.hypot(*(xy[rec_b] - refs[rec_s]).T))
    if np.isinf(far).any():
        bad = nodes[np.flatnonzero(np.isinf(far))[0]]
        raise ValueError(f"node {bad} heard no beacon: it has no sequence window")
    seq, b = _windows(xy, refs, far + margin, max_len)
    k = nodes[seq]
    first = np.ones(len(seq), dtype=bool)
    first[1:] = seq[1:] != seq[:-1]
    prev = np.where(first, b, np.roll(b, 1))
    cap = episode.hops.flood_limit + 1.0
    hops = np.minimum(episode.hops.beacon_node[b, k], cap)
    degree = np.bincount(log.node_links.ravel(), minlength=log.n_nodes)[k]
    off = (xy[b] - refs[seq]) / r_unit
    clear = np.ones(len(seq))
    unheard = np.flatnonzero(hops != 1)
    clear[unheard] = ~episode.line_of_sight.blocked(refs[seq[unheard]], xy[b[unheard]])
    columns = {
        "dx": off[:, 0], "dy": off[:, 1], "range": np.hypot(off[:, 0], off[:, 1]),
        "heard": (hops == 1).astype(np.float64), "clear": clear, "hops": hops / cap,
        "hop_size": np.nan_to_num(episode.hop_size[b] / r_unit),
        "step": np.minimum(np.hypot(*(xy[b] - xy[prev]).T) / r_unit, _STEP_CAP),
        "travel": np.minimum((b - prev) * episode.config.beacon_interval / r_unit, _TRAVEL_CAP),
        "degree": np.log1p(degree) / _DEGREE_SCALE,
        "spread": np.nan_to_num(spread[seq] / r_unit),
    }
    flat = np.stack([columns[name] for name in FEATURE_NAMES], axis=1).astype(np.float32)
    padded, lengths = pad_rows(seq, b, len(nodes))
    pos, _ = pad_rows(seq, np.arange(len(seq)), len(nodes))
    features = np.where((pos >= 0)[..., None], flat[np.maximum(pos, 0)], np.float32(0.0))
    return Sequences(nodes=nodes, beacons=padded, lengths=lengths, features=features)
