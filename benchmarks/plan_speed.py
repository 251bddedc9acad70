"""The adaptive rule's pruned plan on fresh maps against an earlier commit's pruning module.

    python3 benchmarks/plan_speed.py [--against 3c3f17c] [--maps 4] [--density 0.3] [--rounds 2]

Before it moves, the rule prunes the spiral on the static map (``aoass_env.planning.pruning``);
on a fresh 100 m map that takes seconds, most of an episode of ``aoass-rule`` in the simulator
(plans are cached per map, so only the first episode on a map pays). This script times
``prune_spiral`` on ``--maps`` freshly generated maps (map k from ``default_rng([SEED, k])``)
with the current module and with ``aoass_env/planning/pruning.py`` of ``--against`` (read with
``git show``), alternating, each run with its own planner search state, and checks that both
give the same plan bit for bit. Prints the CPU seconds per plan of both (medians) and the median
of the per-map ratios.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
from reset import module_at

from aoass_env.config import AOASSConfig
from aoass_env.maps import generate_map
from aoass_env.planning import pruning
from aoass_env.planning.detour import DETOUR_MARGIN, DetourPlanner
from aoass_env.simulator import Simulator

#: the commit before the batched measure of the ways
BEFORE = "3c3f17c"
SEED = 4242


def plan_once(module, sim: Simulator, config: AOASSConfig) -> tuple[float, object]:
    """CPU seconds of one ``prune_spiral`` of ``module`` on ``sim``'s spiral, and the plan."""
    planner = DetourPlanner.for_map(sim.map, config.anchor_radius + DETOUR_MARGIN)
    cov = sim.coverage_map
    start = time.process_time()
    plan = module.prune_spiral(sim.path.waypoints, sim.path.blocked, sim.start_index, planner,
                               cov.radio, cov.n_cells, config.beacon_interval,
                               config.collinearity_tol, (6.0, 2.0))
    return time.process_time() - start, plan


def same_plan(a: object, b: object) -> bool:
    return all(np.array_equal(getattr(a, f), getattr(b, f)) for f in ("kept", "order",
                                                                       "reference")) and (
        a.length, a.full_length) == (b.length, b.full_length)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", default=BEFORE, help="the reference commit")
    parser.add_argument("--maps", type=int, default=4)
    parser.add_argument("--density", type=float, default=0.3)
    parser.add_argument("--field", type=float, default=100.0)
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    if min(args.maps, args.rounds) < 1:
        parser.error("--maps and --rounds must be at least 1")
    with tempfile.TemporaryDirectory() as tmp:
        old = module_at(args.against, "aoass_env/planning/pruning.py", Path(tmp))
    config = AOASSConfig(field_size=args.field, obstacle_density=args.density)
    times: dict[str, list[float]] = {"now": [], args.against: []}
    ratios, same = [], True
    for k in range(args.maps):
        obstacle_map = generate_map(args.field, args.density, np.random.default_rng([SEED, k]))
        sim = Simulator(config, np.random.default_rng(k), obstacle_map=obstacle_map)
        spent = {"now": [], args.against: []}
        for _ in range(args.rounds):
            for name, module in (("now", pruning), (args.against, old)):
                seconds, plan = plan_once(module, sim, config)
                spent[name].append(seconds)
                if name == "now":
                    mine = plan
                else:
                    same &= same_plan(mine, plan)
        for name in times:
            times[name].append(min(spent[name]))
        ratios.append(min(spent[args.against]) / min(spent["now"]))
        print(f"map {k}: {min(spent['now']):.2f} s now, {min(spent[args.against]):.2f} s at "
              f"{args.against}", flush=True)
    print(f"\nprune_spiral, {args.maps} fresh {args.field:g} m maps at density {args.density:g} "
          f"(CPU s per plan, median of the per-map minima over {args.rounds} rounds)")
    print(f"now: {statistics.median(times['now']):.2f} s; {args.against}: "
          f"{statistics.median(times[args.against]):.2f} s; speed-up (median of per-map "
          f"ratios): {statistics.median(ratios):.2f}x; plans identical: {same}")


if __name__ == "__main__":
    main()
