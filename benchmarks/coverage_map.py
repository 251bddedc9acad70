"""Cost of the anchor's own coverage map in an AOASS-v0 step (issue 19 target: the step with it
costs at most 1.2x the step without it), measured in one process.

Both runs play the same seeded episodes of AOASS-v0 with the zero action (the spiral follower),
resets included; the reference run replaces ``CoverageMap.add_beacon`` with a no-op and tests the
links of the nodes' radio alone (the simulator tests both radios' links in one ``receivers_at``
call), so the only difference is the map's update per beacon. The adaptive setup's observation
sectors (``obs_coverage_sectors=8``) are timed as a third run. Rounds alternate between the runs
so that the machine's noise falls on all of them alike; the script prints steps per second of
each and the ratios.

Run: ``python3 benchmarks/coverage_map.py [--steps 3000] [--rounds 3] [--density 0.2]``.
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import time
from unittest import mock

import gymnasium as gym
import numpy as np

import aoass_env  # noqa: F401  (registers AOASS-v0)
from aoass_env import simulator
from aoass_env.maps.generator import MAX_DENSITY
from aoass_env.planning.coverage import CoverageMap
from aoass_env.validators import argparse_number


def _nodes_only(point: np.ndarray, queries: list) -> list[np.ndarray]:
    """``receivers_at`` without the coverage map: the nodes' receivers, no cells."""
    return [queries[0][0].receivers(point), np.zeros(0, dtype=np.int64)]


def steps_per_second(steps: int, density: float, *, with_map: bool, sectors: int = 0) -> float:
    """Zero-action steps per second of AOASS-v0 (resets included), the coverage map updated or
    not, with ``sectors`` coverage sectors in the observation."""
    env = gym.make("AOASS-v0", obstacle_density=density, obs_coverage_sectors=sectors)
    action = np.zeros(2, np.float32)
    patch = contextlib.ExitStack()
    if not with_map:
        patch.enter_context(mock.patch.object(CoverageMap, "add_beacon",
                                              lambda self, position, cells=None: 0))
        patch.enter_context(mock.patch.object(simulator, "receivers_at", _nodes_only))
    with patch:
        env.reset(seed=0)
        seed, start = 1, time.perf_counter()
        for _ in range(steps):
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                env.reset(seed=seed)
                seed += 1
        elapsed = time.perf_counter() - start
    env.close()
    return steps / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=argparse_number(int, 1), default=3000, help="steps per run")
    parser.add_argument("--rounds", type=argparse_number(int, 1),
                        default=3, help="alternating rounds")
    parser.add_argument("--density", type=argparse_number(float, 0.0, high=MAX_DENSITY),
                        default=0.2, help="obstacle density")
    args = parser.parse_args()
    runs = {"without the map": dict(with_map=False), "with the map": dict(with_map=True),
            "with the map and 8 sectors": dict(with_map=True, sectors=8)}
    rates: dict[str, list[float]] = {name: [] for name in runs}
    # one untimed short run of each first (compiled kernels, the seeds' maps), and the order
    # turned every round: the first run timed used to pay them, so that with --rounds 1 the
    # step with the map read as faster than the step without it
    for kwargs in runs.values():
        steps_per_second(min(args.steps, 200), args.density, **kwargs)
    names = list(runs)
    for k in range(args.rounds):
        for name in names[k % len(names):] + names[:k % len(names)]:
            rates[name].append(steps_per_second(args.steps, args.density, **runs[name]))
    base = statistics.median(rates["without the map"])
    print(f"AOASS-v0, zero action, density {args.density}, {args.steps} steps x "
          f"{args.rounds} rounds (median steps/s)")
    for name, values in rates.items():
        rate = statistics.median(values)
        print(f"  {name:28s} {rate:8.0f} steps/s   step time x{base / rate:.3f}")
    print("target: the step with the map costs at most 1.2x the step without it")


if __name__ == "__main__":
    main()
