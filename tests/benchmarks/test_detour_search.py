"""benchmarks/detour_search.py: recorded planner calls replayed on this tree and an earlier one."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

from tests.benchmarks.conftest import ROOT, load_benchmark, refused


def test_the_calls_replay_to_the_same_answers_on_the_tree_before(capsys):
    bench = load_benchmark("detour_search")
    if subprocess.run(["git", "cat-file", "-e", f"{bench.BEFORE}^{{commit}}"], cwd=ROOT,
                      capture_output=True).returncode:
        pytest.skip(f"needs the repository's history ({bench.BEFORE})")
    bench.main(["--steps", "1500", "--seeds", "0"])      # exits when the answers differ
    out = capsys.readouterr().out
    assert "answers identical to the bit" in out and f"{bench.BEFORE}:" in out


def test_recording_restores_the_planner_and_sees_every_call():
    from aoass_env.planning.detour import DetourPlanner

    bench = load_benchmark("detour_search")
    methods = (DetourPlanner.__dict__["for_map"], DetourPlanner.path, DetourPlanner.costs)
    recorded = bench.record([0], 1500)
    assert (DetourPlanner.__dict__["for_map"].__func__, DetourPlanner.path,
            DetourPlanner.costs) == (methods[0].__func__, methods[1], methods[2])
    assert recorded and all(calls for _, calls in recorded)
    arguments, calls = recorded[0]
    seconds, answers = bench.replay(DetourPlanner, arguments, calls)
    assert seconds > 0.0 and len(answers) == len(calls)
    assert bench.same(answers, bench.replay(DetourPlanner, arguments, calls)[1])
    assert not bench.same(answers, [None if a is not None else np.zeros((2, 2)) for a in answers])


def test_bad_arguments_are_refused_in_one_line(capsys, tmp_path):
    bench = load_benchmark("detour_search")
    for argv, message in ((["--steps", "0"], "--steps must be an integer >= 1"),
                          (["--seeds", "a,b"], "--seeds must be comma-separated integers"),
                          (["--field", "-3"], "field_size=-3.0 must be a number"),
                          (["--density", "0.9"], "obstacle_density=0.9 must be a number")):
        with pytest.raises(SystemExit):
            bench.main(argv)
        assert message in capsys.readouterr().err
    with pytest.raises(SystemExit) as refused:
        bench.module_at("no-such-commit", "aoass_env/planning/detour.py", tmp_path)
    assert str(refused.value) == "--against no-such-commit: no such commit in this repository"


def test_negative_seeds_are_one_line(monkeypatch, capsys):
    """They used to fail in numpy's seeding: a ValueError traceback after the checkout."""
    assert refused(monkeypatch, capsys, "detour_search", "--seeds", "0,-1") == (
        "--seeds must be comma-separated integers >= 0, got '0,-1'")


def test_steps_that_make_no_planner_call_are_refused(monkeypatch, capsys):
    """One step recorded no call: it printed 0.000 ms per call and exited 0."""
    if subprocess.run(["git", "rev-parse", "--verify", "HEAD"], cwd=ROOT,
                      capture_output=True).returncode:
        pytest.skip("needs a git checkout")
    assert refused(monkeypatch, capsys, "detour_search", "--against", "HEAD", "--steps", "1",
                   "--seeds", "0") == (
        "--steps 1: the episodes (seeds 0) made no detour planner call to replay; give more "
        "steps (default 20000)")
