"""Speed of the moving-obstacle tracker (aoass_env.safety.kalman), one env step at a time.

Setup: ``--targets`` (3) env-like targets (0.3-1 m/s, a new random heading about every 10 s,
dt = 0.5 s), detections with the env's noise (0.3 m, 0.2 m/s) generated beforehand, one per
target per step, in the targets' order. Prints microseconds per
:meth:`MultiTargetTracker.step` (best of three passes of ``--steps`` steps, tracks confirmed
before timing) for position-only and position+velocity detections, and per
:meth:`predict_positions` call. No targets enforced.

Reference, in the same process and timed the same way on the same detections: one filterpy
``KalmanFilter`` per target with the tracker's model (constant velocity, the same dt, process
noise 0.5 m/s^2, measurement noises and initial covariance), born at the target's first
detection; a step is ``predict()`` then ``update(z)`` of every filter with its own target's
detection. That is the per-target filtering the tracker does, with the association given:
the ratio (tracker / reference) is what the tracker's gating, association (Mahalanobis
distances, the maneuver stage) and track management cost on top of filterpy's filters. A
prediction's reference is the same filters' states carried ``HORIZON`` ahead, ``F(h) x`` per
filter (:meth:`KnownAssociation.predict_positions`): the tracker's vectorised call against one
product per target.

Run: ``python3 benchmarks/kalman.py [--targets 3] [--steps 2000] [--seed 0]``.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable
from functools import partial

import numpy as np
from filterpy.common import Q_discrete_white_noise
from filterpy.kalman import KalmanFilter

from aoass_env.safety.kalman import MultiTargetTracker
from aoass_env.validators import argparse_number

#: control period (s), detection noises (m, m/s), the CV model's white acceleration (m/s^2)
DT, SIGMA_P, SIGMA_V, SIGMA_A = 0.5, 0.3, 0.2, 0.5
#: speed std per axis of a track born from a position (m/s)
BIRTH_SPEED_STD = 2.0
#: steps before the timed ones (births and confirmations)
WARM_UP = 5
#: look-ahead (s) of the timed predictions
HORIZON = 1.5


class KnownAssociation:
    """The reference: a filterpy ``KalmanFilter`` per target under the tracker's CV model,
    born at the first detections; :meth:`step` predicts every filter by ``DT`` and updates it
    with its own target's detection (row i of the detections is target i's)."""

    def __init__(self, velocity_noise: float | None) -> None:
        self.dz = 2 if velocity_noise is None else 4
        self.F = np.eye(4)
        self.F[0, 2] = self.F[1, 3] = DT
        self.Q = Q_discrete_white_noise(dim=2, dt=DT, var=SIGMA_A ** 2, block_size=2,
                                        order_by_dim=False)
        self.H = np.eye(self.dz, 4)
        noise = [SIGMA_P ** 2] * 2 + ([] if velocity_noise is None else [velocity_noise ** 2] * 2)
        self.R = np.diag(noise)
        self.P0 = np.diag(noise + [BIRTH_SPEED_STD ** 2] * (4 - self.dz))
        self.filters: list[KalmanFilter] = []

    def step(self, detections: np.ndarray) -> None:
        """Births at the first call, then predict and update every filter (m, m/s)."""
        if not self.filters:
            for z in detections:
                kf = KalmanFilter(dim_x=4, dim_z=self.dz)
                kf.F, kf.Q, kf.H, kf.R, kf.P = self.F, self.Q, self.H, self.R, self.P0.copy()
                kf.x = np.zeros((4, 1))
                kf.x[:self.dz, 0] = z
                self.filters.append(kf)
            return
        for kf, z in zip(self.filters, detections, strict=True):
            kf.predict()
            kf.update(z)


    def predict_positions(self, horizon: float) -> np.ndarray:
        """(n, 2) positions (m) ``horizon`` s ahead under the CV model: F(horizon) x of each
        filter, as the tracker's :meth:`~MultiTargetTracker.predict_positions` gives them."""
        f = np.eye(4)
        f[0, 2] = f[1, 3] = horizon
        return np.array([(f @ kf.x)[:2, 0] for kf in self.filters]).reshape(-1, 2)


def detections(n_targets: int, steps: int, rng: np.random.Generator) -> np.ndarray:
    """(steps, n_targets, 4) noisy [x, y, vx, vy] of env-like targets."""
    p = rng.uniform(10, 90, (n_targets, 2))
    speed = rng.uniform(0.3, 1.0, n_targets)
    heading = rng.uniform(0, 2 * math.pi, n_targets)
    out = np.empty((steps, n_targets, 4))
    for k in range(steps):
        turn = rng.random(n_targets) < 0.1 * DT
        heading[turn] = rng.uniform(0, 2 * math.pi, turn.sum())
        v = speed[:, None] * np.column_stack([np.cos(heading), np.sin(heading)])
        p = p + DT * v
        out[k, :, :2] = p + rng.normal(0, SIGMA_P, p.shape)
        out[k, :, 2:] = v + rng.normal(0, SIGMA_V, v.shape)
    return out


def tracker(velocity_noise: float | None) -> MultiTargetTracker:
    """The tracker under test, with the model :class:`KnownAssociation` copies."""
    return MultiTargetTracker(DT, position_noise=SIGMA_P, velocity_noise=velocity_noise,
                              process_noise=SIGMA_A, initial_speed_std=BIRTH_SPEED_STD)


Stepper = MultiTargetTracker | KnownAssociation


def per_step_us(frames: np.ndarray, *makes: Callable[[], Stepper]
                ) -> list[tuple[float, Stepper]]:
    """For each of ``makes``: the best-of-three microseconds per step of a fresh ``make()``
    over ``frames`` after :data:`WARM_UP` untimed steps, and its last pass's stepper. The
    passes take the ``makes`` in turn, so each meets the same drift of a shared machine."""
    best, last = [math.inf] * len(makes), [None] * len(makes)
    for _ in range(3):
        for i, make in enumerate(makes):
            last[i] = stepper = make()
            for z in frames[:WARM_UP]:
                stepper.step(z)
            t0 = time.perf_counter()
            for z in frames[WARM_UP:]:
                stepper.step(z)
            best[i] = min(best[i], (time.perf_counter() - t0) / (len(frames) - WARM_UP))
    return [(b * 1e6, stepper) for b, stepper in zip(best, last, strict=True)]


def per_call_us(calls: tuple[Callable[[], object], ...], n: int = 20_000) -> list[float]:
    """Best-of-three microseconds per call of each of ``calls``, ``n`` calls a pass, the calls
    taking their passes in turn."""
    best = [math.inf] * len(calls)
    for _ in range(3):
        for i, call in enumerate(calls):
            t0 = time.perf_counter()
            for _ in range(n):
                call()
            best[i] = min(best[i], (time.perf_counter() - t0) / n)
    return [b * 1e6 for b in best]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--targets", type=argparse_number(int, 1), default=3)
    parser.add_argument("--steps", type=argparse_number(int, 1), default=2000)
    parser.add_argument("--seed", type=argparse_number(int, 0), default=0)
    args = parser.parse_args(argv)
    frames = detections(args.targets, args.steps + WARM_UP, np.random.default_rng(args.seed))
    for label, vn, cols in (("positions [x, y]", None, 2),
                            ("positions + velocities", SIGMA_V, 4)):
        z = np.ascontiguousarray(frames[..., :cols])
        (us, tr), (ref, _) = per_step_us(z, partial(tracker, vn), partial(KnownAssociation, vn))
        print(f"step, {args.targets} targets, {label:<24}: {us:7.1f} us  "
              f"({len(tr.confirmed)} confirmed tracks at the end); filterpy, association "
              f"given: {ref:7.1f} us; ratio {us / ref:5.2f}")
    tr, ref = tracker(None), KnownAssociation(None)
    for z in frames[:WARM_UP, :, :2]:
        tr.step(z)
        ref.step(z)
    ours, theirs = per_call_us((partial(tr.predict_positions, HORIZON),
                                partial(ref.predict_positions, HORIZON)))
    print(f"predict_positions({HORIZON:g} s), {len(tr.confirmed)} tracks        : "
          f"{ours:7.1f} us; filterpy states, F(h) x each: {theirs:7.1f} us; ratio "
          f"{ours / theirs:5.2f}")


if __name__ == "__main__":
    main()
