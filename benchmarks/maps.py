"""Speed of the obstacle-map generator.

    python3 benchmarks/maps.py [--seeds 5]

Prints the median time of ``generate_map`` for a 200 x 200 m field at density 0.6 against the
2 s target, the same for 100 x 100 m at density 0.4, and, as a reference measured in the same
process, the time of one map-wide shapely traversability check (``check_traversable``) of the
finished 200 m map -- the check a naive generator would repeat for every candidate shape.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from aoass_env.config import AOASSConfig
from aoass_env.maps import ObstacleMap, generate_map
from aoass_env.validators import argparse_number

CLEARANCE = AOASSConfig().map_clearance  # the default the shipped maps use (m)

TARGET_S = 2.0


def timed_maps(size: float, density: float, seeds: int) -> tuple[float, ObstacleMap]:
    """Median seconds of ``generate_map(size, density)`` over ``seeds`` seeds, and a map."""
    times = []
    for seed in range(seeds):
        start = time.perf_counter()
        obstacle_map = generate_map(size, density, np.random.default_rng(seed),
                                    clearance=CLEARANCE)
        times.append(time.perf_counter() - start)
    return statistics.median(times), obstacle_map


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=argparse_number(int, 1),
                        default=5, help="maps per case (default 5)")
    args = parser.parse_args()
    generate_map(50, 0.3, np.random.default_rng(0))  # warm-up: imports, GEOS, caches

    big, big_map = timed_maps(200, 0.6, args.seeds)
    small, _ = timed_maps(100, 0.4, args.seeds)
    checks = []
    for _ in range(5):
        fresh = ObstacleMap(big_map.width, big_map.height, big_map.polygons)
        start = time.perf_counter()
        fresh.check_traversable(CLEARANCE)
        checks.append(time.perf_counter() - start)
    check = statistics.median(checks)

    print(f"generate_map 200x200 m @ 0.6: median {big:.3f} s over {args.seeds} seeds "
          f"(target {TARGET_S:.1f} s, ratio {big / TARGET_S:.2f})")
    print(f"generate_map 100x100 m @ 0.4: median {small:.3f} s over {args.seeds} seeds")
    print(f"one map-wide check_traversable of a 200 m @ 0.6 map: {check * 1e3:.1f} ms; "
          f"generating the map costs {big / check:.0f} such checks")


if __name__ == "__main__":
    main()
