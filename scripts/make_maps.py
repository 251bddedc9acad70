"""Regenerate the shipped obstacle maps in maps/train/ and maps/test/.

    python3 scripts/make_maps.py            # rewrite maps/ (deterministic, about 15 s)
    python3 scripts/make_maps.py --out DIR  # write DIR/train, DIR/test instead

For every field size (100, 200 m) and density (0.1 ... 0.6) it writes 5 train and 3 test maps.
Each file is ``generate_map(size, density, np.random.default_rng(seed), clearance=2.5,
name=stem)`` (the config's default ``map_clearance``) written with
``write_map``; the stem ``d<density>_f<size>_s<seed>`` holds all three inputs, so any file can be
reproduced on its own. Seeds are unique per file; train seeds (0-59) and test seeds (500-535)
are disjoint. Stale ``*.txt`` files in the two folders are removed.
"""

from __future__ import annotations

import argparse
import itertools
import time
from pathlib import Path

import numpy as np

from aoass_env.config import AOASSConfig
from aoass_env.maps import MAPS_DIR, generate_map, write_map

SIZES = (100, 200)
DENSITIES = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6)
PER_GROUP = {"train": 5, "test": 3}
FIRST_SEED = {"train": 0, "test": 500}
#: narrowest passage kept open, the config default (m)
CLEARANCE = AOASSConfig().map_clearance


def map_name(density: float, size: int, seed: int) -> str:
    """File stem of a shipped map, e.g. ``d0.30_f100_s000``."""
    return f"d{density:.2f}_f{size}_s{seed:03d}"


def plan() -> dict[str, list[tuple[float, int, int]]]:
    """(density, size, seed) of every map of each split."""
    groups = list(itertools.product(SIZES, DENSITIES))
    return {split: [(density, size, FIRST_SEED[split] + j * n + k)
                    for j, (size, density) in enumerate(groups) for k in range(n)]
            for split, n in PER_GROUP.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=MAPS_DIR,
                        help=f"folder that receives train/ and test/ (default {MAPS_DIR})")
    args = parser.parse_args()
    splits = plan()
    try:
        for split in splits:
            (args.out / split).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        parser.error(f"--out {args.out}: {exc.strerror or exc}")
    for split, entries in splits.items():
        folder = args.out / split
        wanted = {map_name(*entry) for entry in entries}
        for stale in folder.glob("*.txt"):
            if stale.stem not in wanted:
                stale.unlink()
        for density, size, seed in entries:
            name = map_name(density, size, seed)
            start = time.perf_counter()
            obstacle_map = generate_map(size, density, np.random.default_rng(seed),
                                        clearance=CLEARANCE, name=name)
            write_map(obstacle_map, folder / f"{name}.txt")
            print(f"{split}/{name}: density {obstacle_map.density:.4f}, "
                  f"{len(obstacle_map.polygons)} obstacles, {time.perf_counter() - start:.2f} s")


if __name__ == "__main__":
    main()
