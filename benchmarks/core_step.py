"""Speed of one control step of the simulation core, as the Gymnasium environment drives it.

Each episode builds a :class:`~aoass_env.simulator.Simulator` (the reset) and drives its nominal
follower to the end: per control step ``follower.command``, ``Simulator.step`` (world step,
beacons, radio and ledger), ``World.ray_distances`` and ``World.nearest_obstacle_distance``.
Prints CPU microseconds per step for each part, the reset in milliseconds, and the cost per step
with the reset amortised over the episode. Default config (100 m field, density 0.2, 3 moving
obstacles, dt 0.5 s, 5 substeps, 16 rays) at 100 and 1000 nodes; episodes are capped at
``--steps`` control steps.

Reference, in the same process: Gymnasium's Pendulum-v1 from ``gym.make``, random actions,
resets included, timed in CPU time by ``env_throughput.throughput`` (the project's standard
reference) over ``--pendulum-steps`` steps before the episodes and again after them. Each
total is also printed as a ratio to the mean of the two (how many Pendulum-v1 steps a core
step costs), with the drift between them.

Run: ``python3 benchmarks/core_step.py [--episodes E] [--steps N] [--pendulum-steps P]``.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np
from env_throughput import throughput

from aoass_env.config import AOASSConfig
from aoass_env.simulator import Simulator
from aoass_env.validators import argparse_number

PARTS = ("command", "sim.step", "rays", "d_obs")
#: The untimed warm-up episode's seed (the other benchmarks' too).
WARM_UP_SEED = 9999


def run_episode(config: AOASSConfig, seed: int, max_steps: int) -> tuple[float, dict[str, float],
                                                                          int]:
    """One episode: (reset seconds, seconds per part summed over steps, control steps)."""
    clock = time.process_time   # CPU time: less disturbed by other jobs on shared cores
    t0 = clock()
    sim = Simulator(config, np.random.default_rng(seed))
    follower = sim.follower()
    reset = clock() - t0
    world, dt = sim.world, config.dt
    parts = dict.fromkeys(PARTS, 0.0)
    steps = 0
    for _ in range(max_steps):
        t0 = clock()
        speed, heading = follower.command(world.position, world.heading, dt)
        t1 = clock()
        if follower.done:
            break
        sim.step(speed, heading)
        t2 = clock()
        world.ray_distances()
        t3 = clock()
        world.nearest_obstacle_distance()
        t4 = clock()
        parts["command"] += t1 - t0
        parts["sim.step"] += t2 - t1
        parts["rays"] += t3 - t2
        parts["d_obs"] += t4 - t3
        steps += 1
    return reset, parts, steps


def pendulum_us(steps: int) -> float:
    """CPU microseconds per random step of Pendulum-v1 (resets included) over ``steps``."""
    return 1e6 / throughput(gym.make("Pendulum-v1"), steps)[3]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=3, help="episodes (seeds) per config")
    parser.add_argument("--steps", type=int, default=2000, help="control steps per episode cap")
    parser.add_argument("--pendulum-steps", type=argparse_number(int, 1), default=20_000,
                        help="Pendulum-v1 steps per reference run")
    args = parser.parse_args(argv)
    if args.episodes < 1 or args.steps < 1:
        parser.error("--episodes and --steps must be positive")
    # one untimed episode first: the first reset and steps load compiled kernels and fill
    # caches (about 6x a warm reset)
    run_episode(AOASSConfig(), WARM_UP_SEED, args.steps)
    pendulum_us(2_000)                              # its warm-up (imports, first calls)
    before = pendulum_us(args.pendulum_steps)
    lines = []
    for k, n_nodes in enumerate((100, 1000)):
        config = AOASSConfig(n_nodes=n_nodes)
        resets, totals, steps = [], dict.fromkeys(PARTS, 0.0), 0
        # seeds of their own per node count: the map generator keeps the last maps it drew,
        # so N = 1000 on N = 100's seeds timed resets without map generation
        for seed in range(k * args.episodes, (k + 1) * args.episodes):
            reset, parts, n = run_episode(config, seed, args.steps)
            resets.append(reset)
            steps += n
            for k, v in parts.items():
                totals[k] += v
        per_step = {k: v / steps * 1e6 for k, v in totals.items()}
        step_us = sum(per_step.values())
        reset_ms = 1e3 * float(np.mean(resets))
        amortised = step_us + 1e3 * reset_ms * args.episodes / steps
        lines.append((f"N = {n_nodes}: {steps} steps in {args.episodes} episodes; per step "
                      + ", ".join(f"{k} {v:.1f}" for k, v in per_step.items())
                      + f" us; total {step_us:.1f} us; reset {reset_ms:.1f} ms "
                      f"(median {1e3 * float(np.median(resets)):.1f}); with resets amortised "
                      f"{amortised:.1f} us/step", step_us, amortised))
    after = pendulum_us(args.pendulum_steps)
    reference = (before + after) / 2
    print(f"Pendulum-v1 (gym.make, random actions, resets included): {before:.1f} us/step "
          f"before, {after:.1f} after (drift {after / before - 1:+.1%}); ratios to their mean "
          f"{reference:.1f} us")
    for line, step_us, amortised in lines:
        print(f"{line}; ratio to Pendulum-v1 {step_us / reference:.2f} (amortised "
              f"{amortised / reference:.2f})")


if __name__ == "__main__":
    main()
