"""benchmarks/plan_speed.py: bad flags and a commit before the API it compares, refused in one
line before any plan is timed, and the two modules take turns leading the rounds."""

from __future__ import annotations

import sys
from types import SimpleNamespace

import pytest

from tests.benchmarks.conftest import load_benchmark, refused
from tests.benchmarks.test_reset import has_commit

#: a commit whose PrunedPlan has no ``order`` (added in 5e9fb88)
BEFORE_ORDER = "33bafbd"


@pytest.mark.parametrize("argv, message", [
    (["--density", "0.9"], "argument --density: must be a finite number in [0, 0.6], got '0.9'"),
    (["--field", "5"], "argument --field: must be a finite number in [10, 2000], got '5'"),
])
def test_bad_numbers_are_one_line(monkeypatch, capsys, argv, message):
    """They used to reach the generator or the config: a MapError or ConfigError traceback."""
    assert refused(monkeypatch, capsys, "plan_speed", *argv) == message


def test_a_commit_before_the_api_is_one_line_before_the_timing(monkeypatch, capsys):
    """It used to time the first map's plan, then end in an AttributeError traceback."""
    if not has_commit(BEFORE_ORDER):
        pytest.skip(f"needs the repository's history ({BEFORE_ORDER})")
    assert refused(monkeypatch, capsys, "plan_speed", "--against", BEFORE_ORDER) == (
        f"--against {BEFORE_ORDER}: predates the API this script compares (its PrunedPlan has "
        f"no order); choose a later commit, e.g. the default 3c3f17c")


def test_a_field_too_small_for_its_maps_is_one_line(monkeypatch, capsys):
    if not has_commit("HEAD"):
        pytest.skip("needs a git checkout")
    assert refused(monkeypatch, capsys, "plan_speed", "--against", "HEAD", "--field", "20",
                   "--density", "0.4", "--maps", "1").startswith(
        "--field 20 with --density 0.4: could not place moving obstacle")


def test_the_two_modules_take_turns_leading_the_rounds(monkeypatch, capsys):
    """Every round used to plan with the current module first; the plans of one round are
    compared whichever ran first. Before the rounds, one untimed plan of each module on a map
    of its own (the compiled kernels' first calls were timed in the first round)."""
    bench = load_benchmark("plan_speed")
    old = SimpleNamespace(prune_spiral=None)
    monkeypatch.setattr(bench, "module_at", lambda *a: old)
    monkeypatch.setattr(bench, "api_gap", lambda module: None)
    log = []

    def plan_once(module, sim, config):
        log.append(("now" if module is bench.pruning else "old", sim.map.width))
        return 1.0, SimpleNamespace(kept=[1], order=[0], reference=[0], length=1.0,
                                    full_length=2.0)

    monkeypatch.setattr(bench, "plan_once", plan_once)
    monkeypatch.setattr(sys, "argv", ["plan_speed.py", "--maps", "1", "--rounds", "3",
                                      "--field", "50", "--density", "0.1"])
    bench.main()
    warm = bench.WARM_UP_FIELD
    assert log == [("now", warm), ("old", warm)] + [
        (name, 50.0) for name in ("now", "old", "old", "now", "now", "old")]
    assert "plans identical: True" in capsys.readouterr().out
