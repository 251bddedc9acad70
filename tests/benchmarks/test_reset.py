"""benchmarks/reset.py: bad flags and a commit before the API it swaps in, refused in one line
before any reset."""

from __future__ import annotations

import subprocess

import pytest

from aoass_env.maps import generator
from aoass_env.planning import coverage
from tests.benchmarks.conftest import ROOT, refused

#: a commit whose coverage raster has no _free_points (added in d0b6796)
BEFORE_FREE_POINTS = "b233340"


def has_commit(commit: str) -> bool:
    return subprocess.run(["git", "cat-file", "-e", f"{commit}^{{commit}}"], cwd=ROOT,
                          capture_output=True).returncode == 0


@pytest.mark.parametrize("argv, message", [
    (["--density", "0.9"], "argument --density: must be a finite number in [0, 0.6], got '0.9'"),
    (["--field", "5"], "argument --field: must be a finite number in [10, 2000], got '5'"),
])
def test_bad_numbers_are_one_line(monkeypatch, capsys, argv, message):
    """They used to reach the env: a MapError or ConfigError traceback."""
    assert refused(monkeypatch, capsys, "reset", *argv) == message


def test_a_commit_before_the_api_is_one_line(monkeypatch, capsys):
    """It used to end in an AttributeError traceback."""
    if not has_commit(BEFORE_FREE_POINTS):
        pytest.skip(f"needs the repository's history ({BEFORE_FREE_POINTS})")
    assert refused(monkeypatch, capsys, "reset", "--against", BEFORE_FREE_POINTS) == (
        f"--against {BEFORE_FREE_POINTS}: predates the API this script swaps in (its "
        f"aoass_env/planning/coverage.py has no _free_points); choose a later commit, e.g. the "
        f"default 086f580")


def test_a_field_too_small_for_its_episodes_is_one_line_and_puts_the_code_back(monkeypatch,
                                                                              capsys):
    """No room for the moving obstacles at the first (untimed) reset: a ValueError traceback."""
    from aoass_env import simulator

    if not has_commit("HEAD"):
        pytest.skip("needs a git checkout")
    message = refused(monkeypatch, capsys, "reset", "--against", "HEAD", "--field", "20",
                      "--density", "0.4")
    assert message.startswith("--field 20 with --density 0.4: could not place moving obstacle")
    assert simulator.generate_map is generator.generate_map
    assert coverage._free_points.__module__ == coverage.__name__
