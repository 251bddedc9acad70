"""AOASS stepped as a batch of environments: Gymnasium's and SB3's vector envs, side by side.

Issue 20's last item asks, if per-environment Python overhead dominates a step, for a batch of
environments stepped together in one process, measured against SB3's ``SubprocVecEnv``. This
script measures what the batch can gain before any is built: the same random-action workload
(``gym.make(env_id)``, resets included; AOASS-v0 by default, ``--env-id AOASS-Train-v0`` for
the training setup, whose agent step is 16 control periods) stepped

* one environment at a time (the reference),
* in one process: Gymnasium's ``SyncVectorEnv`` and SB3's ``DummyVecEnv`` (a loop over the
  environments: what a batch in one process starts from),
* in worker processes: Gymnasium's ``AsyncVectorEnv`` (shared memory) and SB3's
  ``SubprocVecEnv``,
* as independent processes, each stepping its own environment (no vector env: the summed rate),

and prints environment steps per wall second and per CPU second of this process, each as a
ratio to the single environment measured in the same run, and the share of a single
environment's step that a batch could merge across environments (the Gymnasium wrappers, the
action sampling and ``AOASSEnv.step`` outside its simulation, planner and sensing calls,
measured by timers around those calls; the rest is per-environment Chipmunk, GEOS and scipy
work on each environment's own world, which no batch merges). It also times the worker round
trip alone (two Pendulum-v1 environments, a step of a few µs, in ``DummyVecEnv`` and in
``SubprocVecEnv``) and bounds what lock-step workers can gain from the spread of a single
environment's step times (a vector step lasts as long as its slowest environment's).

Run: ``python3 benchmarks/vector_envs.py [--env-id ID] [--steps N] [--envs 2 4] [--warm-up N]``.
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import gymnasium as gym
import numpy as np
from env_throughput import part_timers  # benchmarks/env_throughput.py, a sibling
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

import aoass_env  # noqa: F401  (registers AOASS-v0)
from aoass_env.observation import Observer
from aoass_env.planning.follower import WaypointFollower
from aoass_env.simulator import Simulator
from aoass_env.validators import argparse_number
from aoass_env.world import World


def _timed(make: Callable[[], Any], step: Callable[[Any, np.random.Generator], int],
           steps: int, warm_up: int) -> tuple[float, float, int]:
    """(wall s, CPU s of this process, env steps) of ``steps`` env steps after ``warm_up``."""
    venv = make()
    rng = np.random.default_rng(0)
    try:
        done = 0
        while done < warm_up:
            done += step(venv, rng)
        wall, cpu, done = time.perf_counter(), time.process_time(), 0
        while done < steps:
            done += step(venv, rng)
        return time.perf_counter() - wall, time.process_time() - cpu, done
    finally:
        venv.close()


def single(env_id: str, seed: int) -> Callable[[], Any]:
    def make() -> Any:
        env = gym.make(env_id)
        env.reset(seed=seed)
        env.action_space.seed(seed)
        return env
    return make


def single_step(env: Any, rng: np.random.Generator) -> int:
    _, _, terminated, truncated, _ = env.step(env.action_space.sample())
    if terminated or truncated:
        env.reset()
    return 1


def gym_vector(env_id: str, n: int, mode: str, seed: int) -> Callable[[], Any]:
    def make() -> Any:
        venv = gym.make_vec(env_id, num_envs=n, vectorization_mode=mode)
        venv.reset(seed=seed)
        venv.action_space.seed(seed)
        return venv
    return make


def gym_vector_step(venv: Any, rng: np.random.Generator) -> int:
    venv.step(venv.action_space.sample())       # autoreset: the next step resets a done env
    return venv.num_envs


def sb3_vector(env_id: str, n: int, cls: type, seed: int) -> Callable[[], Any]:
    def make() -> Any:
        venv = cls([lambda: gym.make(env_id) for _ in range(n)])
        venv.seed(seed)
        venv.reset()
        return venv
    return make


def sb3_vector_step(venv: Any, rng: np.random.Generator) -> int:
    low, high = venv.action_space.low, venv.action_space.high
    venv.step(rng.uniform(low, high, (venv.num_envs, *low.shape)).astype(np.float32))
    return venv.num_envs


#: The per-environment library work inside ``AOASSEnv.step``, as ``part_timers`` parts: what
#: stays per environment in any batch (each its own Chipmunk space, obstacle map and planner
#: grid). None calls another.
OWN_WORLD: tuple[tuple[str, type, str], ...] = (
    ("Simulator.step", Simulator, "step"),
    ("WaypointFollower.command", WaypointFollower, "command"),
    ("Observer.sense", Observer, "sense"),
    ("World.ray_distances", World, "ray_distances"))


def single_profile(env_id: str, steps: int, seed: int) -> tuple[np.ndarray, float]:
    """The wall time (s) of each of ``steps`` random steps of one environment (after a
    warm-up), and the seconds of them spent in :data:`OWN_WORLD`'s calls (the timers' own
    cost, a few calls per step, is in the step times)."""
    env = single(env_id, seed)()
    rng = np.random.default_rng(0)
    for _ in range(min(steps, 500)):
        single_step(env, rng)
    times = np.empty(steps)
    with part_timers(OWN_WORLD) as totals:
        for k in range(steps):
            start = time.perf_counter()
            single_step(env, rng)
            times[k] = time.perf_counter() - start
    env.close()
    return times, sum(seconds for seconds, _ in totals.values())


def lockstep_bound(times: np.ndarray, n: int) -> float:
    """The speed-up of ``n`` environments stepped in lock step on ``n`` free cores with no
    round trip, from one environment's step times ``times`` (s): each vector step lasts as long
    as its slowest environment's step, so the bound is n x mean / E[max of n steps] (over
    random n-tuples of the recorded steps)."""
    draws = np.random.default_rng(0).choice(times, size=(100_000, n))
    return n * times.mean() / draws.max(axis=1).mean()


def _alone(env_id: str, seed: int, steps: int, warm_up: int) -> float:
    """Env steps per wall second of a single environment in this (worker) process."""
    wall, _, done = _timed(single(env_id, seed), single_step, steps, warm_up)
    return done / wall


def independent(env_id: str, n: int, seed: int, steps: int, warm_up: int) -> float:
    """Summed env steps per wall second of ``n`` processes each stepping its own environment
    at the same time, with no vector env between them (the way evaluation sweeps use cores)."""
    with ProcessPoolExecutor(n) as pool:
        return sum(pool.map(_alone, [env_id] * n, [seed + k for k in range(n)], [steps] * n,
                            [warm_up] * n))


def round_trip(cls: type, steps: int = 3000) -> float:
    """Wall µs per vector step of two Pendulum-v1 environments (a step of a few µs) in ``cls``:
    for ``SubprocVecEnv`` nearly all of it is the workers' round trip through their pipes."""
    venv = cls([lambda: gym.make("Pendulum-v1") for _ in range(2)])
    try:
        venv.reset()
        action = np.zeros((2, *venv.action_space.shape), dtype=np.float32)
        for _ in range(200):
            venv.step(action)
        start = time.perf_counter()
        for _ in range(steps):
            venv.step(action)
        return 1e6 * (time.perf_counter() - start) / steps
    finally:
        venv.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--env-id", default="AOASS-v0", help="registered id (default AOASS-v0)")
    parser.add_argument("--steps", type=argparse_number(int, 1), default=6000,
                        help="env steps timed per setup")
    parser.add_argument("--envs", type=argparse_number(int, 1), nargs="+", default=[2, 4],
                        help="environments per vector env")
    parser.add_argument("--warm-up", type=argparse_number(int, 1), default=400,
                        help="env steps before the timing (worker start-up excluded)")
    parser.add_argument("--seed", type=argparse_number(int, 0), default=0)
    args = parser.parse_args()
    if args.env_id not in gym.registry:
        parser.error(f"--env-id {args.env_id}: not registered; the AOASS ids are "
                     f"{', '.join(i for i in gym.registry if i.startswith('AOASS'))}")
    env_id = args.env_id

    setups: list[tuple[str, int, Callable[[], Any], Callable[..., int]]] = [
        ("single env", 1, single(env_id, args.seed), single_step)]
    for n in args.envs:
        setups += [
            ("gymnasium SyncVectorEnv", n, gym_vector(env_id, n, "sync", args.seed),
             gym_vector_step),
            ("SB3 DummyVecEnv", n, sb3_vector(env_id, n, DummyVecEnv, args.seed),
             sb3_vector_step),
            ("gymnasium AsyncVectorEnv", n, gym_vector(env_id, n, "async", args.seed),
             gym_vector_step),
            ("SB3 SubprocVecEnv", n, sb3_vector(env_id, n, SubprocVecEnv, args.seed),
             sb3_vector_step)]
    print(f"{env_id}, random actions, resets included; {args.steps} env steps per setup after "
          f"{args.warm_up}; {os.cpu_count()} CPUs")
    print(f"{'setup':28s} {'envs':>4s} {'steps/s':>9s} {'ratio':>6s} {'CPU steps/s':>12s}"
          f" {'ratio':>6s}")
    reference: tuple[float, float] | None = None
    for label, n, make, step in setups:
        wall, cpu, done = _timed(make, step, args.steps, args.warm_up)
        rate, cpu_rate = done / wall, done / cpu
        if reference is None:
            reference = (rate, cpu_rate)
        print(f"{label:28s} {n:4d} {rate:9.0f} {rate / reference[0]:6.2f} {cpu_rate:12.0f} "
              f"{cpu_rate / reference[1]:6.2f}")
    for n in args.envs:
        rate = independent(env_id, n, args.seed, args.steps, args.warm_up)
        print(f"{'independent processes':28s} {n:4d} {rate:9.0f} {rate / reference[0]:6.2f}")
    print(f"\nPendulum-v1, 2 envs, wall µs per vector step: DummyVecEnv "
          f"{round_trip(DummyVecEnv):.0f}, SubprocVecEnv {round_trip(SubprocVecEnv):.0f} (the "
          f"difference: the workers' round trip)")
    times, world = single_profile(env_id, args.steps, args.seed)
    for n in args.envs:
        print(f"{n} envs in lock step, free cores and no round trip: at most "
              f"{lockstep_bound(times, n):.2f} x the single env (each vector step waits for its "
              f"slowest env; a step's wall time: median {1e6 * np.median(times):.0f} µs, 99th "
              f"percentile {1e6 * np.quantile(times, 0.99):.0f} µs, longest "
              f"{1e3 * times.max():.1f} ms)")
    total, world, rest = (1e6 * t / args.steps for t in (times.sum(), world,
                                                          times.sum() - world))
    print(f"\na single env's step: {total:.1f} µs wall; per-environment world work (Simulator."
          f"step, WaypointFollower.command, Observer.sense and the rays) {world:.1f} µs "
          f"({world / total:.0%}); the rest, which a batch could merge at best, {rest:.1f} µs "
          f"({rest / total:.0%}): a batch in one process is at most {total / world:.2f} x "
          f"the single env")


if __name__ == "__main__":
    main()
