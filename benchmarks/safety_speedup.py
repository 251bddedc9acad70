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

``--gate`` measures instead, in one process, what the tracker's compiled gate (issue 20's
twenty-first round) takes off: AOASS-v0, AOASS-Safe-v0 and AOASS-Safe-v0 whose tracker
associates by NumPy's inverse and ``linear_sum_assignment`` alone (its ``_nearest`` answering
None: the tree before), stepped in turn in chunks of 200 steps, the order reversed every
round; the three meet the same drift of the machine, and the two stacks play the same
episodes (the pairs are the same, tests/safety/test_kalman.py).

Run: ``python3 benchmarks/safety_speedup.py [--against 2b79768] [--steps 6000] [--seeds 3]
[--rounds 2] [--gate]`` (pin it to one core with ``taskset -c 1``). ``2b79768`` is the tree
before issue 20's twenty-first round (docs/performance.md).
"""

from __future__ import annotations

import argparse
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

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


def gate_us(steps: int, seed: int, chunk: int = 200) -> tuple[float, ...]:
    """(AOASS-v0, AOASS-Safe-v0, AOASS-Safe-v0 with NumPy's association) CPU microseconds per
    random step from ``seed``, stepped in turn (see the module docstring), after 1 500 steps
    of each; then the two stacks' association alone (their trackers' ``_associate``, wall
    microseconds per step of the timed steps): the part the gate changes, timed where it runs,
    which the whole steps' scatter on a shared machine can hide."""
    import time

    from env_throughput import cpu_seconds as run  # after the tree's aoass_env

    def timed(associate: Callable[..., Any], k: int) -> Callable[..., Any]:
        def call(*args: Any) -> Any:
            start = time.perf_counter()
            try:
                return associate(*args)
            finally:
                associating[k] += time.perf_counter() - start
        return call

    envs = [gym.make(env_id) for env_id in ("AOASS-v0", "AOASS-Safe-v0", "AOASS-Safe-v0")]
    associating = [0.0, 0.0]
    for k, env in enumerate(envs[1:]):
        wrapper = env
        while not hasattr(wrapper, "tracker"):
            wrapper = wrapper.env
        tracker = wrapper.tracker
        if k:
            tracker._nearest = lambda *args: None        # NumPy's association decides
        tracker._associate = timed(tracker._associate, k)
    for env in envs:
        env.reset(seed=seed)
        env.action_space.seed(seed)
        run(env, 1_500)
    spent, associating[:] = [0.0, 0.0, 0.0], [0.0, 0.0]
    rounds = max(steps // chunk, 1)
    for r in range(rounds):
        for i in ((0, 1, 2) if r % 2 == 0 else (2, 1, 0)):
            spent[i] += run(envs[i], chunk)
    n = rounds * chunk
    return (*(1e6 * s / n for s in spent), *(1e6 * a / n for a in associating))


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
    parser.add_argument("--gate", action="store_true",
                        help="in one process: the compiled gate against NumPy's association")
    args = parser.parse_args(argv)
    if args.gate:
        from env_throughput import warm_up_env

        for env_id in ("AOASS-Safe-v0", "AOASS-v0"):
            warm_up_env(gym.make(env_id))
        print(f"AOASS-v0, AOASS-Safe-v0 and AOASS-Safe-v0 with NumPy's association stepped in "
              f"turn, CPU us per step ({args.steps} steps each per seed and round):")
        pooled = [0.0] * 5
        for i in range(args.rounds):
            for seed in range(args.seeds):
                us = gate_us(args.steps, seed)
                pooled = [p + u for p, u in zip(pooled, us, strict=True)]
                bare, compiled, numpy_gate, assoc, assoc_numpy = us
                print(f"  round {i + 1}, seed {seed}: the stack {compiled - bare:6.1f} us with "
                      f"the compiled gate, {numpy_gate - bare:6.1f} us without (its association "
                      f"{assoc:5.1f} against {assoc_numpy:5.1f} us); ratio {bare / compiled:.3f} "
                      f"against {bare / numpy_gate:.3f}", flush=True)
        runs = args.rounds * args.seeds
        bare, compiled, numpy_gate, assoc, assoc_numpy = (p / runs for p in pooled)
        print(f"pooled: ratio {bare / compiled:.3f} with the compiled gate, "
              f"{bare / numpy_gate:.3f} without (target 0.7); the stack {compiled - bare:.1f} "
              f"against {numpy_gate - bare:.1f} us per step, of which the association "
              f"{assoc:.1f} against {assoc_numpy:.1f}")
        return
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
