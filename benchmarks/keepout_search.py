"""The follower's keep-out re-plan: the reweighted grid against a whole-graph mask, in one process.

When the follower got stuck, it re-plans round the spot with the grid edges near it made
:data:`~aoass_env.planning.detour.KEEPOUT_COST` times dearer
(``DetourPlanner._reweighted``). This script builds that graph on generated maps both ways:
the planner's (only the entries of the near cells' rows and, through each entry's reverse,
their columns) and the reference it replaced (two boolean masks over every entry of the graph,
inline below), checks that the two give the same floats, and prints milliseconds per graph and
their ratio, with the one-off cost of the reverse index per map.

Run: ``python3 benchmarks/keepout_search.py [--repeat N]``.
"""

from __future__ import annotations

import argparse
import math
import time
import timeit

import numpy as np
from scipy.sparse import csr_matrix

from aoass_env.maps import generate_map
from aoass_env.planning.detour import KEEPOUT_COST, DetourPlanner
from aoass_env.planning.follower import KEEPOUT_RADIUS

#: (field side m, density) of the maps timed; map k is drawn from default_rng([8080, k]).
MAPS = ((100.0, 0.3), (100.0, 0.5), (200.0, 0.3))


def masked(planner: DetourPlanner, cells: np.ndarray, factor: float) -> csr_matrix:
    """The reference: every entry whose row, then whose column, is a masked cell, scaled."""
    graph = planner._graph
    rows = np.repeat(np.arange(graph.shape[0], dtype=graph.indices.dtype),
                     np.diff(graph.indptr))
    data = graph.data.copy()
    data[cells[rows]] *= factor
    data[cells[graph.indices]] *= factor
    return csr_matrix((data, graph.indices, graph.indptr), shape=graph.shape)


def measure(side: float, density: float, k: int, repeat: int) -> tuple[float, float, float]:
    """(reference ms, planner ms, reverse index ms) on map ``k`` with two keep-outs at its
    centre; raises when the two graphs differ in a single bit."""
    planner = DetourPlanner(generate_map(side, density, np.random.default_rng([8080, k])), 0.55)
    keepout = np.array([[side / 2, side / 2], [side / 2 + 2.0, side / 2 - 1.0]])
    cells = planner._near(keepout, KEEPOUT_RADIUS)
    factor = math.sqrt(KEEPOUT_COST)
    start = time.perf_counter()
    got = planner._reweighted(cells, factor)              # builds the reverse index
    first = time.perf_counter() - start
    want = masked(planner, cells, factor)
    if not np.array_equal(got.data.view(np.uint64), want.data.view(np.uint64)):
        raise AssertionError(f"the reweighted graphs differ on the {side:g} m map")
    ref = min(timeit.repeat(lambda: masked(planner, cells, factor), number=repeat, repeat=3))
    new = min(timeit.repeat(lambda: planner._reweighted(cells, factor), number=repeat, repeat=3))
    return 1e3 * ref / repeat, 1e3 * new / repeat, 1e3 * first - 1e3 * new / repeat


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=100, help="graphs per timing")
    args = parser.parse_args(argv)
    if args.repeat < 1:
        parser.error(f"--repeat must be an integer >= 1, got {args.repeat}")
    print("keep-out graph per re-plan (ms): whole-graph masks against the planner's")
    for k, (side, density) in enumerate(MAPS):
        ref, new, reverse = measure(side, density, k, args.repeat)
        print(f"{side:5.0f} m, density {density:.1f}: masks {ref:7.3f}  planner {new:7.3f}  "
              f"({ref / new:5.1f} x)  reverse index, once per map: {reverse:6.1f} ms")


if __name__ == "__main__":
    main()
