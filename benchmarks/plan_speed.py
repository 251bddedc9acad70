"""The adaptive rule's pruned plan on fresh maps against an earlier commit's pruning module.

    python3 benchmarks/plan_speed.py [--against 3c3f17c] [--maps 4] [--density 0.3] [--rounds 2]

Before it moves, the rule prunes the spiral on the static map (``aoass_env.planning.pruning``);
on a fresh 100 m map that takes seconds, most of an episode of ``aoass-rule`` in the simulator
(plans are cached per map, so only the first episode on a map pays). This script times
``prune_spiral`` on ``--maps`` freshly generated maps (map k from ``default_rng([SEED, k])``)
with the current module and with ``aoass_env/planning/pruning.py`` of ``--against`` (read with
``git show``), in turn ``--rounds`` times per map (the current module first in the
odd-numbered rounds 1, 3, ..., second in the even ones: ``git_history.in_turn``), each run
with its own planner search state, after one untimed plan of each on a small map of its own
(the compiled kernels' first calls), and checks that both give the same plan bit for bit. Prints
the CPU seconds per plan of both (medians) and the median of the per-map ratios.
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
from git_history import in_turn, module_at

from aoass_env.config import AOASSConfig
from aoass_env.maps import MAX_DENSITY, generate_map
from aoass_env.planning import pruning
from aoass_env.planning.detour import DETOUR_MARGIN, DetourPlanner
from aoass_env.simulator import Simulator
from aoass_env.validators import argparse_number, one_line

#: the commit before the batched measure of the ways
BEFORE = "3c3f17c"
SEED = 4242
#: the untimed warm-up plan's map: field side (m) and seed, apart from the timed maps' seeds
WARM_UP_FIELD, WARM_UP_SEED = 60.0, 9999


def plan_once(module, sim: Simulator, config: AOASSConfig) -> tuple[float, object]:
    """CPU seconds of one ``prune_spiral`` of ``module`` on ``sim``'s spiral, and the plan."""
    planner = DetourPlanner.for_map(sim.map, config.anchor_radius + DETOUR_MARGIN)
    cov = sim.coverage_map
    start = time.process_time()
    plan = module.prune_spiral(sim.path.waypoints, sim.path.blocked, sim.start_index, planner,
                               cov.radio, cov.n_cells, config.beacon_interval,
                               config.collinearity_tol, (6.0, 2.0))
    return time.process_time() - start, plan


#: what :func:`same_plan` compares of two plans
PLAN_FIELDS = ("kept", "order", "reference", "length", "full_length")


def same_plan(a: object, b: object) -> bool:
    return all(np.array_equal(getattr(a, f), getattr(b, f)) for f in ("kept", "order",
                                                                       "reference")) and (
        a.length, a.full_length) == (b.length, b.full_length)


def api_gap(module) -> str | None:
    """What a pruning module lacks of the API :func:`plan_once` and :func:`same_plan` use
    (``prune_spiral`` taking its nine arguments, ``PrunedPlan`` with :data:`PLAN_FIELDS`), or
    None when it has it all."""
    function, plan = getattr(module, "prune_spiral", None), getattr(module, "PrunedPlan", None)
    if function is None or plan is None or not dataclasses.is_dataclass(plan):
        return "no prune_spiral and PrunedPlan dataclass"
    try:
        inspect.signature(function).bind(*range(9))
    except TypeError as err:
        return f"prune_spiral {err}"
    missing = [f for f in PLAN_FIELDS if f not in {g.name for g in dataclasses.fields(plan)}]
    return f"its PrunedPlan has no {', '.join(missing)}" if missing else None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", default=BEFORE, help="the reference commit")
    parser.add_argument("--maps", type=int, default=4)
    parser.add_argument("--density", type=argparse_number(float, 0.0, high=MAX_DENSITY),
                        default=0.3)
    field = AOASSConfig.__dataclass_fields__["field_size"].metadata
    parser.add_argument("--field", type=argparse_number(float, field["low"], high=field["high"]),
                        default=100.0)
    parser.add_argument("--rounds", type=int, default=2,
                        help="plans of each module per map, in turn, the order swapped each round")
    args = parser.parse_args()
    if min(args.maps, args.rounds) < 1:
        parser.error("--maps and --rounds must be at least 1")
    with tempfile.TemporaryDirectory() as tmp:
        old = module_at(args.against, "aoass_env/planning/pruning.py", Path(tmp))
    gap = api_gap(old)      # an AttributeError once the first map's timing had run
    if gap:
        parser.error(f"--against {args.against}: predates the API this script compares ({gap}); "
                     f"choose a later commit, e.g. the default {BEFORE}")
    config = AOASSConfig(field_size=args.field, obstacle_density=args.density)
    try:        # every map and simulator before the timing: a combination they cannot meet
        sims = [Simulator(config, np.random.default_rng(k), obstacle_map=generate_map(
            args.field, args.density, np.random.default_rng([SEED, k]))) for k in range(args.maps)]
    except ValueError as err:       # MapError, or no room for the moving obstacles
        parser.error(f"--field {args.field:g} with --density {args.density:g}: {one_line(err)}")
    # one untimed plan of each module first, on a map of its own: the compiled kernels'
    # first calls (compilation or cache loading) stay out of the timings, whatever --rounds
    warm_config = AOASSConfig(field_size=WARM_UP_FIELD, obstacle_density=0.2)
    warm = Simulator(warm_config, np.random.default_rng(WARM_UP_SEED), obstacle_map=generate_map(
        WARM_UP_FIELD, 0.2, np.random.default_rng([SEED, WARM_UP_SEED])))
    for module in (pruning, old):
        plan_once(module, warm, warm_config)
    times: dict[str, list[float]] = {"now": [], args.against: []}
    ratios, same = [], True
    for k, sim in enumerate(sims):
        spent = {"now": [], args.against: []}
        for i in range(args.rounds):
            plans = {}
            for name, module in in_turn(i, ("now", pruning), (args.against, old)):
                seconds, plans[name] = plan_once(module, sim, config)
                spent[name].append(seconds)
            same &= same_plan(plans["now"], plans[args.against])
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
