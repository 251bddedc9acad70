"""CPU microseconds per call of the step parts changed in issue 20's seventh round, at one state.

A seeded random-action AOASS-Safe-v0 episode is run ``--steps`` steps, and on until the
tracker holds ``--tracks`` (1) confirmed tracks of moving obstacles; at that state each part
is called ``--calls`` times (best of five rounds) without stepping on: the rays, the observer's
moving-obstacle slots, the fuzzy controller, the braking envelope, the filter's moving
obstacles and its whole verdict, the tracker's observation, and the radios' links of a beacon
(``receivers_at``, 500 points of the field). The episodes are the same bit for bit in every
tree this round compares, so the state is too: run the script with each tree first on
``PYTHONPATH`` and compare the lines (no output depends on the tree but the times)::

    PYTHONPATH=/tmp/base20 python3 benchmarks/step_parts_speed.py
    PYTHONPATH=$PWD python3 benchmarks/step_parts_speed.py

Reference, in the same process and timed the same way: a step of Gymnasium's Pendulum-v1
(``gym.make``) with a random action (``action_space.sample()``; past its 200-step limit it
steps on, truncated, without a reset), best of five rounds of ``--calls`` before the parts
and five after; each part is also printed as a ratio to the least of the two. The ratios,
not the times, are what two runs (two trees, or one tree on another day or machine) can be
compared by.

Run from the repository root or anywhere: the script's own folder, not the working directory,
comes first on ``sys.path``.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import gymnasium as gym
import numpy as np

import aoass_env
from aoass_env.radio import receivers_at
from aoass_env.validators import argparse_number
from aoass_env.wrappers import FuzzyORCASafety


def best_of(function: Callable[[], object], calls: int, rounds: int = 5) -> float:
    """Least CPU microseconds per call of ``function`` over ``rounds`` rounds of ``calls``."""
    best = float("inf")
    for _ in range(rounds):
        start = time.process_time()
        for _ in range(calls):
            function()
        best = min(best, time.process_time() - start)
    return best / calls * 1e6


def pendulum_us(calls: int) -> float:
    """:func:`best_of` a random-action step of Pendulum-v1 (CPU microseconds per call)."""
    env = gym.make("Pendulum-v1")
    env.reset(seed=0)
    env.action_space.seed(0)
    return best_of(lambda: env.step(env.action_space.sample()), calls)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=argparse_number(int, 0),
                        default=400, help="steps before the state")
    parser.add_argument("--calls", type=argparse_number(int, 1),
                        default=3000, help="calls per round")
    parser.add_argument("--tracks", type=argparse_number(int, 0), default=1,
                        help="after --steps, step on until the tracker holds at least this "
                             "many confirmed tracks (0: stop at --steps)")
    args = parser.parse_args(argv)
    env = gym.make("AOASS-Safe-v0", n_nodes=100)
    env.reset(seed=0)
    env.action_space.seed(0)
    # the state must be one of a running episode: a step past its end was a RuntimeError
    # traceback after the steps
    limit = getattr(env.spec, "max_episode_steps", None)
    if limit is not None and args.steps >= limit:
        parser.error(f"--steps {args.steps}: the seed-0 episode ends at its time limit of "
                     f"{limit} steps; give at most {limit - 1}")
    for step in range(1, args.steps + 1):
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            parser.error(f"--steps {args.steps}: the seed-0 episode ends after {step} steps; "
                         f"give at most {step - 1}")
    safe = env
    while not isinstance(safe, FuzzyORCASafety):
        safe = safe.env
    tracker, base = safe.env, safe._base
    # a state with moving obstacles tracked: the tracker's and the filter's parts then do
    # their full work (with no track, at 400 steps of seed 0, they had little to do)
    steps = args.steps
    while len(tracker.tracked_obstacles) < args.tracks:
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        steps += 1
        if terminated or truncated:
            parser.error(f"--tracks {args.tracks}: the seed-0 episode ends after {steps} steps "
                         f"with fewer confirmed tracks; give fewer (0 stops at --steps)")
    world, observer = base.sim.world, base._observe
    position, inner = base.anchor.position, base._observation()
    action = np.array([0.3, -0.2], np.float32)
    beacons = np.random.default_rng(1).uniform(0.0, base.config.field_size, (500, 2))
    queries = [(base.sim.radio, None), base.sim.coverage_map.listeners()]
    parts = {
        "World.ray_distances": world.ray_distances,
        "Observer.moving": lambda: observer.moving(world),
        "FuzzyController (one input)": lambda: safe.controller(2.0, 0.3),
        "FuzzyORCASafety._braking_envelope": lambda: safe._braking_envelope(
            position, safe._static_obstacles()),
        "FuzzyORCASafety._moving_obstacles": safe._moving_obstacles,
        "FuzzyORCASafety._filter": lambda: safe._filter(action),
        "KalmanObstacleTracker.observation": lambda: tracker.observation(inner),
    }
    print(f"aoass_env from {aoass_env.__file__}; state after {steps} steps "
          f"({len(tracker.tracked_obstacles)} confirmed tracks)")
    before = pendulum_us(args.calls)
    times = {name: best_of(function, args.calls) for name, function in parts.items()}
    times["receivers_at (one beacon, both radios)"] = best_of(
        lambda: [receivers_at(p, queries) for p in beacons], 1) / len(beacons)
    after = pendulum_us(args.calls)
    reference = min(before, after)
    for name, us in times.items():
        print(f"  {name:40s} {us:8.2f} us/call {us / reference:7.3f} x Pendulum-v1")
    print(f"  {'Pendulum-v1 step (the reference)':40s} {reference:8.2f} us/call (before the "
          f"parts {before:.2f}, after {after:.2f})")


if __name__ == "__main__":
    main()
