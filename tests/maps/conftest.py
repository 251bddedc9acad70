"""Shared helpers of the aoass_env.maps tests: small boxes, a dense generated map, map files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from aoass_env.maps import ObstacleMap, generate_map

CLEARANCE = 2.5  # generate_map's default (the config's map_clearance)


def rng(seed: int = 0) -> np.random.Generator:
    return np.random.default_rng(seed)


def box(x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float64)


def assert_same_polygons(a: ObstacleMap, b: ObstacleMap) -> None:
    assert (a.width, a.height) == (b.width, b.height)
    assert len(a.polygons) == len(b.polygons)
    for p, q in zip(a.polygons, b.polygons, strict=True):
        np.testing.assert_array_equal(p, q)


@pytest.fixture(scope="module")
def dense_map() -> ObstacleMap:
    return generate_map(100, 0.6, rng(11))


IMR_SAMPLE = """\
[SCALE]
0.01

[BORDER]
100 200
2100 200
2100 1200
100 1200

[OBSTACLE]
600 400
600 700\t
900 700
900 400

[OBSTACLE]\r
1100 300
1500 300
1300 600
"""


def write(tmp_path: Path, text: str, name: str = "m.txt") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8", newline="")
    return path
