"""State of the sensor network during one episode: heard beacons, coverage and energy.

**Coverage (Eq. 18).** A node is covered once it has heard at least three beacons that are not
collinear. For each node the scatter matrix S of its heard beacon positions (about their mean)
is kept; its smallest eigenvalue lambda_min is the sum of squared distances of those positions to
their total-least-squares line. The node is covered when ``n >= 3`` and
``sqrt(lambda_min) >= collinearity_tol`` (1 m by default): the heard positions deviate from every
straight line by at least that root-sum-square distance. Adding a beacon adds the positive
semi-definite term ``n/(n+1) d d^T`` to S (d: offset of the new position from the old mean), so
lambda_min never decreases and a covered node stays covered. S is updated with Welford's
recurrence, which avoids the cancellation of raw sums of squares.

**Energy (Table 1, first-order radio model).** A beacon of ``packet_bits`` bits costs the anchor
``packet_bits * (e_elec + e_amp * R^2)`` to transmit (free-space amplifier at range R) and each
receiving node ``packet_bits * e_elec``; anchor motion costs ``anchor_motion_energy`` J per metre.
The total energy of Eq. 16 is anchor motion + anchor transmissions + all node energy.
"""

from __future__ import annotations

import math

import numpy as np

from aoass_env.config import AOASSConfig
from aoass_env.jit import njit
from aoass_env.validators import finite_array, integer, real

__all__ = ["Network", "lambda_min", "residual_after"]


@njit
def _welford(idx: np.ndarray, x: float, y: float, heard: np.ndarray, mean: np.ndarray,
             scatter: np.ndarray, covered: np.ndarray, min_scatter: float) -> int:
    """Add a beacon at (``x``, ``y``) [m] to the nodes ``idx``: Welford's update of their
    counts, means and scatters in place (module docstring), and the nodes it makes covered
    (n >= 3, :func:`lambda_min` >= ``min_scatter``) marked; returns how many. The operations
    of NumPy's array form, node by node, so the floats are the same."""
    fresh = 0
    for k in range(len(idx)):
        i = idx[k]
        n = heard[i] + 1
        dox = x - mean[i, 0]
        doy = y - mean[i, 1]
        mx = mean[i, 0] + dox / n
        my = mean[i, 1] + doy / n
        dnx = x - mx
        dny = y - my
        scatter[i, 0] += dox * dnx
        scatter[i, 1] += dox * dny
        scatter[i, 2] += doy * dny
        mean[i, 0] = mx
        mean[i, 1] = my
        heard[i] = n
        if not covered[i] and n >= 3:
            sxx, sxy, syy = scatter[i, 0], scatter[i, 1], scatter[i, 2]
            lam = max(0.5 * (sxx + syy) - math.hypot(0.5 * (sxx - syy), sxy), 0.0)
            if lam >= min_scatter:
                covered[i] = True
                fresh += 1
    return fresh


def _read_only(array: np.ndarray) -> np.ndarray:
    view = array.view()
    view.flags.writeable = False
    return view


def lambda_min(scatter: np.ndarray) -> np.ndarray:
    """Smallest eigenvalue [m^2] of symmetric 2x2 matrices given as (K, 3) Sxx, Sxy, Syy (the
    spread of a node's heard beacons, module docstring)."""
    sxx, sxy, syy = scatter[:, 0], scatter[:, 1], scatter[:, 2]
    lam = 0.5 * (sxx + syy) - np.hypot(0.5 * (sxx - syy), sxy)
    return np.maximum(lam, 0.0)


def residual_after(heard: int, mean: np.ndarray, scatter: np.ndarray,
                   points: np.ndarray) -> np.ndarray:
    """Root-sum-square distance [m] (K,) of one node's heard beacons to their best line once a
    beacon at each of ``points`` (K, 2) [m] is added alone: its ``heard`` count, ``mean`` (2,)
    [m] and ``scatter`` (3,) Sxx, Sxy, Syy [m^2] grown by Welford's term n/(n+1) d d^T."""
    heard = integer("heard", heard, "beacons", low=0)
    d = finite_array("points", points, "m", shape=(None, 2)) - mean
    w = heard / (heard + 1.0)
    grown = np.asarray(scatter, dtype=np.float64) + w * np.stack(
        [d[:, 0] * d[:, 0], d[:, 0] * d[:, 1], d[:, 1] * d[:, 1]], axis=1)
    return np.sqrt(lambda_min(grown))


class Network:
    """Heard beacons, coverage and energy ledger of ``n_nodes`` static nodes in one episode.

    Args:
        n_nodes: number of nodes (>= 1).
        config: supplies ``collinearity_tol`` [m], ``radio_range`` [m], ``packet_bits``,
            ``e_elec`` [J/bit], ``e_amp`` [J/bit/m^2], ``node_initial_energy`` [J] and
            ``anchor_motion_energy`` [J/m].
    """

    def __init__(self, n_nodes: int, config: AOASSConfig) -> None:
        n = integer("n_nodes", n_nodes, "nodes", low=1)
        if not isinstance(config, AOASSConfig):
            raise TypeError(f"config must be an AOASSConfig, got {type(config)!r}")
        self.config = config
        self.n_nodes = n
        self._min_scatter = config.collinearity_tol ** 2
        self._heard = np.zeros(n, dtype=np.int64)
        self._mean = np.zeros((n, 2))
        self._scatter = np.zeros((n, 3))  # Sxx, Sxy, Syy about the mean [m^2]
        self._covered = np.zeros(n, dtype=bool)
        self._n_covered = 0
        self._beacons_sent = 0
        self._receptions = 0
        self._distance = 0.0

    # --- energy figures per event -------------------------------------------------------
    @property
    def tx_energy_per_beacon(self) -> float:
        """Anchor energy to transmit one beacon [J]: packet_bits (e_elec + e_amp R^2)."""
        c = self.config
        return c.packet_bits * (c.e_elec + c.e_amp * c.radio_range ** 2)

    @property
    def rx_energy_per_beacon(self) -> float:
        """Node energy to receive one beacon [J]: packet_bits e_elec."""
        return self.config.packet_bits * self.config.e_elec

    # --- updates --------------------------------------------------------------------------
    def record_beacon(self, position: np.ndarray, receivers: np.ndarray) -> int:
        """Account one beacon broadcast at ``position`` (2,) [m] and heard by ``receivers``.

        ``receivers`` are strictly increasing node indices (as :meth:`Radio.receivers` gives).
        Returns the number of nodes that became covered.
        """
        p = np.asarray(position, dtype=np.float64)
        if p.shape != (2,) or not (math.isfinite(p[0]) and math.isfinite(p[1])):
            raise ValueError(f"position must be a finite (2,) point in metres, got {position!r}")
        idx = np.asarray(receivers)
        if idx.ndim != 1 or (idx.size and idx.dtype.kind not in "iu"):
            raise ValueError(f"receivers must be a 1-D integer array, got shape {idx.shape} "
                             f"dtype {idx.dtype}")
        idx = idx.astype(np.int64, copy=False)
        if idx.size and (idx[0] < 0 or idx[-1] >= self.n_nodes
                         or (idx[1:] <= idx[:-1]).any()):
            raise ValueError(f"receivers must be strictly increasing node indices in "
                             f"[0, {self.n_nodes}), got {receivers!r}")
        self._beacons_sent += 1
        if idx.size == 0:
            return 0
        self._receptions += idx.size
        fresh = _welford(idx, float(p[0]), float(p[1]), self._heard, self._mean,
                         self._scatter, self._covered, self._min_scatter)
        self._n_covered += fresh
        return fresh

    def charge_motion(self, distance: float) -> None:
        """Account ``distance`` [m] >= 0 travelled by the anchor."""
        if type(distance) is float and 0.0 <= distance < math.inf:   # the common case
            self._distance += distance
        else:
            self._distance += real("distance", distance, "m", low=0.0)

    # --- coverage -------------------------------------------------------------------------
    @property
    def heard(self) -> np.ndarray:
        """Beacons heard by each node (N,) int64 (read-only)."""
        return _read_only(self._heard)

    @property
    def covered(self) -> np.ndarray:
        """Nodes meeting Eq. 18 (N,) bool (read-only)."""
        return _read_only(self._covered)

    @property
    def beacon_centroid(self) -> np.ndarray:
        """Mean position [m] (N, 2) of the beacons each node heard (0 for nodes that heard
        none); read-only. The environment's cheap online position estimate."""
        return _read_only(self._mean)

    @property
    def line_residual(self) -> np.ndarray:
        """Root-sum-square distance [m] (N,) of each node's heard beacons to their best line."""
        return np.sqrt(lambda_min(self._scatter))

    @property
    def scatter(self) -> np.ndarray:
        """(N, 3) Sxx, Sxy, Syy [m^2] of each node's heard beacons about their mean (read-only):
        of every beacon heard, growing after the node is covered (a node stays covered; the
        anchor's coverage map freezes its cells because covered cells stop listening)."""
        return _read_only(self._scatter)

    @property
    def n_covered(self) -> int:
        return self._n_covered

    @property
    def coverage_ratio(self) -> float:
        """Eq. 18: covered nodes / all nodes."""
        return self._n_covered / self.n_nodes

    # --- energy ledger --------------------------------------------------------------------
    @property
    def beacons_sent(self) -> int:
        return self._beacons_sent

    @property
    def receptions(self) -> int:
        """Total number of (beacon, node) receptions."""
        return self._receptions

    @property
    def distance_travelled(self) -> float:
        """Anchor path length charged so far [m]."""
        return self._distance

    @property
    def node_energy(self) -> np.ndarray:
        """Energy spent by each node (N,) [J]."""
        return self._heard * self.rx_energy_per_beacon

    @property
    def node_residual_energy(self) -> np.ndarray:
        """node_initial_energy - node_energy (N,) [J]; depletion is not modelled (2 J lasts
        about 156 000 receptions of 256 bit)."""
        return self.config.node_initial_energy - self.node_energy

    @property
    def anchor_motion_energy_spent(self) -> float:
        """anchor_motion_energy x distance travelled [J]."""
        return self.config.anchor_motion_energy * self._distance

    @property
    def anchor_tx_energy(self) -> float:
        """Energy of all beacon transmissions [J]."""
        return self._beacons_sent * self.tx_energy_per_beacon

    @property
    def anchor_energy(self) -> float:
        """Anchor motion + transmissions [J]."""
        return self.anchor_motion_energy_spent + self.anchor_tx_energy

    @property
    def node_energy_total(self) -> float:
        """Energy spent by all nodes together [J]."""
        return self._receptions * self.rx_energy_per_beacon

    @property
    def energy_total(self) -> float:
        """E_total of Eq. 16: anchor motion + anchor transmissions + all node energy [J]."""
        return self.anchor_energy + self.node_energy_total
