"""Regenerate the measured tables of docs/baselines.md: the reconstructed baselines on the
shipped 100 m test maps.

    python3 scripts/baselines_table.py [--table {measured,fdpp-budget,otpp,all}]

``measured`` ("Measured behaviour"): OHM, FDPP, M-ANCHORO and OTPP, each on the first shipped
100 m test map of every density 0.1-0.6, N = 100 nodes, seed 0, no moving obstacles, default
config otherwise (the episode of ``evaluate.py``'s runner, less the moving obstacles, so that
the planners are compared alone): the planned path (m, Eq. 19's ideal), the distance driven
(m), coverage (Eq. 18), anchor contacts and wall seconds per episode (plan and run).

``fdpp-budget`` (FDPP's "Measured" item): FDPP at 1.0 x and 1.5 x its travel budget (the
square spiral's length) on the same maps, seeds 0-2, default config with its moving obstacles:
coverage per seed and their mean, the mean distance driven (m), contacts summed over the three
episodes and wall seconds per episode.

``otpp`` (OTPP's "Dense maps" and "Planning time" items): on the first shipped test map of every
density 0.1-0.6, 100 m and 200 m, the sub-squares whose ``reg`` is not empty (Lemma 2's premise,
``otpp.served_sub_squares``) out of those with free samples, and the wall seconds of OTPP's plan
(``otpp.plan``) and of its beacon points alone (``otpp.beacon_points``; the rest is the links).

Wall seconds depend on the machine and its load; every other number is the same on every run
with the same OpenBLAS kernels. FDPP's budget episodes (with moving obstacles) depend on them
(docs/evaluation.md): docs/baselines.md's table is run as ``OPENBLAS_CORETYPE=Haswell python3
scripts/baselines_table.py --table fdpp-budget``, the kernels the tests pin.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence

import numpy as np

from aoass_env.config import AOASSConfig
from aoass_env.evaluation.methods import METHODS, RunOptions
from aoass_env.maps import MAPS_DIR, list_maps, load_map
from aoass_env.maps.text_format import read_map
from aoass_env.planning.baselines import BASELINE_METHODS, otpp
from aoass_env.planning.baselines.fdpp import FDPP, FDPPController
from aoass_env.simulator import Simulator

#: Obstacle densities of the tables; each uses the first shipped 100 m test map of the density.
DENSITIES = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6)
#: FDPP's travel budgets, as multiples of the square spiral's length.
BUDGETS = (1.0, 1.5)
#: Episode seeds of FDPP's budget table.
FDPP_SEEDS = (0, 1, 2)


#: Field sides (m) of OTPP's table.
OTPP_FIELDS = (100.0, 200.0)


def first_test_map(density: float, field_size: float = 100.0) -> str:
    """The first shipped test map of ``density`` and side ``field_size`` (m) (its name)."""
    return list_maps("test", field_size=field_size, densities=(density, density))[0]


def measured_rows(methods: Sequence[str] = tuple(BASELINE_METHODS),
                  densities: Sequence[float] = DENSITIES) -> list[str]:
    """The rows of the "Measured behaviour" table (markdown), method by method: planned and
    driven path (m), coverage (Eq. 18), contacts and wall seconds per episode."""
    rows = []
    for method in methods:
        for density in densities:
            name = first_test_map(density)
            config = AOASSConfig(field_size=100.0, n_nodes=100, n_moving_obstacles=0, map=name)
            t0 = time.perf_counter()
            run = METHODS[method].runner(config, load_map(name), 0, RunOptions())
            seconds = time.perf_counter() - t0
            rows.append(f"| {BASELINE_METHODS[method].label.removesuffix(' (reconstructed)')} "
                        f"| {name.removeprefix('test/')} | {run.sim.path.length:.0f} "
                        f"| {run.sim.network.distance_travelled:.0f} "
                        f"| {run.sim.network.coverage_ratio:.2f} | {run.sim.collisions} "
                        f"| {seconds:.2f} |")
    return rows


def fdpp_episode(name: str, seed: int, budget: float) -> tuple[float, float, int, float]:
    """FDPP on shipped map ``name`` with ``seed`` and ``budget`` times the spiral's length:
    coverage, distance driven (m), contacts and wall seconds."""
    config = AOASSConfig(field_size=100.0, n_nodes=100, map=name)
    t0 = time.perf_counter()
    obstacle_map = load_map(name)
    sim = Simulator(config, np.random.default_rng(seed), obstacle_map=obstacle_map, seed=seed,
                    method=FDPP.name, path=FDPP.plan(obstacle_map, config))
    controller = FDPPController(sim, budget=budget * sim.spiral.length)
    sim.run(max_steps=sim.step_limit(), controller=controller)
    return (sim.network.coverage_ratio, sim.network.distance_travelled, sim.collisions,
            time.perf_counter() - t0)


def fdpp_budget_rows(densities: Sequence[float] = DENSITIES,
                     seeds: Sequence[int] = FDPP_SEEDS) -> list[str]:
    """The rows of FDPP's budget table (markdown), one per density: per budget, coverage per
    seed and their mean, the mean distance driven (m), contacts summed and wall seconds per
    episode."""
    rows = []
    for density in densities:
        cells = [f"{density:.1f}"]
        for budget in BUDGETS:
            runs = [fdpp_episode(first_test_map(density), seed, budget) for seed in seeds]
            coverage, path, contacts, seconds = np.array(runs).T
            cells += [" / ".join(f"{c:.2f}" for c in coverage), f"{coverage.mean():.2f}",
                      f"{path.mean():.0f}", f"{contacts.sum():.0f}", f"{seconds.mean():.2f}"]
        rows.append("| " + " | ".join(cells) + " |")
    return rows


def otpp_rows(fields: Sequence[float] = OTPP_FIELDS,
              densities: Sequence[float] = DENSITIES) -> list[str]:
    """The rows of OTPP's table (markdown), one per map: sub-squares with a non-empty ``reg``
    out of those with free samples, the wall seconds of the plan and of its beacon points, each
    timed on the map read afresh (a map keeps what it derives: the region, the planner's grid)."""
    rows = []
    for field_size in fields:
        config = AOASSConfig(field_size=field_size)
        for density in densities:
            name = first_test_map(density, field_size)
            seconds = []
            for step in (otpp.plan, otpp.beacon_points):
                obstacle_map = read_map(MAPS_DIR / f"{name}.txt")
                t0 = time.perf_counter()
                step(obstacle_map, config)
                seconds.append(time.perf_counter() - t0)
            served, squares = otpp.served_sub_squares(load_map(name), config)
            rows.append(f"| {name.removeprefix('test/')} | {served}/{squares} "
                        f"| {seconds[0]:.2f} | {seconds[1]:.2f} |")
    return rows


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--table", choices=("measured", "fdpp-budget", "otpp", "all"),
                        default="all", help="which table to print (default: all)")
    args = parser.parse_args(argv)
    if args.table in ("measured", "all"):
        print("| method | map | planned (m) | path (m) | coverage | contacts | s/episode |")
        print("|---|---|---|---|---|---|---|")
        for row in measured_rows():
            print(row, flush=True)
        print()
    if args.table in ("fdpp-budget", "all"):
        budgets = [f"{b:.1f}×" for b in BUDGETS]
        seeds = "/".join(str(s) for s in FDPP_SEEDS)
        print(f"| density | coverage, budget {budgets[0]} (seeds {seeds}) | mean | path (m) "
              f"| contacts | s/ep | coverage {budgets[1]} | mean | path (m) | contacts | s/ep |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        for row in fdpp_budget_rows():
            print(row, flush=True)
        print()
    if args.table in ("otpp", "all"):
        print("| map | sub-squares with reg | plan (s) | of it, beacon points (s) |")
        print("|---|---|---|---|")
        for row in otpp_rows():
            print(row, flush=True)


if __name__ == "__main__":
    main()
