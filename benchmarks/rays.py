"""Speed of the range sensor: the compiled rays (aoass_env.rays) against Chipmunk's queries.

Drives the anchor of a world on a freshly generated 100 m map with random commands and, after
every control step, reads the 16 rays both ways in turn, in this process: ``World.ray_distances``
as the world casts them (one compiled call) and through pymunk's space ray by ray (the world's
code where the probe fails). Prints microseconds per reading of each, the ratio, the share of
rays that hit something, and whether every reading agreed to the bit (it exits with an error
when one did not).

Run: ``python3 benchmarks/rays.py [--steps 3000] [--density 0.2] [--seed 881000]``.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from aoass_env.config import AOASSConfig
from aoass_env.maps import generate_map
from aoass_env.validators import argparse_number
from aoass_env.world import World


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=argparse_number(int, 1), default=3000)
    parser.add_argument("--density", type=argparse_number(float, 0.0), default=0.2)
    parser.add_argument("--seed", type=argparse_number(int, 0), default=881000,
                        help="the map's and world's seed")
    args = parser.parse_args(argv)
    if args.density > 0.6:
        parser.error(f"--density must be at most 0.6, got {args.density}")
    config = AOASSConfig(obstacle_density=args.density)
    rng = np.random.default_rng(args.seed)
    obstacle_map = generate_map(config.field_size, args.density, rng)
    start = obstacle_map.sample_free_points(1, rng, clearance=1.0)[0]
    world = World(config, obstacle_map, rng, tuple(start.tolist()))
    shapes = world._ray_shapes
    if shapes is None:
        sys.exit("the compiled rays are not Chipmunk's on this machine (aoass_env.rays."
                 "compiled_rays() is False): the world queries the space ray by ray")
    compiled = chipmunk = 0.0
    hits = 0
    for step in range(args.steps):
        world.step(float(rng.uniform(0.0, 1.0)), float(rng.uniform(-4.0, 4.0)))
        order = (True, False) if step % 2 else (False, True)
        out = {}
        for fast in order:
            world._ray_shapes = shapes if fast else None
            t = time.perf_counter()
            out[fast] = world.ray_distances()
            spent = time.perf_counter() - t
            if fast:
                compiled += spent
            else:
                chipmunk += spent
        world._ray_shapes = shapes
        if out[True].tobytes() != out[False].tobytes():
            sys.exit(f"step {step}: the compiled rays read {out[True].tolist()}, Chipmunk "
                     f"{out[False].tolist()}")
        hits += int((out[False] < config.sensing_range).sum())
    n = args.steps
    print(f"{config.n_rays} rays on a {config.field_size:g} m map of density {args.density} "
          f"(seed {args.seed}), {n} readings, {hits / (n * config.n_rays):.0%} of the rays hit:")
    print(f"  Chipmunk, ray by ray : {1e6 * chipmunk / n:6.2f} us per reading")
    print(f"  compiled (one call)  : {1e6 * compiled / n:6.2f} us per reading, "
          f"{chipmunk / compiled:.2f} x faster; every reading identical to the bit")


if __name__ == "__main__":
    main()
