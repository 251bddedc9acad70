"""Speed of the radio model on a cluttered field.

Setup: a generated 100 x 100 m map of obstacle density 0.4, N = 1000 nodes uniform in free
space, R = 25 m, line of sight on. Prints

* ``Radio.receivers``: microseconds per beacon (target < 300 us), best of three passes;
* the ratio to a plain-Python reference measured in the same run (target >= 20x): for every
  node within R it tests the segment against every obstacle edge with pure-Python loops;
  both must return the same receivers;
* ``Radio.node_links`` for all N nodes (seconds, best of three fresh radios).

Run: ``python3 benchmarks/radio.py [--nodes 1000] [--density 0.4] [--seed 0]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from aoass_env.maps import generate_map
from aoass_env.maps.generator import MAX_DENSITY
from aoass_env.radio import Radio
from aoass_env.validators import argparse_number


def reference_receivers(nodes: list[tuple[float, float]],
                        edges: list[tuple[float, float, float, float]],
                        point: tuple[float, float], radio_range: float) -> list[int]:
    """Nodes within ``radio_range`` whose segment to ``point`` crosses no edge (pure Python)."""
    ax, ay = point
    r2 = radio_range * radio_range
    heard = []
    for i, (bx, by) in enumerate(nodes):
        if (bx - ax) ** 2 + (by - ay) ** 2 > r2:
            continue
        blocked = False
        for px, py, qx, qy in edges:
            o1 = (bx - ax) * (py - ay) - (by - ay) * (px - ax)
            o2 = (bx - ax) * (qy - ay) - (by - ay) * (qx - ax)
            o3 = (qx - px) * (ay - py) - (qy - py) * (ax - px)
            o4 = (qx - px) * (by - py) - (qy - py) * (bx - px)
            if o1 * o2 < 0 and o3 * o4 < 0:
                blocked = True
                break
        if not blocked:
            heard.append(i)
    return heard


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--nodes", type=argparse_number(int, 1), default=1000)
    parser.add_argument("--density", type=argparse_number(float, 0.0, high=MAX_DENSITY),
                        default=0.4)
    parser.add_argument("--range", type=argparse_number(float, 0, True),
                        default=25.0, dest="radio_range")
    parser.add_argument("--beacons", type=argparse_number(int, 1), default=1000)
    parser.add_argument("--reference-beacons", type=argparse_number(int, 1), default=20)
    parser.add_argument("--seed", type=argparse_number(int, 0), default=0)
    args = parser.parse_args()

    rng = np.random.default_rng(args.seed)
    obstacle_map = generate_map(100.0, args.density, rng)
    nodes = obstacle_map.sample_free_points(args.nodes, rng)
    beacons = obstacle_map.sample_free_points(args.beacons, rng)
    radio = Radio(nodes, obstacle_map, args.radio_range)
    print(f"map: density {obstacle_map.density:.3f}, {len(obstacle_map.polygons)} obstacles, "
          f"{len(obstacle_map.edges)} edges; N={args.nodes}, R={args.radio_range:g} m")

    passes = []
    heard = 0
    for _ in range(3):
        start = time.perf_counter()
        heard = sum(len(radio.receivers(p)) for p in beacons)
        passes.append((time.perf_counter() - start) / len(beacons))
    fast = min(passes)
    print(f"receivers: {fast * 1e6:.1f} us per beacon (target < 300 us), "
          f"{heard / len(beacons):.1f} receivers per beacon on average")

    node_list = [(float(x), float(y)) for x, y in nodes]
    edge_list = [tuple(float(v) for v in e.ravel()) for e in obstacle_map.edges]
    sample = beacons[:args.reference_beacons]
    start = time.perf_counter()
    expected = [reference_receivers(node_list, edge_list, (float(p[0]), float(p[1])),
                                    args.radio_range) for p in sample]
    slow = (time.perf_counter() - start) / len(sample)
    for p, ref in zip(sample, expected, strict=True):
        got = radio.receivers(p).tolist()
        if got != ref:
            raise SystemExit(f"receivers at {p} differ from the reference: {got} != {ref}")
    print(f"plain-Python reference: {slow * 1e6:.0f} us per beacon; "
          f"speed-up {slow / fast:.0f}x (target >= 20x)")

    times = []
    links = np.zeros((0, 2))
    for _ in range(3):
        fresh = Radio(nodes, obstacle_map, args.radio_range)
        start = time.perf_counter()
        links = fresh.node_links()
        times.append(time.perf_counter() - start)
    print(f"node_links: {min(times):.3f} s for N={args.nodes} ({len(links)} links)")


if __name__ == "__main__":
    main()
