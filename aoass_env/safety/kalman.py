"""Constant-velocity multi-target tracker for the moving obstacles (filterpy Kalman filters).

Each track is a :class:`filterpy.kalman.KalmanFilter` on the state ``[x, y, vx, vy]`` (m, m/s,
world frame) with the constant-velocity (CV) model

    x_{k+1} = F x_k + w_k,   F = [[I, dt I], [0, I]],

where ``w_k`` is the discrete white-noise acceleration of std ``process_noise`` (m/s^2)
(:func:`filterpy.common.Q_discrete_white_noise`, the same block for x and y). Detections are
positions ``[x, y]`` (``velocity_noise=None``) or positions and velocities ``[x, y, vx, vy]``,
with independent Gaussian noise of std ``position_noise`` (m) and ``velocity_noise`` (m/s).

One :meth:`MultiTargetTracker.step` per control period ``dt`` (s):

1. **predict** every track by ``dt``;
2. **gate**: a detection z may feed a track when the squared Mahalanobis distance of its
   innovation, ``y' S^-1 y`` with ``S = H P H' + R``, is at most the ``gate`` quantile of the
   chi-square law with ``len(z)`` degrees of freedom;
3. **associate** (global nearest neighbour) in three stages, each on the detections the
   earlier ones left: (a) confirmed tracks; (b) *maneuver stage*: the confirmed tracks still
   without a detection, gated with the covariance of a *maneuver model*; (c) tentative tracks.
   In each stage, an optimal assignment (:func:`scipy.optimize.linear_sum_assignment`) pairs
   as many tracks and detections inside each other's gate as possible, at the least summed
   squared Mahalanobis distance. Tentative tracks come last because their wide covariance
   gives small Mahalanobis distances that would otherwise steal detections from established
   tracks. Where a stage has one track or one detection (the usual case), the distances are
   computed compiled (by Cholesky) and the pair is the gated one of least distance, what the
   assignment gives there; within a relative 1e-6 of the gate or of a tie, NumPy's inverse and
   the assignment decide, so the pairs are theirs;
4. **update** the associated tracks (hit), count a miss on the others;
5. **manage**: a track is confirmed after ``birth_hits`` hits (its birth counts as one); a
   tentative track is deleted at its first miss, a confirmed one after ``max_misses``
   consecutive misses (it coasts on its prediction until then); every detection left over
   starts a tentative track at the measured position, with the measured velocity when
   detections carry one, else 0 m/s with std ``initial_speed_std`` (m/s) per axis.

Maneuvers. The env's moving obstacles pick a new heading at random instants and bounce off
walls: their velocity jumps, which a CV model with a small ``process_noise`` (smooth velocity
estimates on straight runs) cannot follow: the detection after a U-turn falls outside the
gate and the track is lost. The maneuver model adds to the predicted covariance
``dQ = maneuver_speed^2 [[dt^2/3 I, dt/2 I], [dt/2 I, I]]``: a velocity jump of std
``maneuver_speed`` (m/s) at a uniformly random instant of the period (dp = dv * tau,
tau ~ U(0, dt)). A track paired in stage (b) is updated with the covariance ``P + alpha dQ``,
where alpha in [0, 1] is the smallest inflation that brings the detection onto the gate
boundary (bisection on the generalised eigenvalues of (dQ, S)): a detection just outside the
nominal gate (1 - ``gate`` of the ordinary noise draws) barely inflates it, a real maneuver
inflates it enough for the track to re-converge to the new velocity in a few periods.
``maneuver_speed=None`` turns stage (b) off.

Track ids are consecutive integers from 0 in order of birth (reset by :meth:`reset`); the
tracker has no randomness, so the same detections give the same tracks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from filterpy.common import Q_discrete_white_noise
from filterpy.kalman import KalmanFilter
from numpy.typing import ArrayLike
from scipy.optimize import linear_sum_assignment
from scipy.stats import chi2

from aoass_env.jit import njit
from aoass_env.validators import integer, positive, real

__all__ = ["MultiTargetTracker", "Track"]

#: relative band (of the gate's d2) within which the compiled distances of
#: :func:`_gate_distances` leave a decision to NumPy's: a d2 this close to the gate, or two
#: gated d2 this close to each other. Both computations are backward stable (relative errors
#: of a few cond(S) x 1e-16; S >= R, so cond(S) stays far below the 1e10 that would make the
#: two differ by the band), so outside the band they decide alike
_DECISION_BAND = 1e-6


@njit
def _gate_distances(x: np.ndarray, p: np.ndarray, r: np.ndarray, extra: np.ndarray,
                    z: np.ndarray, cols: np.ndarray, out: np.ndarray) -> bool:
    """Squared Mahalanobis distances ``y' S^-1 y`` of one track (state ``x`` (4, 1),
    covariance ``p`` (4, 4)) to the detections ``z[cols]`` into ``out`` (len(cols),), with
    ``S = p[:dz, :dz] + r (+ extra[:dz, :dz] when extra is (4, 4))`` and ``dz = len(r)``:
    by Cholesky, not NumPy's inverse, so the last bits differ (see :data:`_DECISION_BAND`).
    False when S is not positive definite (NumPy's path decides then)."""
    dz = r.shape[0]
    low = np.zeros((dz, dz))
    for j in range(dz):
        for i in range(j, dz):
            acc = p[i, j] + r[i, j]
            if extra.shape[0] == 4:
                acc += extra[i, j]
            for k in range(j):
                acc -= low[i, k] * low[j, k]
            if i == j:
                if not acc > 0.0:
                    return False
                low[j, j] = math.sqrt(acc)
            else:
                low[i, j] = acc / low[j, j]
    w = np.empty(dz)
    for c in range(cols.shape[0]):
        d2 = 0.0
        for i in range(dz):
            acc = z[cols[c], i] - x[i, 0]
            for k in range(i):
                acc -= low[i, k] * w[k]
            w[i] = acc / low[i, i]
            d2 += w[i] * w[i]
        out[c] = d2
    return True


@njit
def _nearest_pairs(d2: np.ndarray, gate: float, band: float) -> np.ndarray:
    """The gated global-nearest-neighbour pairs of a cost matrix ``d2`` (m, n) with m == 1 or
    n == 1, where the pairing is the gated entry of least d2 (what
    :func:`scipy.optimize.linear_sum_assignment` gives such a matrix): [[i, j]], or no row
    when no entry is gated; None (NumPy's path decides) when an entry lies within ``band`` x
    ``gate`` of the gate, or the two least gated entries within it of each other."""
    tol = band * gate
    best, second = np.inf, np.inf
    bi, bj = -1, -1
    for i in range(d2.shape[0]):
        for j in range(d2.shape[1]):
            v = d2[i, j]
            if not abs(v - gate) > tol:      # NaN too
                return None
            if v < gate:
                if v < best:
                    second, best, bi, bj = best, v, i, j
                elif v < second:
                    second = v
    if bi < 0:
        return np.empty((0, 2), np.int64)
    if not second - best > tol:
        return None
    out = np.empty((1, 2), np.int64)
    out[0, 0], out[0, 1] = bi, bj
    return out


@dataclass(eq=False)
class Track:
    """One tracked target.

    Attributes:
        id: unique id, consecutive from 0 in order of birth.
        filter: its Kalman filter; ``filter.x`` is the (4, 1) state ``[x, y, vx, vy]``
            (m, m/s, world frame), ``filter.P`` the (4, 4) covariance.
        hits: number of updates with a detection, birth included.
        misses: consecutive steps without a detection.
        confirmed: whether ``hits`` has reached the tracker's ``birth_hits``.
    """

    id: int
    filter: KalmanFilter
    hits: int
    misses: int
    confirmed: bool

    @property
    def state(self) -> np.ndarray:
        """Estimated ``[x, y, vx, vy]`` (m, m/s), shape (4,), a copy."""
        return self.filter.x[:, 0].copy()

    @property
    def covariance(self) -> np.ndarray:
        """Covariance of :attr:`state`, shape (4, 4) (m^2, m^2/s, m^2/s^2), a copy."""
        return self.filter.P.copy()


class MultiTargetTracker:
    """Kalman tracking of several targets under a constant-velocity model.

    Args:
        dt: time between two :meth:`step` calls (s), > 0.
        position_noise: std of the measured positions (m), > 0.
        velocity_noise: std of the measured velocities (m/s), > 0; None when detections carry
            positions only.
        process_noise: std of the white acceleration of the CV model (m/s^2), > 0.
        gate: probability mass of the chi-square validation gate, in (0, 1).
        birth_hits: hits (birth included) before a track is confirmed, >= 1.
        max_misses: consecutive misses that delete a confirmed track, >= 1.
        initial_speed_std: std per axis of the velocity of a track born from a position-only
            detection (m/s), > 0; unused when detections carry velocities.
        maneuver_speed: std of the sudden velocity change of the maneuver model (m/s), > 0;
            about the largest speed change of a target within one period (2.0: a U-turn at
            the env's default top speed of 1 m/s); None disables the maneuver stage (see the
            module docstring).
    """

    def __init__(self, dt: float, *, position_noise: float, velocity_noise: float | None,
                 process_noise: float = 0.5, gate: float = 0.99, birth_hits: int = 2,
                 max_misses: int = 3, initial_speed_std: float = 2.0,
                 maneuver_speed: float | None = 2.0) -> None:
        self.dt = positive("dt", dt, "s")
        self.position_noise = positive("position_noise", position_noise, "m")
        self.velocity_noise = (None if velocity_noise is None
                               else positive("velocity_noise", velocity_noise, "m/s"))
        self.process_noise = positive("process_noise", process_noise, "m/s^2")
        self.initial_speed_std = positive("initial_speed_std", initial_speed_std, "m/s")
        self.maneuver_speed = (None if maneuver_speed is None
                               else positive("maneuver_speed", maneuver_speed, "m/s"))
        self.gate = gate = real("gate", gate, "probability", low=0.0, high=1.0, low_open=True,
                                high_open=True)
        self.birth_hits = integer("birth_hits", birth_hits, "hits", low=1)
        self.max_misses = integer("max_misses", max_misses, "misses", low=1)

        dz = 2 if self.velocity_noise is None else 4
        self._dz = dz
        self._gate_d2 = float(chi2.ppf(gate, dz))
        # Model matrices, shared read-only by every track's filter (filterpy only reads them).
        f = np.eye(4)
        f[0, 2] = f[1, 3] = self.dt
        q = Q_discrete_white_noise(dim=2, dt=self.dt, var=self.process_noise ** 2,
                                   block_size=2, order_by_dim=False)
        h = np.eye(dz, 4)
        r_diag = [self.position_noise ** 2] * 2
        if dz == 4:
            r_diag += [self.velocity_noise ** 2] * 2
        r = np.diag(r_diag)
        p0 = np.diag([self.position_noise ** 2] * 2 + (
            [self.velocity_noise ** 2] * 2 if dz == 4 else [self.initial_speed_std ** 2] * 2))
        # Extra covariance of the maneuver model: a velocity jump of std maneuver_speed at a
        # uniformly random instant of the period (dp = dv * tau, tau ~ U(0, dt)).
        dq = None
        if self.maneuver_speed is not None:
            t = self.dt
            dq = self.maneuver_speed ** 2 * np.kron([[t * t / 3, t / 2], [t / 2, 1.0]], np.eye(2))
        for a in (f, q, h, r, p0) + (() if dq is None else (dq,)):
            a.setflags(write=False)
        self._F, self._Q, self._H, self._R, self._P0, self._dQ = f, q, h, r, p0, dq
        self._no_extra = np.zeros((0, 0))    # _gate_distances' "no extra covariance"
        self._tracks: list[Track] = []
        self._next_id = 0

    def reset(self) -> None:
        """Forget every track; ids start again from 0."""
        self._tracks = []
        self._next_id = 0

    # ---------------------------------------------------------------------------- queries
    @property
    def tracks(self) -> list[Track]:
        """All live tracks, tentative and confirmed, in order of birth (a new list)."""
        return list(self._tracks)

    @property
    def n_tracks(self) -> int:
        """How many tracks are live, tentative and confirmed."""
        return len(self._tracks)

    @property
    def confirmed(self) -> list[Track]:
        """The confirmed tracks, in order of birth; rows of :meth:`states` follow this order."""
        return [t for t in self._tracks if t.confirmed]

    def _selected(self, confirmed_only: bool) -> list[Track]:
        return self.confirmed if confirmed_only else self._tracks

    def states(self, confirmed_only: bool = True) -> np.ndarray:
        """Estimated ``[x, y, vx, vy]`` (m, m/s) of the confirmed (or all) tracks, shape (m, 4),
        rows in the order of :attr:`confirmed` (or :attr:`tracks`)."""
        sel = self._selected(confirmed_only)
        if not sel:
            return np.zeros((0, 4))
        return np.array([t.filter.x[:, 0] for t in sel])     # np.stack's array, faster

    def covariances(self, confirmed_only: bool = True) -> np.ndarray:
        """Covariances of :meth:`states` (m^2, m^2/s, m^2/s^2), shape (m, 4, 4), rows in the
        same order; a copy."""
        sel = self._selected(confirmed_only)
        if not sel:
            return np.zeros((0, 4, 4))
        return np.array([t.filter.P for t in sel])

    def position_covariances(self, confirmed_only: bool = True) -> np.ndarray:
        """Covariances of the estimated positions (m^2), shape (m, 2, 2), rows as in
        :meth:`states`; a copy."""
        return self.covariances(confirmed_only)[:, :2, :2].copy()

    def predict_positions(self, horizon: float, confirmed_only: bool = True) -> np.ndarray:
        """Positions (m) ``horizon`` seconds ahead under the CV model, shape (m, 2).

        ``x + v * horizon`` for each track: the same as applying F ``k`` times when
        ``horizon = k * dt``, and exact under the model for any other horizon >= 0. The
        tracks are not changed.
        """
        horizon = real("horizon", horizon, "s", low=0.0)
        s = self.states(confirmed_only)
        return s[:, :2] + horizon * s[:, 2:]

    def predict_steps(self, k: int, confirmed_only: bool = True) -> np.ndarray:
        """Positions (m) ``k`` control periods ahead: ``predict_positions(k * dt)``, (m, 2)."""
        return self.predict_positions(integer("k", k, "steps", low=0) * self.dt, confirmed_only)

    # ------------------------------------------------------------------------------ step
    def _detections(self, detections: ArrayLike) -> np.ndarray:
        try:
            z = np.asarray(detections, dtype=float)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"detections must be a numeric array: {exc}") from None
        if z.size == 0:
            return np.zeros((0, self._dz))
        if z.ndim != 2 or z.shape[1] != self._dz:
            what = "[x, y]" if self._dz == 2 else "[x, y, vx, vy]"
            raise ValueError(f"detections of shape {z.shape} must be (n, {self._dz}) rows "
                             f"{what} (velocity_noise={self.velocity_noise})")
        if not np.isfinite(z).all():
            raise ValueError("detections must be finite (no NaN or inf)")
        return z

    def _associate(self, tracks: list[Track], z: np.ndarray, free: np.ndarray,
                   pairs: list[tuple[Track, int]], extra: np.ndarray | None = None
                   ) -> list[Track]:
        """Gated global-nearest-neighbour pairs of ``tracks`` and the free detections; appends
        to ``pairs``, marks used detections in ``free``, returns the tracks left unpaired.
        ``extra`` (4, 4) is added to every track's predicted covariance for the gate."""
        cols = np.flatnonzero(free)
        if not tracks or cols.size == 0:
            return tracks
        if len(tracks) == 1 or cols.size == 1:   # the usual case: one track or one detection
            found = self._nearest(tracks, z, cols, extra)
            if found is not None:
                rows_left = [True] * len(tracks)
                for i, j in found.tolist():
                    rows_left[i] = False
                    free[cols[j]] = False
                    pairs.append((tracks[i], int(cols[j])))
                return [t for t, left in zip(tracks, rows_left, strict=True) if left]
        dz = self._dz
        x = np.array([t.filter.x[:dz, 0] for t in tracks])              # H x, (m, dz)
        s = np.array([t.filter.P[:dz, :dz] for t in tracks]) + self._R   # H P H' + R
        if extra is not None:
            s += extra[:dz, :dz]
        y = z[cols][None, :, :] - x[:, None, :]                            # (m, n, dz)
        d2 = ((y @ np.linalg.inv(s)) * y).sum(axis=2)                     # y' S^-1 y (S sym.)
        inside = d2 <= self._gate_d2
        if not inside.any():
            return tracks
        # Out-of-gate pairs cost more than any set of gated ones: the assignment first pairs as
        # many gated pairs as possible, then minimises their summed d2; out-of-gate pairs are
        # dropped afterwards.
        big = 1.0 + len(tracks) * self._gate_d2
        rows, js = linear_sum_assignment(np.where(inside, d2, big))
        rows_left = np.ones(len(tracks), bool)
        for i, j in zip(rows.tolist(), js.tolist(), strict=True):
            if inside[i, j]:
                rows_left[i] = False
                free[cols[j]] = False
                pairs.append((tracks[i], int(cols[j])))
        return [t for t, left in zip(tracks, rows_left, strict=True) if left]

    def _nearest(self, tracks: list[Track], z: np.ndarray, cols: np.ndarray,
                 extra: np.ndarray | None) -> np.ndarray | None:
        """:meth:`_associate`'s pairs [[track row, column of ``cols``]] where one track or one
        detection is free, from compiled distances (:func:`_gate_distances`); None where
        they leave the decision to NumPy (:func:`_nearest_pairs`)."""
        d2 = np.empty((len(tracks), cols.size))
        extra = self._no_extra if extra is None else extra
        for i, t in enumerate(tracks):
            if not _gate_distances(t.filter.x, t.filter.P, self._R, extra, z, cols, d2[i]):
                return None
        return _nearest_pairs(d2, self._gate_d2, _DECISION_BAND)

    def _inflation(self, track: Track, z: np.ndarray) -> float:
        """Smallest alpha in [0, 1] that puts ``z`` inside the gate computed with the predicted
        covariance ``P + alpha * dQ``: 0 when it is already inside, else the alpha of the gate
        boundary, by bisection on d2(alpha) = sum u_i^2 / (1 + alpha lam_i), decreasing."""
        dz = self._dz
        s = track.filter.P[:dz, :dz] + self._R
        lam, v = scipy.linalg.eigh(self._dQ[:dz, :dz], s)    # v' s v = I, v' dQ v = diag(lam)
        u2 = np.square(v.T @ (z - track.filter.x[:dz, 0]))
        target = self._gate_d2
        if u2.sum() <= target:
            return 0.0
        lo, hi = 0.0, 1.0
        for _ in range(30):
            mid = 0.5 * (lo + hi)
            if (u2 / (1.0 + mid * lam)).sum() > target:
                lo = mid
            else:
                hi = mid
        return hi

    def step(self, detections: ArrayLike) -> None:
        """Advance every track by ``dt`` and fuse this period's detections.

        Args:
            detections: (n, 2) positions ``[x, y]`` (m) when ``velocity_noise`` is None, else
                (n, 4) ``[x, y, vx, vy]`` (m, m/s), world frame; n may be 0 (an empty list
                is accepted).

        Raises:
            ValueError: wrong shape or non-finite values in ``detections``.
        """
        z = self._detections(detections)
        if not self._tracks and len(z) == 0:
            return                  # nothing to predict, associate or start (the steps below)
        for t in self._tracks:
            t.filter.predict()
        free = np.ones(len(z), bool)
        pairs: list[tuple[Track, int]] = []
        unpaired = self._associate([t for t in self._tracks if t.confirmed], z, free, pairs)
        maneuvers: list[tuple[Track, int]] = []
        if self._dQ is not None and unpaired:
            unpaired = self._associate(unpaired, z, free, maneuvers, self._dQ)
            for t, j in maneuvers:
                t.filter.P = t.filter.P + self._inflation(t, z[j]) * self._dQ
        unpaired += self._associate([t for t in self._tracks if not t.confirmed], z, free, pairs)
        for t, j in pairs + maneuvers:
            t.filter.update(z[j])
            t.hits += 1
            t.misses = 0
            if t.hits >= self.birth_hits:
                t.confirmed = True
        dead = set()
        for t in unpaired:
            t.misses += 1
            if not t.confirmed or t.misses >= self.max_misses:
                dead.add(t.id)
        if dead:
            self._tracks = [t for t in self._tracks if t.id not in dead]
        for j in np.flatnonzero(free):
            self._tracks.append(self._birth(z[j]))

    def _birth(self, z: np.ndarray) -> Track:
        kf = KalmanFilter(dim_x=4, dim_z=self._dz)
        kf.F, kf.Q, kf.H, kf.R = self._F, self._Q, self._H, self._R
        kf.x = np.zeros((4, 1))
        kf.x[:self._dz, 0] = z
        kf.P = self._P0.copy()
        track = Track(id=self._next_id, filter=kf, hits=1, misses=0,
                      confirmed=self.birth_hits <= 1)
        self._next_id += 1
        return track
