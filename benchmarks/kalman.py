"""Speed of the moving-obstacle tracker (aoass_env.safety.kalman), one env step at a time.

Setup: ``--targets`` (3) env-like targets (0.3-1 m/s, a new random heading about every 10 s,
dt = 0.5 s), detections with the env's noise (0.3 m, 0.2 m/s) generated beforehand. Prints
microseconds per :meth:`MultiTargetTracker.step` (best of three passes of ``--steps`` steps,
tracks confirmed before timing) for position-only and position+velocity detections, and per
:meth:`predict_positions` call. Figures only, no targets enforced.

Run: ``python3 benchmarks/kalman.py [--targets 3] [--steps 2000] [--seed 0]``.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from aoass_env.safety.kalman import MultiTargetTracker
from aoass_env.validators import argparse_number

DT, SIGMA_P, SIGMA_V = 0.5, 0.3, 0.2


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


def per_step_us(frames: np.ndarray, velocity_noise: float | None) -> tuple[float, int]:
    """Best-of-three microseconds per step, and the confirmed tracks at the end."""
    best, confirmed = math.inf, 0
    for _ in range(3):
        tr = MultiTargetTracker(DT, position_noise=SIGMA_P, velocity_noise=velocity_noise)
        for z in frames[:5]:                      # warm-up: births and confirmations
            tr.step(z)
        t0 = time.perf_counter()
        for z in frames[5:]:
            tr.step(z)
        best = min(best, (time.perf_counter() - t0) / (len(frames) - 5))
        confirmed = len(tr.confirmed)
    return best * 1e6, confirmed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--targets", type=argparse_number(int, 1), default=3)
    parser.add_argument("--steps", type=argparse_number(int, 1), default=2000)
    parser.add_argument("--seed", type=argparse_number(int, 0), default=0)
    args = parser.parse_args()
    frames = detections(args.targets, args.steps + 5, np.random.default_rng(args.seed))
    for label, vn, cols in (("positions [x, y]", None, 2),
                            ("positions + velocities", SIGMA_V, 4)):
        us, n = per_step_us(np.ascontiguousarray(frames[..., :cols]), vn)
        print(f"step, {args.targets} targets, {label:<24}: {us:7.1f} us  "
              f"({n} confirmed tracks at the end)")
    tr = MultiTargetTracker(DT, position_noise=SIGMA_P, velocity_noise=None)
    for z in frames[:5, :, :2]:
        tr.step(z)
    n = 20000
    t0 = time.perf_counter()
    for _ in range(n):
        tr.predict_positions(1.5)
    print(f"predict_positions(1.5 s), {len(tr.confirmed)} tracks        : "
          f"{(time.perf_counter() - t0) / n * 1e6:7.1f} us")


if __name__ == "__main__":
    main()
