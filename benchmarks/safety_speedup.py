"""The safety stack's cost against an earlier commit (issue 20's "AOASS-Safe-v0 >= 0.7 x the
bare env"), paired tree by tree.

The earlier tree is unpacked with ``git archive`` into a temporary folder
(``step_speedup.unpack``). For each round and each seed, that tree and this one run in turn,
each in a fresh interpreter that imports its own ``aoass_env`` (``step_speedup.run_in_tree``):
``env_throughput.interleaved`` after ``env_throughput.warm_up_env`` of both envs, so
AOASS-v0 and AOASS-Safe-v0 are stepped in turn with random actions, resets included, in the
process's CPU time. Each process gives its own ratio (bare / Safe) and the stack's own cost
(Safe - bare); the trees meet the same machine one process apart, so the per-seed pairs and
the pooled figures are what to read on a shared or drifting machine.

Run: ``python3 benchmarks/safety_speedup.py [--against 2b79768] [--steps 6000] [--seeds 3]
[--rounds 2]`` (pin it to one core with ``taskset -c 1``). ``2b79768`` is the tree before
issue 20's twenty-first round (docs/performance.md).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import gymnasium as gym
from step_speedup import ROOT, run_in_tree, unpack


def paired_us(steps: int, seed: int) -> tuple[float, float]:
    """(AOASS-v0, AOASS-Safe-v0) CPU microseconds per random step stepped in turn
    (``env_throughput.interleaved``, ``steps`` each from ``seed``), after the warm-up of both
    envs (``env_throughput.warm_up_env``)."""
    from env_throughput import interleaved, warm_up_env  # after the tree's aoass_env

    for env_id in ("AOASS-Safe-v0", "AOASS-v0"):
        warm_up_env(gym.make(env_id))
    return interleaved(steps, seed)


def main(argv: list[str] | None = None) -> None:
    from aoass_env.validators import argparse_number

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--against", default="2b79768", help="the earlier commit")
    parser.add_argument("--steps", type=argparse_number(int, 1), default=6_000,
                        help="steps per env and seed, after the warm-up")
    parser.add_argument("--seeds", type=argparse_number(int, 1), default=3,
                        help="seeds 0 .. N-1")
    parser.add_argument("--rounds", type=argparse_number(int, 1), default=2,
                        help="runs of each tree and seed, in turn")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="aoass_before_") as folder:
        before = Path(folder)
        unpack(args.against, before)
        print(f"AOASS-Safe-v0 against AOASS-v0 stepped in turn, CPU us per step ({args.steps} "
              f"steps each per seed); {args.against} against this tree, one process each:")
        pooled = {args.against: [0.0, 0.0], "this tree": [0.0, 0.0]}
        for i in range(args.rounds):
            for seed in range(args.seeds):
                cells = []
                for name, tree in ((args.against, before), ("this tree", ROOT)):
                    bare, safe = run_in_tree(tree, "safety_speedup", "paired_us", args.steps,
                                             seed)
                    pooled[name][0] += bare
                    pooled[name][1] += safe
                    cells.append(f"{name}: stack {safe - bare:6.1f} us, ratio {bare / safe:.3f}")
                print(f"  round {i + 1}, seed {seed}: " + "; ".join(cells), flush=True)
        for name, (bare, safe) in pooled.items():
            runs = args.rounds * args.seeds
            print(f"{name}: pooled ratio {bare / safe:.3f} (target 0.7), the stack "
                  f"{(safe - bare) / runs:.1f} us per step on average over {runs} runs")


if __name__ == "__main__":
    main()
