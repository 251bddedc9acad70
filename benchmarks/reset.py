"""Fresh resets of AOASS-v0 against an earlier commit's map generator and coverage raster.

    python3 benchmarks/reset.py [--against 086f580] [--resets 20] [--density 0.4] [--field 100]

Issue 20 asks for a reset of at most 50 ms at density 0.4 on a 100 m field with fresh seeds
(a map generated on every reset). The machine is shared and noisy, so the earlier code is timed
in the same process, seed by seed in alternation with the current code: the files
``aoass_env/maps/generator.py`` and ``aoass_env/planning/coverage.py`` of ``--against`` are read
with ``git show`` and their ``generate_map`` and ``_free_points`` swapped in (the rest of the
reset is the current tree's). Prints the median times (ms) of both for the reset, its map
generation and its coverage raster, the median of the per-seed ratios, and whether the two
trees' maps and coverage rasters agree bit for bit.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
from git_history import module_at

import aoass_env  # noqa: F401  (registers AOASS-v0)
from aoass_env import simulator
from aoass_env.config import AOASSConfig
from aoass_env.maps import generator
from aoass_env.planning import coverage
from aoass_env.validators import argparse_number, one_line

TARGET_MS = 50.0
#: the commit before issue 20's reset work
BEFORE = "086f580"


#: what is timed: the whole reset and two of its parts
PARTS = ("reset", "map generation", "coverage raster")
_CELLS = coverage._cells


def timed(function: Callable[..., Any], spent: list[float]) -> Callable[..., Any]:
    """``function`` adding its wall time (s) to ``spent[0]`` on every call."""
    def run(*args: Any, **kwargs: Any) -> Any:
        t = time.perf_counter()
        out = function(*args, **kwargs)
        spent[0] += time.perf_counter() - t
        return out
    return run


def timed_reset(env: gym.Env, seed: int, code: tuple) -> tuple[list[float], bytes]:
    """(the ms of :data:`PARTS`, fingerprint of the map and raster) of one reset with the
    ``code`` (generate_map, _free_points) swapped in."""
    generate, free_points = code
    spent_map, spent_cells = [0.0], [0.0]
    simulator.generate_map = timed(generate, spent_map)
    coverage._free_points = free_points
    coverage._cells = timed(_CELLS, spent_cells)
    t = time.perf_counter()
    env.reset(seed=seed)
    total = time.perf_counter() - t
    sim = env.unwrapped.sim
    fingerprint = (b"".join(p.tobytes() for p in sim.map.polygons)
                   + sim.coverage_map.centres.tobytes())
    return [1e3 * total, 1e3 * spent_map[0], 1e3 * spent_cells[0]], fingerprint


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--against", default=BEFORE, help=f"earlier commit (default {BEFORE})")
    parser.add_argument("--resets", type=int, default=20, help="fresh seeds (default 20)")
    parser.add_argument("--density", type=argparse_number(float, 0.0, high=generator.MAX_DENSITY),
                        default=0.4)
    field = AOASSConfig.__dataclass_fields__["field_size"].metadata
    parser.add_argument("--field", type=argparse_number(float, field["low"], high=field["high"]),
                        default=100.0, help="field side (m)")
    args = parser.parse_args()
    if args.resets < 1:
        parser.error("--resets must be positive")
    with tempfile.TemporaryDirectory() as folder:
        try:
            old_generator = module_at(args.against, "aoass_env/maps/generator.py", Path(folder))
            old_coverage = module_at(args.against, "aoass_env/planning/coverage.py", Path(folder))
        except ImportError as err:          # it imports what today's tree no longer has
            parser.error(f"--against {args.against}: predates the API this script swaps in "
                         f"({one_line(err)}); choose a later commit, e.g. the default {BEFORE}")
    # a commit before the coverage raster's _free_points used to end in an AttributeError
    for module, path, name in ((old_generator, "aoass_env/maps/generator.py", "generate_map"),
                               (old_coverage, "aoass_env/planning/coverage.py", "_free_points")):
        if not callable(getattr(module, name, None)):
            parser.error(f"--against {args.against}: predates the API this script swaps in (its "
                         f"{path} has no {name}); choose a later commit, e.g. the default "
                         f"{BEFORE}")
    codes = {"before": (old_generator.generate_map, old_coverage._free_points),
             "now": (generator.generate_map, coverage._free_points)}
    env = gym.make("AOASS-v0", obstacle_density=args.density, field_size=args.field)
    try:
        for code in codes.values():
            timed_reset(env, 10_000, code)          # first-use costs (imports, caches)
    except ValueError as err:       # MapError, or no room for the moving obstacles
        simulator.generate_map, coverage._free_points = codes["now"]
        coverage._cells = _CELLS
        parser.error(f"--field {args.field:g} with --density {args.density:g}: {one_line(err)}")
    runs: dict[str, list[list[float]]] = {name: [] for name in codes}
    same = True
    for i in range(args.resets):
        order = list(codes) if i % 2 else list(codes)[::-1]
        prints = []
        for name in order:
            times, fingerprint = timed_reset(env, 20_000 + i, codes[name])
            runs[name].append(times)
            prints.append(fingerprint)
        same &= prints[0] == prints[1]
    simulator.generate_map, coverage._free_points = codes["now"]
    coverage._cells = _CELLS
    print(f"fresh resets of AOASS-v0, density {args.density:g}, {args.field:g} m field, "
          f"{args.resets} seeds, alternated in one process (median ms):")
    for k, what in enumerate(PARTS):
        before = [run[k] for run in runs["before"]]
        now = [run[k] for run in runs["now"]]
        ratio = statistics.median(b / n for b, n in zip(before, now, strict=True))
        print(f"  {what:16s} {args.against}: {statistics.median(before):6.1f}   now: "
              f"{statistics.median(now):6.1f}   per-seed ratio {ratio:.2f}")
    print(f"target: reset <= {TARGET_MS:g} ms on a 100 m field at density 0.4; maps and coverage "
          f"rasters {'identical' if same else 'DIFFERENT'} in both trees")


if __name__ == "__main__":
    main()
