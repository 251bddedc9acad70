"""Throughput of AOASS-v0 and AOASS-Safe-v0 against Gymnasium's Pendulum-v1, in one process.

Every environment comes from ``gymnasium.make`` (same wrappers), takes random actions from its
action space and is reset whenever an episode ends; the time of the resets is included. The
script prints steps per second of each (and per CPU second of the process, steadier on a shared
machine), the ratios AOASS-v0 / Pendulum-v1 (issue 20 target: >= 0.22) and AOASS-Safe-v0 /
AOASS-v0 (target: >= 0.7), the latter also with the two envs stepped in turn in chunks of 200
steps over long runs from three seeds (steadier: both meet the same drift, and the long runs
average over episodes), the reset time of AOASS-v0 at density 0.4 on a 100 m field (target:
<= 50 ms) with fresh seeds, repeated seeds and a shipped map, and where a random-action step
of AOASS-v0 and of AOASS-Safe-v0's safety stack goes: wall time per step of their parts,
measured by timers around them (a part's time includes the parts it calls; the rest is
Gymnasium's wrappers, the action, reward and info).

Run: ``python3 benchmarks/env_throughput.py [--steps N] [--nodes 100 1000] [--field 100]
[--interleaved N]``.
"""

from __future__ import annotations

import argparse
import functools
import statistics
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import gymnasium as gym
from numba.core import event as numba_event

import aoass_env  # noqa: F401  (registers AOASS-v0)
from aoass_env import simulator, wrappers
from aoass_env.config import AOASSConfig
from aoass_env.env import AOASSEnv
from aoass_env.maps import generator
from aoass_env.network import Network
from aoass_env.observation import Observer
from aoass_env.planning.coverage import CoverageMap
from aoass_env.planning.detour import DetourPlanner
from aoass_env.planning.follower import WaypointFollower
from aoass_env.safety.fuzzy import FuzzyController
from aoass_env.safety.kalman import MultiTargetTracker
from aoass_env.simulator import Simulator
from aoass_env.validators import argparse_number, one_line
from aoass_env.world import World

#: (label, class, method) of the parts a step is split into, outermost first.
PARTS: tuple[tuple[str, type, str], ...] = (
    ("AOASSEnv.step", AOASSEnv, "step"),
    ("  Simulator.step", Simulator, "step"),
    ("    World.step", World, "advance"),    # what Simulator.step calls (rows as floats)
    ("    Simulator._broadcast", Simulator, "_broadcast"),
    ("      receivers_at (both radios' links)", simulator, "receivers_at"),
    ("      Network.record_beacon (nodes, cells)", Network, "record_beacon"),
    ("      CoverageMap.add_beacon", CoverageMap, "add_beacon"),
    ("  WaypointFollower.command", WaypointFollower, "command"),
    ("    DetourPlanner.path (its searches)", DetourPlanner, "path"),
    ("  Observer.sense (d_obs, detections)", Observer, "sense"),
    ("    World.nearest_obstacle_distance", World, "nearest_obstacle_distance"),
    ("  Observer.vector (rays, the vector)", Observer, "vector"),
    ("    World.ray_distances", World, "ray_distances"),
    ("AOASSEnv.reset", AOASSEnv, "reset"),
)


#: (label, owner, attribute) of the parts a step of AOASS-Safe-v0's safety stack is split into:
#: the wrappers' methods and the functions ``aoass_env.wrappers`` calls (patched where it
#: looks them up).
SAFE_PARTS: tuple[tuple[str, Any, str], ...] = (
    ("FuzzyORCASafety.step", wrappers.FuzzyORCASafety, "step"),
    ("  AOASSEnv.step (the bare env)", AOASSEnv, "step"),
    ("  KalmanObstacleTracker.observation", wrappers.KalmanObstacleTracker, "observation"),
    ("    MultiTargetTracker.step", MultiTargetTracker, "step"),
    ("  FuzzyORCASafety._filter", wrappers.FuzzyORCASafety, "_filter"),
    ("    FuzzyController (fuzzy.py)", FuzzyController, "__call__"),
    ("    filter_period (ORCA Eq. 10, braking edges, command)", wrappers, "filter_period"),
    ("    solve_velocity", wrappers, "solve_velocity"),
    ("    escape_velocity (look-ahead)", wrappers, "escape_velocity"),
    ("    _braking_envelope", wrappers.FuzzyORCASafety, "_braking_envelope"),
    ("    unicycle_command (unicycle.py)", wrappers, "unicycle_command"),
)

#: A shipped 100 m map of density 0.4, for the reset on a named map.
NAMED_MAP = "test/d0.40_f100_s509"


def throughput(env: gym.Env, steps: int, seed: int = 0) -> tuple[float, int, float, float]:
    """(steps per second, episodes started, seconds spent in reset, steps per CPU second of
    this process) over ``steps`` random steps, resets included. The CPU rate is the steadier
    one on a shared machine: other processes lengthen the wall time, not this one's CPU time."""
    env.action_space.seed(seed)
    start, cpu = time.perf_counter(), time.process_time()
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
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    return steps / wall, episodes, reset_time, steps / max(cpu, 1e-9)


def cpu_seconds(env: gym.Env, n: int) -> float:
    """The process's CPU seconds for ``n`` random steps of ``env`` (resets included)."""
    cpu = time.process_time()
    for _ in range(n):
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            env.reset()
    return time.process_time() - cpu


def interleaved(steps: int, seed: int, chunk: int = 200, warm_up: int = 1_500,
                **kwargs: Any) -> tuple[float, float]:
    """(AOASS-v0, AOASS-Safe-v0) CPU microseconds per random step, resets included: the two
    envs (seeded with ``seed``) take ``warm_up`` steps each, then are stepped in turn in
    chunks of ``chunk`` steps until each has taken ``steps`` more. Both meet the same drift of
    a shared machine, and the long run averages over their episodes, so the ratio is steadier
    than that of two short runs one after the other."""
    envs = [gym.make(env_id, **kwargs) for env_id in ("AOASS-v0", "AOASS-Safe-v0")]
    run = cpu_seconds
    for env in envs:
        env.reset(seed=seed)
        env.action_space.seed(seed)
        run(env, warm_up)
    rounds = max(steps // chunk, 1)
    spent = [0.0, 0.0]
    for _ in range(rounds):
        for i, env in enumerate(envs):
            spent[i] += run(env, chunk)
    return 1e6 * spent[0] / (rounds * chunk), 1e6 * spent[1] / (rounds * chunk)


def reset_ms(resets: int, seeds: list[int] | None = None, **kwargs: Any) -> float:
    """Median wall time (ms) of ``resets`` seeded resets of AOASS-v0 with ``kwargs``, seeds
    0, 1, ... (or the ``seeds`` given, in turn, each reset once before the clock starts so
    that every timed reset reuses its generated map: at most as many seeds as
    :func:`~aoass_env.maps.generate_map` keeps maps)."""
    if seeds is not None and len(seeds) > generator._GENERATED_MAX:
        raise ValueError(f"{len(seeds)} seeds cannot all reuse their maps: generate_map keeps "
                         f"{generator._GENERATED_MAX}")
    env = gym.make("AOASS-v0", **kwargs)
    env.reset(seed=10_000)                          # first-use costs (imports, caches)
    for seed in seeds or ():                        # their maps drawn and kept
        env.reset(seed=seed)
    times = []
    for i in range(resets):
        seed = i if seeds is None else seeds[i % len(seeds)]
        t = time.perf_counter()
        env.reset(seed=seed)
        times.append(time.perf_counter() - t)
    return 1e3 * statistics.median(times)


#: The warm-up's seed (:func:`warm_up_env`), used by no timed run.
WARM_UP_SEED = 9_999


def warm_up_env(env: gym.Env, most: int = 20_000, quiet: int = 2_000) -> None:
    """Random steps of an AOASS ``env`` until an episode has ended and the env has then run
    ``quiet`` steps in a row without compiling a numba kernel (numba's ``"numba:compile"``
    events, which a kernel loaded from numba's cache does not raise), at most ``most``; under
    AOASS-Safe-v0 only after its first look-ahead (a step with a moving obstacle's ORCA line)
    as well. The first calls of a kernel compile it on a machine's first run (seconds each) or
    load it from numba's cache; either would otherwise fall into a timed run (an episode's end,
    the look-ahead's contest and the re-solve of an escape come late or rarely). It plays its
    own seed, :data:`WARM_UP_SEED`: the maps it generates are none a timed run asks for (the
    generator keeps its last few maps), so every timed reset builds its map."""
    env.reset(seed=WARM_UP_SEED)
    env.action_space.seed(WARM_UP_SEED)
    ended = looked = False          # an episode has ended; the look-ahead has run (or none)
    since = 0                       # quiet steps since both
    with numba_event.install_recorder("numba:compile") as compiles:
        seen = 0
        for _ in range(most):
            _, _, terminated, truncated, info = env.step(env.action_space.sample())
            safety = info.get("safety")
            looked = looked or safety is None or safety["constraints"] > safety["static"]
            if terminated or truncated:
                ended = True
                env.reset()
            since = since + 1 if ended and looked and len(compiles.buffer) == seen else 0
            seen = len(compiles.buffer)
            if since >= quiet:
                break


@contextmanager
def part_timers(parts: tuple[tuple[str, Any, str], ...] = PARTS
                ) -> Iterator[dict[str, list[float]]]:
    """Wraps the methods of ``parts`` (default :data:`PARTS`) in wall-clock timers while the
    context is open; yields label -> [seconds, calls]."""
    totals: dict[str, list[float]] = {}
    saved = []

    def timed(label: str, method: Callable) -> Callable:
        entry = totals.setdefault(label, [0.0, 0])

        @functools.wraps(method)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            t = time.perf_counter()
            try:
                return method(*args, **kwargs)
            finally:
                entry[0] += time.perf_counter() - t
                entry[1] += 1
        return wrapper

    for label, cls, name in parts:
        method = vars(cls).get(name)
        if method is None and name == "advance":     # a tree before World.advance
            name = "step"
            method = cls.__dict__[name]
        if method is None:      # a part an older tree does not have (receivers_at)
            continue
        saved.append((cls, name, method))
        setattr(cls, name, timed(label, method))
    try:
        yield totals
    finally:
        for cls, name, method in saved:
            setattr(cls, name, method)


def profile(steps: int, env_id: str = "AOASS-v0", **kwargs: Any) -> None:
    """Print the per-part wall time of ``steps`` random steps of ``env_id`` (AOASS-v0: the
    parts of :data:`PARTS`; AOASS-Safe-v0: of :data:`SAFE_PARTS`) with ``kwargs``."""
    parts = SAFE_PARTS if env_id == "AOASS-Safe-v0" else PARTS
    env = gym.make(env_id, **kwargs)
    with part_timers(parts) as totals:
        start = time.perf_counter()
        throughput(env, steps)
        total = time.perf_counter() - start
    print(f"\nwhere a random-action step of {env_id} {kwargs or ''} goes "
          f"({1e6 * total / steps:.0f} us/step in all, timers included):")
    for label, _, _ in parts:
        seconds, calls = totals.get(label, (0.0, 0))
        print(f"  {label:42s} {1e6 * seconds / steps:7.1f} us/step {100 * seconds / total:5.1f} %"
              f"  ({calls} calls, {1e6 * seconds / max(calls, 1):8.1f} us/call)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=20_000, help="random steps per env")
    # the config's ranges, checked here: a bad --nodes failed after the 27 s warm-up
    meta = {name: AOASSConfig.__dataclass_fields__[name].metadata
            for name in ("n_nodes", "field_size")}
    parser.add_argument("--nodes", type=argparse_number(int, meta["n_nodes"]["low"],
                                                        high=meta["n_nodes"]["high"]),
                        nargs="+", default=[100, 1000], help="AOASS-v0 node counts to measure")
    parser.add_argument("--field", type=argparse_number(float, meta["field_size"]["low"],
                                                        high=meta["field_size"]["high"]),
                        default=100.0, help="field side (m)")
    parser.add_argument("--resets", type=int, default=15, help="resets timed at density 0.4")
    parser.add_argument("--interleaved", type=int, default=20_000,
                        help="steps per env of the interleaved AOASS-Safe-v0 / AOASS-v0 "
                             "measurement, per seed 0-2 (0: skip it)")
    args = parser.parse_args()
    if args.steps < 1 or args.resets < 1 or args.interleaved < 0:
        parser.error("--steps and --resets must be positive, --interleaved at least 0")
    field = {"field_size": args.field} if args.field != 100.0 else {}
    # a field too small for the moving obstacles failed at the warm-up's first reset, or in the
    # reset timing after the whole run: those seeded resets are tried first, and the maps they
    # draw forgotten after (the generator keeps its last few), so every timed reset still
    # builds its own
    envs = {d: gym.make("AOASS-v0", obstacle_density=d, **field)
            for d in (AOASSConfig.obstacle_density, 0.4)}
    try:
        for density, seed in [(AOASSConfig.obstacle_density, WARM_UP_SEED)] + [
                (0.4, seed) for seed in (10_000, *range(args.resets))]:
            envs[density].reset(seed=seed)
    except ValueError as err:       # MapError, or no room for the moving obstacles
        parser.error(f"--field {args.field:g} (density {density:g}, seed {seed}): "
                     f"{one_line(err)}")
    finally:
        generator.clear_cache()
    throughput(gym.make("Pendulum-v1"), 2_000)       # warm-up (imports, CPU clock)
    # first-use costs of AOASS (lazy imports, compiled kernels loaded from numba's cache, or
    # compiled on a machine's first run), the look-ahead's included
    warm_up_env(gym.make("AOASS-Safe-v0", **field))
    warm_up_env(gym.make("AOASS-v0", **field))
    ref, _, _, ref_cpu = throughput(gym.make("Pendulum-v1"), args.steps)
    print(f"{'env':34s} {'steps/s':>9s} {'us/step':>8s} {'CPU us':>7s} {'episodes':>8s} "
          f"{'reset s':>8s} {'ratio':>6s} {'CPU':>6s}  against")
    print(f"{'Pendulum-v1':34s} {ref:9.0f} {1e6 / ref:8.1f} {1e6 / ref_cpu:7.1f}")
    bare = None
    for env_id, n in [("AOASS-v0", n) for n in args.nodes] + [("AOASS-Safe-v0", args.nodes[0])]:
        rate, episodes, reset_s, cpu = throughput(gym.make(env_id, n_nodes=n, **field),
                                                  args.steps)
        if bare is None:
            bare = rate, cpu
        against, base = ("AOASS-v0", bare) if env_id == "AOASS-Safe-v0" else \
            ("Pendulum", (ref, ref_cpu))
        print(f"{f'{env_id} n_nodes={n}':34s} {rate:9.0f} {1e6 / rate:8.1f} {1e6 / cpu:7.1f} "
              f"{episodes:8d} {reset_s:8.2f} {rate / base[0]:6.3f} {cpu / base[1]:6.3f}  "
              f"{against} (target {0.7 if against == 'AOASS-v0' else 0.22})")
    again, _, _, again_cpu = throughput(gym.make("Pendulum-v1"), args.steps)
    print(f"{'Pendulum-v1 (again)':34s} {again:9.0f} {1e6 / again:8.1f} {1e6 / again_cpu:7.1f}"
          f"   (reference drift {again / ref - 1:+.1%}, CPU {again_cpu / ref_cpu - 1:+.1%}; "
          f"ratios above use the first run; 'CPU': the same from this process's CPU time)")
    if args.interleaved:
        print(f"\nAOASS-Safe-v0 against AOASS-v0, stepped in turn (chunks of 200 steps, "
              f"{args.interleaved} steps each after 1 500 of warm-up; CPU us per step):")
        pooled = [0.0, 0.0]
        for seed in range(3):
            bare_us, safe_us = interleaved(args.interleaved, seed, n_nodes=args.nodes[0],
                                           **field)
            pooled = [pooled[0] + bare_us, pooled[1] + safe_us]
            print(f"  seed {seed}: {safe_us:.1f} against {bare_us:.1f}, ratio "
                  f"{bare_us / safe_us:.3f}")
        print(f"  seeds 0-2 pooled: ratio {pooled[0] / pooled[1]:.3f} (target 0.7)")
    fresh = reset_ms(args.resets, obstacle_density=0.4, **field)
    few = list(range(min(args.resets, generator._GENERATED_MAX)))
    again = reset_ms(args.resets, few, obstacle_density=0.4, **field)
    print(f"\nreset of AOASS-v0, density 0.4, {args.field:g} m field: median {fresh:.1f} ms over "
          f"{args.resets} fresh seeds (target <= 50 ms on 100 m); {again:.1f} ms with the same "
          f"{len(few)} seeds again and again (their generated maps reused)")
    if args.field == 100.0:
        print(f"reset of AOASS-v0 on the shipped map {NAMED_MAP}: median "
              f"{reset_ms(args.resets, map=NAMED_MAP):.1f} ms over {args.resets} seeds")
    profile(min(args.steps, 10_000), **field)
    profile(min(args.steps, 10_000), "AOASS-Safe-v0", **field)
    if any(n != 100 for n in args.nodes):
        profile(min(args.steps, 10_000), n_nodes=max(args.nodes), **field)


if __name__ == "__main__":
    main()
