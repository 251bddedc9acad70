"""Speed of aoass_env.safety.orca: microseconds per ORCA call.

Anchor of radius 0.7 m (0.5 m + 0.2 m margin), max speed 2 m/s, horizons 4 s (moving) and
2.5 s (static), as the safety wrapper uses it. Scenes:

* empty: no obstacle (fast path);
* 3 moving discs within 6 m;
* a box 1.5 m away + the 3 discs;
* 20 random polygons around the anchor (within about 8 m) + the 3 discs;
* a generated 100 x 100 m map of density 0.4 (``free_space_loops``, field border included),
  the anchor at 200 random free points, + the 3 discs.

For each it prints the microseconds per ``orca_velocity`` call and per ``orca_lines`` +
``solve_velocity`` (the wrapper's path), best of three passes, and the average number of lines.
No comparison with RVO2's Python bindings: no ``rvo2`` package is installable from the package
index here. Run: ``python3 benchmarks/orca.py [--calls N]``.

``--reference FILE`` times another version of ``aoass_env/safety/orca.py`` (e.g. one saved with
``git show REV:aoass_env/safety/orca.py > /tmp/orca_ref.py``) in the same process on the same
calls, alternating the two on chunks of 50 calls over ``--repeats`` passes (noise of a shared
machine hits both alike), and prints the microseconds per ``orca_velocity`` call of each (the
fastest pass of every chunk) and their ratio, current / reference.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from pathlib import Path
from types import ModuleType

import numpy as np
import shapely

from aoass_env.maps import generate_map
from aoass_env.safety import orca
from aoass_env.safety.orca import StaticObstacles, orca_lines, orca_velocity, solve_velocity
from aoass_env.validators import argparse_number

RADIUS, MAX_SPEED, TAU, TAU_OBST, STEP = 0.7, 2.0, 4.0, 2.5, 0.1


def discs(rng: np.random.Generator, centre: np.ndarray) -> np.ndarray:
    """Three moving discs [x, y, vx, vy, r] 2-6 m from ``centre``."""
    angle = rng.uniform(0, 2 * np.pi, 3)
    dist = rng.uniform(2.0, 6.0, 3)
    xy = centre + np.c_[dist * np.cos(angle), dist * np.sin(angle)]
    return np.c_[xy, rng.uniform(-1, 1, (3, 2)), np.full(3, 0.5)]


def random_polygons(rng: np.random.Generator, count: int) -> list[np.ndarray]:
    """``count`` disjoint convex polygons (CCW) 1.5-8 m from the origin."""
    shapes: list[shapely.Polygon] = []
    while len(shapes) < count:
        angle, dist = rng.uniform(0, 2 * np.pi), rng.uniform(2.5, 8.0)
        k = rng.integers(3, 7)
        corners = np.sort(rng.uniform(0, 2 * np.pi, k))
        size = rng.uniform(0.3, 1.0)
        poly = shapely.Polygon(dist * np.array([np.cos(angle), np.sin(angle)])
                               + size * np.c_[np.cos(corners), np.sin(corners)])
        if poly.is_valid and poly.distance(shapely.Point(0, 0)) > 1.5 \
                and all(poly.distance(other) > 0.05 for other in shapes):
            shapes.append(poly)
    return [np.asarray(shapely.geometry.polygon.orient(s, 1.0).exterior.coords)[:-1]
            for s in shapes]


def timed(calls: list[dict], split: bool) -> float:
    """Best of three passes, microseconds per call."""
    best = np.inf
    for _ in range(3):
        if not split:
            best = min(best, velocity_pass(orca, calls))
            continue
        start = time.perf_counter()
        for kw in calls:
            lines = orca_lines(kw["position"], kw["velocity"], RADIUS, MAX_SPEED,
                               static_obstacles=kw["static"], moving_obstacles=kw["moving"],
                               time_horizon=TAU, time_horizon_obst=TAU_OBST, time_step=STEP)
            solve_velocity(lines, kw["preferred"], MAX_SPEED)
        best = min(best, (time.perf_counter() - start) / len(calls) * 1e6)
    return best


def scene_calls(name: str, rng: np.random.Generator, calls: int) -> list[dict]:
    out = []
    box = StaticObstacles.from_loops([[[1.5, -2.0], [3.0, -2.0], [3.0, 2.0], [1.5, 2.0]]])
    polygons = StaticObstacles.from_loops(random_polygons(rng, 20))
    free_map = None
    if name == "map":
        obstacle_map = generate_map(100.0, 0.4, rng)
        free_map = StaticObstacles.from_loops(obstacle_map.free_space_loops)
        free_space = obstacle_map.free_space.buffer(-RADIUS)
        lo, hi = np.array(free_space.bounds[:2]), np.array(free_space.bounds[2:])
        points: list[np.ndarray] = []
        while len(points) < 200:
            p = rng.uniform(lo, hi)
            if free_space.contains(shapely.Point(p)):
                points.append(p)
    for i in range(calls):
        position = np.zeros(2)
        static = None
        if name == "box":
            static = box
        elif name == "polygons":
            static = polygons
        elif name == "map":
            position = points[i % len(points)]
            static = free_map
        heading = rng.uniform(0, 2 * np.pi)
        velocity = rng.uniform(0.5, 2.0) * np.array([np.cos(heading), np.sin(heading)])
        preferred = 2.0 * np.array([np.cos(heading + 0.3), np.sin(heading + 0.3)])
        moving = None if name == "empty" else discs(rng, position)
        out.append({"position": position, "velocity": velocity, "preferred": preferred,
                    "static": static, "moving": moving})
    return out


def load_reference(path: Path) -> ModuleType:
    """The ORCA module in ``path``, imported under its own name beside the current one."""
    spec = importlib.util.spec_from_file_location("orca_reference", path)
    if spec is None or spec.loader is None:
        raise SystemExit(f"--reference {path}: not a Python file")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while building
    spec.loader.exec_module(module)
    return module


def velocity_pass(module: ModuleType, calls: list[dict]) -> float:
    """One pass of ``module.orca_velocity`` over ``calls``, microseconds per call."""
    start = time.perf_counter()
    for kw in calls:
        module.orca_velocity(kw["position"], kw["velocity"], kw["preferred"], RADIUS, MAX_SPEED,
                             static_obstacles=kw["static"], moving_obstacles=kw["moving"],
                             time_horizon=TAU, time_horizon_obst=TAU_OBST, time_step=STEP)
    return (time.perf_counter() - start) / len(calls) * 1e6


def against_reference(name: str, calls: list[dict], reference: ModuleType,
                      repeats: int) -> None:
    """Print the current and the reference ``orca_velocity`` (us per call: the fastest of
    ``repeats`` alternating passes, chunk by chunk) and their ratio, after checking that both
    give the same velocities."""
    converted: dict[int, object] = {}
    ref_calls = []
    for kw in calls:
        static = kw["static"]
        if static is not None and id(static) not in converted:
            converted[id(static)] = reference.StaticObstacles(
                static.point, static.direction, static.next, static.prev, static.convex)
        ref_calls.append({**kw, "static": None if static is None else converted[id(static)]})
    for kw, ref in zip(calls, ref_calls, strict=True):
        opts = {"moving_obstacles": kw["moving"], "time_horizon": TAU,
                "time_horizon_obst": TAU_OBST, "time_step": STEP}
        ours = orca_velocity(kw["position"], kw["velocity"], kw["preferred"], RADIUS, MAX_SPEED,
                             static_obstacles=kw["static"], **opts)
        theirs = reference.orca_velocity(kw["position"], kw["velocity"], kw["preferred"], RADIUS,
                                         MAX_SPEED, static_obstacles=ref["static"], **opts)
        if not np.array_equal(ours, theirs):    # no speed ratio against other answers
            raise SystemExit(f"{name}: velocities differ from the reference, e.g. {ours} != "
                             f"{theirs}")
    # alternate the two on chunks of 50 calls and keep each chunk's fastest pass: a burst of
    # load on the shared machine spoils a few chunks of one pass, not a whole scene
    chunks = range(0, len(calls), 50)
    best = {"current": np.full(len(chunks), np.inf), "reference": np.full(len(chunks), np.inf)}
    for r in range(repeats):
        for c, lo in enumerate(chunks):
            runs = [("current", orca, calls[lo:lo + 50]),
                    ("reference", reference, ref_calls[lo:lo + 50])]
            for label, module, batch in runs if (r + c) % 2 == 0 else runs[::-1]:
                best[label][c] = min(best[label][c], velocity_pass(module, batch) * len(batch))
    ours, theirs = (best[label].sum() / len(calls) for label in ("current", "reference"))
    print(f"{name:<12}{theirs:>12.1f} us{ours:>11.1f} us{ours / theirs:>8.3f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--calls", type=argparse_number(int, 1), default=2000)
    parser.add_argument("--seed", type=argparse_number(int, 0), default=0)
    parser.add_argument("--reference", type=Path, default=None,
                        help="another orca.py to time against, in the same process")
    parser.add_argument("--repeats", type=argparse_number(int, 1), default=9,
                        help="alternating passes per scene with --reference")
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    reference = None
    if args.reference is not None:      # a missing file was a FileNotFoundError traceback
        if not args.reference.is_file():
            parser.error(f"--reference {args.reference}: no such file; save one with "
                         f"`git show REV:aoass_env/safety/orca.py > /tmp/orca_ref.py`")
        reference = load_reference(args.reference)
        missing = [name for name in ("orca_velocity", "StaticObstacles")
                   if not hasattr(reference, name)]
        if missing:
            parser.error(f"--reference {args.reference}: not a version of "
                         f"aoass_env/safety/orca.py (no {', '.join(missing)})")
    if reference is None:
        print(f"{'scene':<12}{'orca_velocity':>16}{'lines+solve':>14}{'lines':>8}")
    else:
        print(f"{'scene':<12}{'reference':>15}{'current':>14}{'ratio':>8}")
    for name in ("empty", "discs", "box", "polygons", "map"):
        calls = scene_calls(name, rng, args.calls)
        if reference is not None:
            against_reference(name, calls, reference, args.repeats)
            continue
        n_lines = np.mean([len(orca_lines(kw["position"], kw["velocity"], RADIUS, MAX_SPEED,
                                          static_obstacles=kw["static"],
                                          moving_obstacles=kw["moving"], time_horizon=TAU,
                                          time_horizon_obst=TAU_OBST, time_step=STEP))
                           for kw in calls])
        print(f"{name:<12}{timed(calls, False):>13.1f} us{timed(calls, True):>11.1f} us"
              f"{n_lines:>8.1f}")


if __name__ == "__main__":
    main()
