"""Throughput of AOASS-v0 against Gymnasium's Pendulum-v1, measured in the same run.

Both environments come from ``gymnasium.make`` (same wrappers), take random actions from their
action space and are reset whenever an episode ends; the time of the resets is included. The
script prints steps per second of each and the ratio AOASS / Pendulum (issue 3 targets: >= 0.4
at 100 nodes, >= 0.15 at 1000 nodes).

Run: ``python3 benchmarks/env_throughput.py [--steps N] [--nodes 100 1000]``.
Profile: ``pyinstrument benchmarks/env_throughput.py --steps 5000 --nodes 100``.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym

import aoass_env  # noqa: F401  (registers AOASS-v0)


def throughput(env: gym.Env, steps: int, seed: int = 0) -> tuple[float, int, float]:
    """(steps per second, episodes started, seconds spent in reset) over ``steps`` random
    steps, resets included."""
    env.action_space.seed(seed)
    start = time.perf_counter()
    env.reset(seed=seed)
    reset_time = time.perf_counter() - start
    episodes = 1
    for _ in range(steps):
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            t = time.perf_counter()
            env.reset()
            reset_time += time.perf_counter() - t
            episodes += 1
    return steps / (time.perf_counter() - start), episodes, reset_time


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=20_000, help="random steps per env")
    parser.add_argument("--nodes", type=int, nargs="+", default=[100, 1000],
                        help="AOASS-v0 node counts to measure")
    args = parser.parse_args()
    targets = {100: 0.4, 1000: 0.15}
    throughput(gym.make("Pendulum-v1"), 2_000)       # warm-up (imports, CPU clock)
    ref, _, _ = throughput(gym.make("Pendulum-v1"), args.steps)
    print(f"{'env':28s} {'steps/s':>9s} {'us/step':>8s} {'episodes':>8s} {'reset s':>8s} "
          f"{'ratio':>6s} {'target':>6s}")
    print(f"{'Pendulum-v1':28s} {ref:9.0f} {1e6 / ref:8.1f} {'':>8s} {'':>8s} {1.0:6.2f}")
    for n in args.nodes:
        rate, episodes, reset_s = throughput(gym.make("AOASS-v0", n_nodes=n), args.steps)
        target = targets.get(n)
        print(f"{f'AOASS-v0 n_nodes={n}':28s} {rate:9.0f} {1e6 / rate:8.1f} {episodes:8d} "
              f"{reset_s:8.2f} {rate / ref:6.3f} {target if target else '':>6}")
    again, _, _ = throughput(gym.make("Pendulum-v1"), args.steps)
    print(f"{'Pendulum-v1 (again)':28s} {again:9.0f} {1e6 / again:8.1f}   "
          f"(reference drift {again / ref - 1:+.1%}; ratios above use the first run)")


if __name__ == "__main__":
    main()
