"""The zero action's episodes on a registered id: decisions, Eq. 14 return and coverage.

    python3 scripts/zero_action_returns.py [--env AOASS-Quick-v0] [--seeds 100 101 102]

The zero action (on the residual ids: the spiral the follower drives, unchanged) is the
reference a learned policy's returns are compared with on the same episodes (docs/env.md quotes
this table for ``AOASS-Quick-v0``, seeds 100-102). One episode per seed, ``reset(seed=seed)``
on a fresh env.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

import gymnasium as gym
import numpy as np

from aoass_env.registration import ENV_IDS


def zero_action_episode(env_id: str, seed: int) -> tuple[int, float, float]:
    """One zero-action episode of ``env_id`` from ``reset(seed=seed)``: decisions, return
    (Eq. 14, summed) and final coverage (Eq. 18)."""
    env = gym.make(env_id)
    try:
        env.reset(seed=seed)
        zero = np.zeros(env.action_space.shape, env.action_space.dtype)
        decisions, total = 0, 0.0
        while True:
            _, reward, terminated, truncated, info = env.step(zero)
            decisions, total = decisions + 1, total + float(reward)
            if terminated or truncated:
                return decisions, total, float(info["coverage"])
    finally:
        env.close()


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--env", default="AOASS-Quick-v0", help="a registered id")
    parser.add_argument("--seeds", type=int, nargs="+", default=[100, 101, 102],
                        help="one episode per seed")
    args = parser.parse_args(argv)
    if args.env not in ENV_IDS:
        parser.error(f"--env {args.env!r}: not a registered id; valid: {', '.join(ENV_IDS)}")
    if min(args.seeds) < 0:
        parser.error(f"--seeds {min(args.seeds)}: seeds are integers >= 0")
    print(f"zero action on {args.env}")
    print("| seed | decisions | return | coverage |\n|---|---|---|---|")
    for seed in args.seeds:
        decisions, total, coverage = zero_action_episode(args.env, seed)
        print(f"| {seed} | {decisions} | {total:.1f} | {coverage:.3f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
