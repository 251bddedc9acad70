"""Shared fixtures: a small 40 m map file, so episodes take a fraction of a second."""

from pathlib import Path

import pytest

from aoass_env.evaluation.store import EpisodeKey

SMALL_MAP = """[SCALE]
1

[BORDER]
0 0
40 0
40 40
0 40

[OBSTACLE]
24 24
29 24
29 29
24 29
"""


@pytest.fixture(scope="session")
def small_map(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 40 m x 40 m map file with one 5 m square obstacle."""
    path = tmp_path_factory.mktemp("maps") / "small40.txt"
    path.write_text(SMALL_MAP)
    return path


@pytest.fixture(scope="session")
def small_key(small_map: Path):
    """The key of a 20-node episode on the small map, for any method."""
    def key(method: str, seed: int = 0) -> EpisodeKey:
        return EpisodeKey(method, str(small_map), 40.0, 20, 0.02, seed)
    return key
