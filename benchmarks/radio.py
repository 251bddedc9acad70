"""Speed of the radio model on a cluttered field.

Setup: a generated 100 x 100 m map of obstacle density 0.4, N = 1000 nodes uniform in free
space, R = 25 m, line of sight on. Prints

* ``Radio.receivers``: microseconds per beacon over ``--beacons`` beacons (target < 300 us),
  best of three passes;
* the ratio to a plain-Python reference (target >= 20x): for every node within R it tests the
  segment against every obstacle edge with pure-Python loops. The reference is slow (about
  0.1 s per beacon at the defaults), so both sides are timed on the same first
  ``--reference-beacons`` beacons (20), best of three passes each, the two sides in turn and
  the first side alternating (``git_history.in_turn``); both must return the same receivers;
* ``Radio.node_links`` for all N nodes (seconds, best of three fresh radios).

Run: ``python3 benchmarks/radio.py [--nodes 1000] [--density 0.4] [--seed 0]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from git_history import in_turn

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


#: timed passes of each side (the best is kept)
PASSES = 3


def compared(radio: Radio, beacons: np.ndarray
             ) -> tuple[float, float, list[list[int]], list[list[int]]]:
    """(best seconds per beacon of ``radio.receivers``, the same of :func:`reference_receivers`,
    the receivers each gave) over the same ``beacons``: :data:`PASSES` passes of each, the two
    in turn, the reference first in the passes 0, 2, ... (``in_turn``)."""
    nodes = [(float(x), float(y)) for x, y in radio.nodes]
    edges = [tuple(float(v) for v in e.ravel()) for e in radio.obstacle_map.edges]
    points = [(float(x), float(y)) for x, y in beacons]
    sides = {"radio": lambda: [radio.receivers(p).tolist() for p in beacons],
             "reference": lambda: [reference_receivers(nodes, edges, p, radio.radio_range)
                                   for p in points]}
    best = {side: float("inf") for side in sides}
    heard: dict[str, list[list[int]]] = {}
    for k in range(PASSES):
        for side in in_turn(k, "reference", "radio"):
            start = time.perf_counter()
            heard[side] = sides[side]()
            best[side] = min(best[side], (time.perf_counter() - start) / len(beacons))
    return best["radio"], best["reference"], heard["radio"], heard["reference"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--nodes", type=argparse_number(int, 1), default=1000)
    parser.add_argument("--density", type=argparse_number(float, 0.0, high=MAX_DENSITY),
                        default=0.4)
    parser.add_argument("--range", type=argparse_number(float, 0, True),
                        default=25.0, dest="radio_range")
    parser.add_argument("--beacons", type=argparse_number(int, 1), default=1000)
    parser.add_argument("--reference-beacons", type=argparse_number(int, 1), default=20,
                        help="the first beacons both sides are timed on (the reference is slow)")
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
    for _ in range(PASSES):
        start = time.perf_counter()
        heard = sum(len(radio.receivers(p)) for p in beacons)
        passes.append((time.perf_counter() - start) / len(beacons))
    print(f"receivers: {min(passes) * 1e6:.1f} us per beacon over {len(beacons)} beacons "
          f"(target < 300 us), {heard / len(beacons):.1f} receivers per beacon on average")

    sample = beacons[:args.reference_beacons]
    fast, slow, got, expected = compared(radio, sample)
    for p, mine, ref in zip(sample, got, expected, strict=True):
        if mine != ref:
            raise SystemExit(f"receivers at {p} differ from the reference: {mine} != {ref}")
    print(f"on the same first {len(sample)} beacons, best of {PASSES} passes each: receivers "
          f"{fast * 1e6:.1f} us, plain-Python reference {slow * 1e6:.0f} us per beacon; "
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
