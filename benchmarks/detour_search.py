"""The detour planner's searches against an earlier commit's planner, on recorded calls.

    python3 benchmarks/detour_search.py [--against 6d39d57] [--steps 20000] [--seeds 0,1,2]
                                        [--field 100] [--density 0.2]

Random-action episodes of AOASS-v0 (the issue-20 measure: resets included; the default config
unless ``--field`` or ``--density`` say otherwise) record every call
the follower makes to its detour planner (``path`` with and without keep-outs, ``costs``),
with the map each planner plans on. The calls are then replayed map by map, in the order made,
on a fresh planner of this tree and on one of ``--against`` (its
``aoass_env/planning/detour.py`` read with ``git show``; the rest is this tree's), in one
process, alternating which goes first. Prints the milliseconds per call of both, their ratio,
the steps' share, and whether every answer is the same to the bit (the planner's state, its
kept search tree, carries from call to call as in the episode). The earlier planner searches
this tree's grid (its free cells, their graph and main region, built before the clock starts):
the free cells are exact since 2026-11-30 (cells a thin wall or spike blocks), and what is
compared is the searches.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from git_history import module_at

import aoass_env  # noqa: F401  (registers AOASS-v0)
from aoass_env.planning import detour

#: the commit before the compiled goal search (issue 20's eighteenth round)
BEFORE = "6d39d57"


def record(seeds: list[int], steps: int, **config: Any) -> list[tuple[tuple, list[tuple]]]:
    """[(planner arguments (map, radius, resolution), [calls in order])] of the planners the
    episodes (AOASS-v0 with ``config``) built; a call is ``("path", start, goal, keepout,
    radius)`` or ``("costs", start, goals)``, arrays copied."""
    planners: dict[int, tuple[tuple, list[tuple]]] = {}
    keep: list[Any] = []                 # the planners stay alive: their ids stay theirs
    for_map, path, costs = (detour.DetourPlanner.for_map, detour.DetourPlanner.path,
                            detour.DetourPlanner.costs)

    def recording_for_map(cls: type, obstacle_map: Any, radius: float,
                          resolution: float = 0.5) -> Any:
        planner = for_map.__func__(cls, obstacle_map, radius, resolution)
        keep.append(planner)
        planners[id(planner)] = ((obstacle_map, radius, resolution), [])
        return planner

    def recording_path(self: Any, start: Any, goal: Any, keepout: Any = None,
                       keepout_radius: float = 0.0) -> Any:
        planners[id(self)][1].append(
            ("path", np.array(start, float), np.array(goal, float),
             None if keepout is None else np.array(keepout, float), keepout_radius))
        return path(self, start, goal, keepout, keepout_radius)

    def recording_costs(self: Any, start: Any, goals: Any) -> Any:
        planners[id(self)][1].append(("costs", np.array(start, float), np.array(goals, float)))
        return costs(self, start, goals)

    detour.DetourPlanner.for_map = classmethod(recording_for_map)
    detour.DetourPlanner.path, detour.DetourPlanner.costs = recording_path, recording_costs
    try:
        for seed in seeds:
            env = gym.make("AOASS-v0", **config)
            env.reset(seed=seed)
            env.action_space.seed(seed)
            for _ in range(steps):
                _, _, terminated, truncated, _ = env.step(env.action_space.sample())
                if terminated or truncated:
                    env.reset()
            env.close()
    finally:
        detour.DetourPlanner.for_map = classmethod(for_map.__func__)
        detour.DetourPlanner.path, detour.DetourPlanner.costs = path, costs
    return [entry for entry in planners.values() if entry[1]]


def replay(planner_class: type, arguments: tuple, calls: list[tuple]) -> tuple[float, list]:
    """(seconds, answers) of ``calls`` on a fresh planner of ``planner_class`` (its grid built
    before the clock starts)."""
    planner = planner_class(*arguments)
    answers = []
    start = time.perf_counter()
    for call in calls:
        if call[0] == "path":
            answers.append(planner.path(*call[1:]))
        else:
            answers.append(planner.costs(*call[1:]))
    return time.perf_counter() - start, answers


def on_this_grid(planner_class: type) -> Any:
    """A builder of ``planner_class`` planners (an earlier commit's) that search this tree's
    grid: the free cells, the nearest free cell of each cell, the graph and the main region of
    a planner of this tree on the same arguments replace its own."""
    def build(*arguments: Any) -> Any:
        planner, now = planner_class(*arguments), detour.DetourPlanner(*arguments)
        for name in ("free", "_nearest", "_graph", "_main"):
            setattr(planner, name, getattr(now, name))
        planner._degree = int(np.diff(now._graph.indptr).max(initial=0))
        return planner
    return build


def same(a: list, b: list) -> bool:
    """Whether two lists of answers (arrays or None) are equal to the bit."""
    return len(a) == len(b) and all(
        (x is None and y is None) or (x is not None and y is not None and x.shape == y.shape
                                      and np.array_equal(x.view(np.uint64), y.view(np.uint64)))
        for x, y in zip(a, b, strict=True))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--against", default=BEFORE, help=f"earlier commit (default {BEFORE})")
    parser.add_argument("--steps", type=int, default=20_000,
                        help="random steps per seed (default 20000)")
    parser.add_argument("--seeds", default="0,1,2", help="comma-separated (default 0,1,2)")
    parser.add_argument("--field", type=float, default=None, help="field side (m; default the "
                        "config's, 100)")
    parser.add_argument("--density", type=float, default=None, help="obstacle density (default "
                        "the config's, 0.2)")
    args = parser.parse_args(argv)
    try:
        seeds = [int(s) for s in args.seeds.split(",")]
    except ValueError:
        seeds = [-1]
    if min(seeds) < 0:          # a negative seed failed in numpy's seeding, after the checkout
        parser.error(f"--seeds must be comma-separated integers >= 0, got {args.seeds!r}")
    if args.steps < 1:
        parser.error(f"--steps must be an integer >= 1, got {args.steps}")
    with tempfile.TemporaryDirectory() as folder:
        old = module_at(args.against, "aoass_env/planning/detour.py", Path(folder))
    config = {key: value for key, value in (("field_size", args.field),
                                             ("obstacle_density", args.density))
              if value is not None}
    try:
        gym.make("AOASS-v0", **config).close()
    except ValueError as err:                  # the config's own one-line message
        parser.error(str(err).splitlines()[0])
    recorded = record(seeds, args.steps, **config)
    if not recorded:                # printed 0.000 ms per call and exited 0
        parser.error(f"--steps {args.steps}: the episodes (seeds {args.seeds}) made no detour "
                     f"planner call to replay; give more steps (default 20000)"
                     + (" or a --density above 0" if args.density == 0 else ""))
    classes = {args.against: on_this_grid(old.DetourPlanner), "now": detour.DetourPlanner}
    if recorded:                          # first-use costs (compilation, caches)
        for cls in classes.values():
            replay(cls, *recorded[0])
    spent = dict.fromkeys(classes, 0.0)
    identical = True
    for k, (arguments, calls) in enumerate(recorded):
        order = list(classes) if k % 2 else list(classes)[::-1]
        answers = {}
        for name in order:
            seconds, answers[name] = replay(classes[name], arguments, calls)
            spent[name] += seconds
        identical &= same(answers[args.against], answers["now"])
    calls = sum(len(c) for _, c in recorded)
    total = args.steps * len(seeds)
    print(f"detour planner calls of {total} random AOASS-v0 steps (seeds {args.seeds}): {calls} "
          f"on {len(recorded)} maps, replayed in one process")
    for name in classes:
        print(f"  {name:>8s}: {1e3 * spent[name] / max(calls, 1):7.3f} ms per call, "
              f"{1e6 * spent[name] / total:6.2f} us per step")
    if spent["now"] > 0:
        print(f"  speed-up {spent[args.against] / spent['now']:.2f} x; answers "
              f"{'identical' if identical else 'DIFFERENT'} to the bit")
    if not identical:
        raise SystemExit("the two planners' answers differ")


if __name__ == "__main__":
    main()
