"""Speed of aoass_env.world: control steps per second on a density-0.4 map.

Measures one control step (``World.step`` with ``physics_substeps`` pymunk steps, 16 rays,
d_obs, 5 moving obstacles) while the anchor wanders and bumps into obstacles, and compares it
with a bare pymunk space holding the same shapes and bodies stepped the same number of times in
this process. Run: ``python3 benchmarks/world.py [--steps N]``.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
import pymunk

from aoass_env.config import AOASSConfig
from aoass_env.maps import ObstacleMap
from aoass_env.world import World


def grid_map(cells: int = 10, cell: float = 10.0, density: float = 0.4) -> ObstacleMap:
    """Boxes and concave L shapes, one per cell, 1 m corridors around each; exact density."""
    area = density * cell * cell
    side = cell - 2.0
    arm = side - math.sqrt(side * side - area)         # L of two arms: 2*side*arm - arm^2
    polys = []
    for i in range(cells):
        for j in range(cells):
            x, y = i * cell + 1.0, j * cell + 1.0
            if (i + j) % 2:
                h = area / side
                y0 = y + (side - h) / 2
                polys.append([(x, y0), (x + side, y0), (x + side, y0 + h), (x, y0 + h)])
            else:
                polys.append([(x, y), (x + side, y), (x + side, y + arm), (x + arm, y + arm),
                              (x + arm, y + side), (x, y + side)])
    return ObstacleMap(cells * cell, cells * cell, polys, name="grid-0.4")


def bare_space(world: World, config: AOASSConfig) -> pymunk.Space:
    """A plain pymunk space with the world's shapes, a dynamic anchor and kinematic discs."""
    space = pymunk.Space()
    m = world.obstacle_map
    t = max(m.width, m.height)
    for x0, y0, x1, y1 in ((-t, -t, m.width + t, 0.0), (-t, m.height, m.width + t, m.height + t),
                           (-t, 0.0, 0.0, m.height), (m.width, 0.0, m.width + t, m.height)):
        space.add(pymunk.Poly(space.static_body, [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]))
    for part in m.convex_parts:
        space.add(pymunk.Poly(space.static_body, part.tolist()))
    anchor = pymunk.Body(1.0, math.inf)
    anchor.position = tuple(world.position)
    anchor.velocity = (1.0, 0.0)
    space.add(anchor, pymunk.Circle(anchor, config.anchor_radius))
    for p, v in zip(world.moving_positions.tolist(), world.moving_velocities.tolist(),
                    strict=True):
        body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        body.position, body.velocity = p, v
        space.add(body, pymunk.Circle(body, config.moving_obstacle_radius))
    return space


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000, help="control steps per repeat")
    args = parser.parse_args()
    if args.steps < 1:
        parser.error(f"--steps={args.steps} must be a positive number of control steps")
    config = AOASSConfig(n_rays=16, n_moving_obstacles=5)
    obstacle_map = grid_map()
    n = args.steps
    commands = np.random.default_rng(1).uniform((0.5, -math.pi), (config.anchor_max_speed,
                                                                  math.pi), size=(n, 2)).tolist()

    world = World(config, obstacle_map, np.random.default_rng(0), (10.0, 10.0))

    def run_world() -> tuple[float, dict[str, float]]:
        clock = time.perf_counter
        parts = {"step": 0.0, "rays": 0.0, "d_obs": 0.0}
        for speed, heading in commands:
            t0 = clock()
            world.step(speed, heading)
            t1 = clock()
            world.ray_distances()
            t2 = clock()
            world.nearest_obstacle_distance()
            parts["step"] += t1 - t0
            parts["rays"] += t2 - t1
            parts["d_obs"] += clock() - t2
        return sum(parts.values()) / n, {k: v / n for k, v in parts.items()}

    space = bare_space(world, config)

    def run_bare() -> float:
        start = time.perf_counter()
        for _ in range(n * config.physics_substeps):
            space.step(config.substep_dt)
        return (time.perf_counter() - start) / n

    world_s, parts = min((run_world() for _ in range(3)), key=lambda run: run[0])
    bare_s = min(run_bare() for _ in range(3))
    print(f"map {obstacle_map.name}: density {obstacle_map.density:.3f}, "
          f"{len(obstacle_map.convex_parts)} convex parts; {config.n_rays} rays, "
          f"{config.n_moving_obstacles} moving obstacles, {config.physics_substeps} substeps")
    print(f"world control step (step + rays + d_obs): {world_s * 1e6:8.1f} us "
          f"= {1.0 / world_s:8.0f} steps/s")
    print("  of which " + ", ".join(f"{k} {v * 1e6:.1f} us" for k, v in parts.items()))
    print(f"bare pymunk, {config.physics_substeps} space.step calls: {bare_s * 1e6:8.1f} us "
          f"= {1.0 / bare_s:8.0f} steps/s")
    print(f"ratio world / bare pymunk: {world_s / bare_s:.1f}x; "
          f"{world.contacts} anchor contacts")


if __name__ == "__main__":
    main()
