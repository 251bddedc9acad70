"""What a reset of AOASS-Adaptive-v0 costs on a freshly generated map (the sweep's plan).

The adaptive rule plans its sweep on the static map before it moves (``AdaptiveSweep``: the
site tour, ``aoass_env.planning.pruning``); plans are cached per map, so on the shipped maps
only the first episode of a map pays, but every reset on a freshly generated map does (the
robustness preset, training or evaluating on generated maps). This script resets
``gym.make("AOASS-Adaptive-v0")`` once per map on ``--maps`` fresh maps of side ``--field``
(map k of density d from ``default_rng([SEED, k])``, densities taken in turn from
``--densities``) and prints the CPU seconds of each reset and their sum. The reference, in
the same process: ``gym.make("AOASS-v0")``'s reset on the same maps with the same seed (the
same simulator and episode, without the sweep's plan); each env resets on its own copy of a
map (a map keeps what it derives: the second would find the first's work done), and the two
take turns going first, map by map. Prints the reference's seconds too, and the ratio of the
sums, adaptive / plain: how many plain resets an adaptive one costs. Compare trees by
running it with ``PYTHONPATH=<tree>``.

Run: ``python3 benchmarks/adaptive_reset.py [--maps 4] [--densities 0.2 0.3 0.4 0.5]
[--field 100]``.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import aoass_env  # noqa: F401  (registers the ids)
from aoass_env.maps import MAX_DENSITY, ObstacleMap, generate_map
from aoass_env.validators import one_line

#: map k is generate_map(100, d, default_rng([SEED, k])): seeds used nowhere else
SEED = 31313


def fresh_maps(maps: int, densities: list[float], field: float = 100.0) -> list[ObstacleMap]:
    """The ``maps`` fresh maps of side ``field`` (m), densities taken in turn."""
    return [generate_map(field, densities[k % len(densities)], np.random.default_rng([SEED, k]))
            for k in range(maps)]


def copy_of(fresh: ObstacleMap) -> ObstacleMap:
    """A new map with ``fresh``'s field and polygons, none of what ``fresh`` derived."""
    return ObstacleMap(fresh.width, fresh.height, fresh.polygons, fresh.name)


def check_episodes(maps: list[ObstacleMap], field: float = 100.0) -> None:
    """The episodes :func:`resets` starts, started by AOASS-v0 (the same simulator, seeds and
    maps, without the sweep's plan) on copies of the maps (a map keeps what it derives, so the
    timed resets must not find it done): the ValueError of a map the simulator cannot use (no
    room for the moving obstacles) comes at once, not after the resets timed before it."""
    env = gym.make("AOASS-v0", field_size=field)
    env.reset(seed=1)
    for fresh in maps:
        env.reset(seed=2, options={"map": copy_of(fresh)})


#: the timed env first, the reference second
ENV_IDS = ("AOASS-Adaptive-v0", "AOASS-v0")


def resets(maps: list[ObstacleMap], field: float = 100.0) -> list[list[float]]:
    """CPU seconds of one reset on each fresh map of side ``field`` (m) of each env of
    :data:`ENV_IDS` (one list per env), after a first reset of each that loads the kernels;
    each reset on its own copy of the map, the envs in turn first (the second first on odd
    maps)."""
    envs = [gym.make(env_id, field_size=field) for env_id in ENV_IDS]
    for env in envs:
        env.reset(seed=1)
    out: list[list[float]] = [[] for _ in envs]
    for k, fresh in enumerate(maps):
        for i in (0, 1) if k % 2 == 0 else (1, 0):
            own = copy_of(fresh)
            start = time.process_time()
            envs[i].reset(seed=2, options={"map": own})
            out[i].append(time.process_time() - start)
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--maps", type=int, default=4, help="fresh maps, one reset each")
    parser.add_argument("--densities", type=float, nargs="+", default=[0.2, 0.3, 0.4, 0.5])
    parser.add_argument("--field", type=float, default=100.0, help="field side (m)")
    args = parser.parse_args(argv)
    if args.maps < 1:
        parser.error(f"--maps must be an integer >= 1, got {args.maps}")
    for d in args.densities:
        if not 0.0 <= d <= MAX_DENSITY:
            parser.error(f"--densities must lie in [0, {MAX_DENSITY}], got {d}")
    if not 20.0 <= args.field <= 400.0:
        parser.error(f"--field must lie in [20, 400] m, got {args.field:g}")
    try:
        maps = fresh_maps(args.maps, args.densities, args.field)
        check_episodes(maps, args.field)
    except ValueError as err:      # MapError (density out of reach), or no room to start
        parser.error(f"--field {args.field:g} with --densities "
                     f"{' '.join(f'{d:g}' for d in args.densities)}: {one_line(err)}")
    adaptive, plain = resets(maps, args.field)
    for env_id, times in zip(ENV_IDS, (adaptive, plain), strict=True):
        print(f"{env_id} reset on a fresh {args.field:g} m map, CPU s: "
              + " ".join(f"{t:.3f}" for t in times) + f"  (sum {sum(times):.3f})")
    print(f"ratio {ENV_IDS[0]} / {ENV_IDS[1]} (sums): {sum(adaptive) / sum(plain):.1f}")


if __name__ == "__main__":
    main()
