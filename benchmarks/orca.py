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
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import shapely

from aoass_env.maps import generate_map
from aoass_env.safety.orca import StaticObstacles, orca_lines, orca_velocity, solve_velocity

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
        start = time.perf_counter()
        for kw in calls:
            if split:
                lines = orca_lines(kw["position"], kw["velocity"], RADIUS, MAX_SPEED,
                                   static_obstacles=kw["static"], moving_obstacles=kw["moving"],
                                   time_horizon=TAU, time_horizon_obst=TAU_OBST, time_step=STEP)
                solve_velocity(lines, kw["preferred"], MAX_SPEED)
            else:
                orca_velocity(kw["position"], kw["velocity"], kw["preferred"], RADIUS, MAX_SPEED,
                              static_obstacles=kw["static"], moving_obstacles=kw["moving"],
                              time_horizon=TAU, time_horizon_obst=TAU_OBST, time_step=STEP)
        best = min(best, time.perf_counter() - start)
    return best / len(calls) * 1e6


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--calls", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    print(f"{'scene':<12}{'orca_velocity':>16}{'lines+solve':>14}{'lines':>8}")
    for name in ("empty", "discs", "box", "polygons", "map"):
        calls = scene_calls(name, rng, args.calls)
        n_lines = np.mean([len(orca_lines(kw["position"], kw["velocity"], RADIUS, MAX_SPEED,
                                          static_obstacles=kw["static"],
                                          moving_obstacles=kw["moving"], time_horizon=TAU,
                                          time_horizon_obst=TAU_OBST, time_step=STEP))
                           for kw in calls])
        print(f"{name:<12}{timed(calls, False):>13.1f} us{timed(calls, True):>11.1f} us"
              f"{n_lines:>8.1f}")


if __name__ == "__main__":
    main()
