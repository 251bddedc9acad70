"""benchmarks/lookahead_speed.py: a reference that cannot take today's calls is refused in one
line, and the warm-up replays every call once."""

from __future__ import annotations

import pytest

from tests.benchmarks.conftest import load_benchmark, refused


def before_tolerance(velocity, preferred, *, horizon, progress_weight=0.0):
    """A reference's signature from before a keyword the recorded calls pass."""
    return velocity


def with_tolerance(velocity, preferred, *, horizon, progress_weight=0.0, tolerance=None):
    return velocity


CALLS = [((1.0, 2.0), {"horizon": 3.0}), ((1.0, 2.0), {"horizon": 3.0, "tolerance": 1.0})]


def test_a_reference_without_a_recorded_keyword_is_refused_in_one_line():
    bench = load_benchmark("lookahead_speed")
    bench.replayable(with_tolerance, CALLS, "abc1234", "escape_velocity")     # takes them all
    with pytest.raises(SystemExit) as refused:
        bench.replayable(before_tolerance, CALLS, "abc1234", "escape_velocity")
    message = str(refused.value)
    assert "\n" not in message and message.startswith("--ref abc1234: its escape_velocity")
    assert "'tolerance'" in message and bench.REFERENCE in message


def test_the_warm_up_replays_every_call_of_each_function_once():
    bench = load_benchmark("lookahead_speed")
    seen = []
    bench.warm_up((lambda *a, **k: seen.append(("old", a, k)), CALLS),
                  (lambda *a, **k: seen.append(("new", a, k)), CALLS[:1]))
    assert seen == [("old", *CALLS[0]), ("old", *CALLS[1]), ("new", *CALLS[0])]


def test_a_reference_that_is_not_a_commit_is_one_line(monkeypatch, capsys):
    """It used to be a CalledProcessError traceback from ``git show``."""
    assert refused(monkeypatch, capsys, "lookahead_speed", "--ref", "no-such-commit") == (
        "--ref no-such-commit: no such commit in this repository")


def test_git_problem_names_a_file_the_commit_lacks():
    bench = load_benchmark("git_history")
    if bench.git_problem("HEAD", "benchmarks/lookahead_speed.py") is not None:
        pytest.skip("needs a git checkout")
    assert bench.git_problem("HEAD", "no/such/file.py") == "has no no/such/file.py (it predates it)"
    assert bench.git_problem("-x", "no/such/file.py") == "no such commit in this repository"


def test_in_turn_swaps_two_sides_every_round_and_rotates_more():
    in_turn = load_benchmark("git_history").in_turn
    assert [in_turn(i, "ref", "now") for i in range(3)] == [
        ["ref", "now"], ["now", "ref"], ["ref", "now"]]
    assert [in_turn(i, *"abc") for i in range(4)] == [
        list("abc"), list("bca"), list("cab"), list("abc")]


def test_the_reference_runs_first_in_even_rounds_only_and_results_keep_their_order():
    """Every round used to time the reference first."""
    bench = load_benchmark("lookahead_speed")
    seen = []

    def side(name):
        return lambda x: seen.append(name) or (name, x)

    calls = [((1,), {}), ((2,), {})]
    for i in range(3):
        seen.clear()
        (_, old), (_, new) = bench.timed_in_turn(i, (side("old"), calls), (side("new"), calls))
        assert seen == (["old", "old", "new", "new"] if i % 2 == 0 else
                        ["new", "new", "old", "old"])
        assert old == [("old", 1), ("old", 2)] and new == [("new", 1), ("new", 2)]
