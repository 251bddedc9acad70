"""Speed-up of an AOASS-v0 step against an earlier commit (issue 20's "3 x faster per step").

The earlier tree is unpacked with ``git archive`` into a temporary folder; this tree and that one
then run in turn (the earlier first in the odd-numbered rounds 1, 3, ..., second in the even
ones: ``git_history.in_turn``), each in a fresh interpreter whose ``PYTHONPATH`` puts the tree
first: random actions in ``gymnasium.make("AOASS-v0")`` (default config), ``--steps`` steps from
each of seeds 0, 1, ... after 3 000 steps of warm-up on seed 9 999 (imports, caches, compiled
kernels), resets included, timed in the process's CPU time: once with each action drawn by
``action_space.sample()`` inside the loop (issue 20's measure), once with the same actions
drawn before the clock starts (the two passes in an order that alternates with the seed and
the round; the step alone; the difference is the draw, whose cost depends
on the tree's action space: ``aoass_env.action.ActionBox`` since 2026-11-29). The
fingerprint test pins the same episodes for the same seeds since before issue 20, and both
trees' action spaces draw the same actions, so both trees step through the same states.
Pendulum-v1 (3 x ``--steps`` steps per seed) is timed the same way in the same process as each
tree's AOASS-v0, seed by seed in turn with it (which of the two goes first alternates with the
seed and the round), as the reference of issue 20's second target (AOASS-v0 at >= 0.22 x its
steps/s): each tree's ratio divides two figures of one process.

Run: ``python3 benchmarks/step_speedup.py [--against 94e941b] [--steps 20000] [--seeds 3]
[--rounds 2]`` (pin it to one core with ``taskset -c 1`` on a shared machine). ``94e941b`` is
the tree before issue 20's first change.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
from git_history import in_turn

ROOT = Path(__file__).resolve().parents[1]

#: the warm-up's seed and length, used by no timed run
WARM_UP_SEED, WARM_UP_STEPS = 9_999, 3_000

#: the envs each tree's process times in turn: (id, timed steps per seed as a multiple of
#: ``--steps``); Pendulum-v1's step is about a quarter of AOASS-v0's
ENVS = (("AOASS-v0", 1), ("Pendulum-v1", 3))


def seed_cpu_s(env: gym.Env, seed: int, steps: int, swap: bool = False
               ) -> tuple[float, float]:
    """CPU seconds of ``steps`` random steps of ``env`` from ``seed`` (resets included): (each
    action drawn with ``action_space.sample()`` in the loop, issue 20's measure; the same
    actions drawn before the clock starts, the step alone). The in-the-loop pass runs first,
    or second with ``swap`` (callers alternate it, so a drift of the machine's speed does not
    land on the draw's cost, the difference of the two)."""
    spent = {}
    for drawn_first in ((True, False) if swap else (False, True)):
        env.reset(seed=seed)
        env.action_space.seed(seed)
        drawn = [env.action_space.sample() for _ in range(steps)] if drawn_first else None
        start = time.process_time()
        for i in range(steps):
            action = drawn[i] if drawn else env.action_space.sample()
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                env.reset()
        spent[drawn_first] = time.process_time() - start
    return spent[False], spent[True]


def cpu_us_per_step(steps: int, seeds: int, round_: int = 0, warm_up: int = WARM_UP_STEPS
                    ) -> dict[str, tuple[float, float]]:
    """env id -> CPU microseconds per random step (resets included) of each of :data:`ENVS` in
    this one process: (action drawn in the loop, drawn before the clock; :func:`seed_cpu_s`)
    over its share of ``steps`` steps from each of seeds 0 .. ``seeds`` - 1. Each env first
    takes ``warm_up`` untimed steps from :data:`WARM_UP_SEED`; then, seed by seed, the envs run
    in turn, in the order ``in_turn(round_ + seed, ...)``, and each env's two passes in the
    order that alternates with ``round_ + seed`` too."""
    import aoass_env  # noqa: F401  (registers AOASS-v0 of the tree first on the path)

    envs = {env_id: gym.make(env_id) for env_id, _ in ENVS}
    share = dict(ENVS)
    for env in envs.values():
        seed_cpu_s(env, WARM_UP_SEED, warm_up)
    spent = {env_id: [0.0, 0.0] for env_id in envs}
    for seed in range(seeds):
        for env_id in in_turn(round_ + seed, *envs):
            sampled, alone = seed_cpu_s(envs[env_id], seed, share[env_id] * steps,
                                        swap=(round_ + seed) % 2 == 1)
            spent[env_id][0] += sampled
            spent[env_id][1] += alone
    for env in envs.values():
        env.close()
    return {env_id: (1e6 * a / (share[env_id] * steps * seeds),
                     1e6 * b / (share[env_id] * steps * seeds))
            for env_id, (a, b) in spent.items()}


def unpack(ref: str, folder: Path) -> None:
    """The files of commit ``ref`` (``git archive``) into ``folder``; exits in one line when git
    does not know it."""
    run = subprocess.run(["git", "archive", "--format=tar", ref], cwd=ROOT, capture_output=True)
    if run.returncode:
        raise SystemExit(f"--against {ref}: git archive failed "
                         f"({run.stderr.decode().strip().splitlines()[-1]})")
    with tarfile.open(fileobj=io.BytesIO(run.stdout)) as tar:
        tar.extractall(folder, filter="data")


def run_in_tree(tree: Path, module: str, function: str, *args: Any) -> Any:
    """``module.function(*args)`` (a module of this folder; JSON arguments and result) in a
    fresh interpreter, run in ``tree``, that imports ``aoass_env`` from it; exits in one line
    when the call fails or another copy of ``aoass_env`` was imported."""
    code = ("import importlib, json, sys, aoass_env; sys.path.insert(0, sys.argv[1]); "
            "f = getattr(importlib.import_module(sys.argv[2]), sys.argv[3]); "
            "print(json.dumps([aoass_env.__file__, f(*json.loads(sys.argv[4]))]))")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(tree), *filter(None, [os.environ.get("PYTHONPATH")])]))
    run = subprocess.run([sys.executable, "-c", code, str(Path(__file__).parent), module,
                          function, json.dumps(args)], cwd=tree, env=env, capture_output=True,
                         text=True)
    if run.returncode:
        raise SystemExit(f"the tree {tree} failed to run {module}.{function}{args}: "
                         f"{(run.stderr.strip().splitlines() or ['no error output'])[-1]}")
    path, result = json.loads(run.stdout.strip().splitlines()[-1])
    if not Path(path).resolve().is_relative_to(tree.resolve()):
        raise SystemExit(f"the run meant for {tree} imported aoass_env from {path}")
    return result


def in_tree(tree: Path, steps: int, seeds: int, round_: int = 0, warm_up: int = WARM_UP_STEPS
            ) -> dict[str, tuple[float, float]]:
    """:func:`cpu_us_per_step` in a fresh interpreter that imports ``tree``'s ``aoass_env``
    (:func:`run_in_tree`)."""
    timed = run_in_tree(tree, "step_speedup", "cpu_us_per_step", steps, seeds, round_, warm_up)
    return {env_id: (sampled, alone) for env_id, (sampled, alone) in timed.items()}


def main(argv: list[str] | None = None) -> None:
    # imported here, not at the top: the earlier tree's interpreter imports this module with
    # its own aoass_env, which may predate argparse_number
    from aoass_env.validators import argparse_number

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--against", default="94e941b", help="the earlier commit")
    parser.add_argument("--steps", type=argparse_number(int, 1), default=20_000,
                        help="timed steps per seed")
    parser.add_argument("--seeds", type=argparse_number(int, 1), default=3,
                        help="seeds 0 .. N-1")
    parser.add_argument("--rounds", type=argparse_number(int, 1), default=2,
                        help="runs of each tree, in turn, the earlier first in every other one")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="aoass_before_") as folder:
        before = Path(folder)
        unpack(args.against, before)
        print(f"AOASS-v0, random actions, resets included, CPU us per step ({args.steps} steps "
              f"from each of {args.seeds} seeds); {args.against} against this tree:")
        ratios, alone, pendulum = [], [], []
        for i in range(args.rounds):
            timed = {tree: in_tree(tree, args.steps, args.seeds, i)
                     for tree in in_turn(i, before, ROOT)}
            (old, old_alone), (ref_old, _) = (timed[before][e] for e, _ in ENVS)
            (new, new_alone), (ref, ref_alone) = (timed[ROOT][e] for e, _ in ENVS)
            ratios.append(old / new)
            alone.append(old_alone / new_alone)
            pendulum.append((ref_old / old, ref / new))
            print(f"  round {i + 1}: {old:7.1f} -> {new:7.1f} us, {old / new:5.2f} x faster "
                  f"(target 3); Pendulum-v1 in the same process {ref_old:5.1f}, {ref:5.1f} us: "
                  f"{ref_old / old:.3f} x -> {ref / new:.3f} x its steps/s (target 0.22)")
            print(f"           the step alone (actions drawn before the clock): {old_alone:7.1f} "
                  f"-> {new_alone:7.1f} us, {old_alone / new_alone:5.2f} x; drawing the action "
                  f"in the loop {old - old_alone:5.1f} -> {new - new_alone:5.1f} us "
                  f"(Pendulum-v1's step alone {ref_alone:4.1f} us, its draw "
                  f"{ref - ref_alone:4.1f})")
        print(f"median speed-up {statistics.median(ratios):.2f} x (the step alone "
              f"{statistics.median(alone):.2f} x); against Pendulum-v1 "
              f"{statistics.median(p[0] for p in pendulum):.3f} x -> "
              f"{statistics.median(p[1] for p in pendulum):.3f} x")


if __name__ == "__main__":
    main()
