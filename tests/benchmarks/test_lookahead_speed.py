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


def test_a_reference_without_the_obstacles_edges_gets_them_among_the_anchors():
    """reference_calls joins the obstacles' edges to the anchor's for a reference that predates
    them, and the answers stay the same: today's escape_velocity answers the joined call (its
    obstacles then bounce off the joined edges) as it answers the recorded one, on escapes of
    a random-action AOASS-Safe-v0 episode with many moving obstacles."""
    import numpy as np

    from aoass_env.safety.lookahead import escape_velocity

    bench = load_benchmark("lookahead_speed")

    def before_bounces(velocity, preferred, *, starts, ends, horizon):
        return velocity

    calls = []
    real = bench.wrappers.escape_velocity
    try:
        bench.wrappers.escape_velocity = lambda *a, **k: calls.append((a, k)) or real(*a, **k)
        bench.random_steps("AOASS-Safe-v0", dict(bench.EPISODES[1][0]), 3, 300)
    finally:
        bench.wrappers.escape_velocity = real
    joined = bench.reference_calls(before_bounces, calls)
    assert bench.reference_calls(escape_velocity, calls) is calls
    assert len(joined) == len(calls) > 20
    grew = 0
    for (args, kwargs), (_, kw) in zip(calls, joined, strict=True):
        assert "bounce_starts" not in kw and len(kw["starts"]) >= len(kwargs["starts"])
        grew += len(kw["starts"]) > len(kwargs["starts"])
        assert bench.same_escape(escape_velocity(*args, **kwargs), escape_velocity(*args, **kw))
        assert np.array_equal(kw["starts"][:len(kwargs["starts"])], kwargs["starts"])
    assert grew > 0
    assert bench.reference_calls(before_bounces, CALLS) == CALLS      # no edges to join


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
