"""What both localizers derive from a beacon log before estimating anything.

:func:`prepare` builds an :class:`Episode`: the episode's config, the hop counts of every
virtual anchor (:mod:`~aoass_env.localization.hops`) and the HopSize of every beacon (Eq. 11),
both computed on first use (only DV-Hop reads them), and which nodes are covered under Eq. 18.
Coverage is recomputed by replaying the receptions through :class:`aoass_env.network.Network`,
the same incremental criterion the simulator applies, so a log and its episode always agree on
it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from aoass_env.beacon_log import BeaconLog, BeaconLogError
from aoass_env.config import AOASSConfig, ConfigError
from aoass_env.localization.hops import (
    DEFAULT_FLOOD_LIMIT,
    HopCounts,
    check_flood_limit,
    hop_counts,
    hop_size,
    require_beacons,
)
from aoass_env.network import Network
from aoass_env.radio import LineOfSight

__all__ = ["Episode", "covered_nodes", "log_config", "prepare"]


@dataclass(frozen=True)
class Episode:
    """A beacon log with the quantities both localizers share.

    Attributes:
        log: the validated beacon log.
        config: the episode's configuration (from the log's ``config_json``).
        covered: (N,) nodes that heard >= 3 non-collinear beacons (Eq. 18).
        heard_centroid: (N, 2) mean position of each node's heard beacons [m] (NaN: none).
        flood_limit: hop-count flooding limit [hops] of :attr:`hops`.
        line_of_sight: exact line-of-sight test against the log's obstacles.
    """

    log: BeaconLog
    config: AOASSConfig
    covered: np.ndarray
    heard_centroid: np.ndarray
    flood_limit: int = DEFAULT_FLOOD_LIMIT
    line_of_sight: LineOfSight = dataclasses.field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "line_of_sight", LineOfSight(self.log.obstacle_map))

    # hop counts only DV-Hop reads: computed on first use (the consensus never floods)
    @cached_property
    def hops(self) -> HopCounts:
        """Hop counts from every beacon (virtual anchor), up to :attr:`flood_limit` hops."""
        return hop_counts(self.log, self.flood_limit)

    @cached_property
    def hop_size(self) -> np.ndarray:
        """(B,) HopSize of each beacon, Eq. 11 [m]."""
        return hop_size(self.beacon_xy, self.hops.beacon_beacon)

    @property
    def beacon_xy(self) -> np.ndarray:
        """(B, 2) beacon positions [m]."""
        return self.log.beacons[:, 1:]

    @property
    def field(self) -> tuple[float, float]:
        """Field width and height [m]."""
        return float(self.log.field[0]), float(self.log.field[1])


def log_config(log: BeaconLog) -> AOASSConfig:
    """The :class:`AOASSConfig` recorded in ``log.config_json`` (``{"config": {...}, ...}``).

    A log without a ``config`` object (written by another tool) gets the default config with the
    log's radio range.

    Raises:
        BeaconLogError: the recorded config is not a valid :class:`AOASSConfig`.
    """
    recorded = log.config.get("config")
    if recorded is None:
        return AOASSConfig(radio_range=log.radio_range)
    if not isinstance(recorded, dict):
        raise BeaconLogError("'config' must be a JSON object of AOASSConfig fields",
                             "config_json")
    try:
        return AOASSConfig.from_kwargs(**recorded)
    except (ConfigError, TypeError) as exc:
        raise BeaconLogError(f"'config' is not a valid AOASSConfig: {exc}",
                             "config_json") from None


def covered_nodes(log: BeaconLog, config: AOASSConfig) -> np.ndarray:
    """(N,) bool: Eq. 18 coverage, replaying the log's receptions through a :class:`Network`
    (a log holds each (beacon, node) once: :class:`~aoass_env.beacon_log.BeaconLog`)."""
    network = Network(log.n_nodes, config)
    rec = log.receptions[np.lexsort((log.receptions[:, 1], log.receptions[:, 0]))]
    bounds = np.searchsorted(rec[:, 0], np.arange(log.n_beacons + 1))
    xy = log.beacons[:, 1:]
    for b in np.flatnonzero(np.diff(bounds)):
        network.record_beacon(xy[b], rec[bounds[b]:bounds[b + 1], 1])
    return np.array(network.covered)


def prepare(log: BeaconLog, flood_limit: int = DEFAULT_FLOOD_LIMIT) -> Episode:
    """Hop counts, HopSizes (Eq. 11), coverage (Eq. 18) and heard centroids of ``log``.

    Raises:
        BeaconLogError: the log holds no beacons or no nodes, or its config or receptions are
            invalid.
    """
    require_beacons(log)
    if log.n_nodes == 0:
        raise BeaconLogError("the log holds no nodes: nothing to localize", "nodes")
    check_flood_limit(flood_limit)
    config = log_config(log)
    xy = log.beacons[:, 1:]
    heard_count = np.bincount(log.receptions[:, 1], minlength=log.n_nodes)
    sums = np.stack([np.bincount(log.receptions[:, 1], weights=xy[log.receptions[:, 0], i],
                                 minlength=log.n_nodes) for i in range(2)], axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        centroid = sums / heard_count[:, None]
    return Episode(log=log, config=config, covered=covered_nodes(log, config),
                   heard_centroid=centroid, flood_limit=int(flood_limit))
