"""benchmarks/safety_filter_speed.py: a --ref that is not a commit is refused in one line
before any episode, and the reference and the current functions take turns leading the
rounds."""

from __future__ import annotations

import argparse
from types import SimpleNamespace

import numpy as np

from tests.benchmarks.conftest import load_benchmark, refused


def test_a_reference_that_is_not_a_commit_is_one_line(monkeypatch, capsys):
    """It used to be a CalledProcessError traceback from ``git show``."""
    assert refused(monkeypatch, capsys, "safety_filter_speed", "--ref", "no-such-commit") == (
        "--ref no-such-commit: no such commit in this repository")


def test_the_reference_leads_the_odd_numbered_rounds_only(monkeypatch, capsys):
    """Every round used to time the reference first. The three functions of both sides are
    fakes that log their side; one recorded call each."""
    bench = load_benchmark("safety_filter_speed")
    log = []

    def side(name, answer):
        return lambda *args, **kwargs: log.append(name) or answer()

    def escape():
        return SimpleNamespace(velocity=np.zeros(2), escaping=False, shortfall=0.0,
                               chosen_shortfall=0.0)

    def functions(name):
        residual = type("ResidualAction", (), {"action": side(name, lambda: np.zeros(2)),
                                                "__init__": lambda self, *args: None})
        return SimpleNamespace(escape_velocity=side(name, escape), ResidualAction=residual,
                               checked_action=side(name, lambda: np.zeros(2)))

    new = functions("new")
    monkeypatch.setattr(bench, "replay_arguments",
                        lambda *a: argparse.Namespace(ref="abc1234", steps=1, rounds=3))
    monkeypatch.setattr(bench, "reference_module", lambda *a: functions("old"))
    monkeypatch.setattr(bench, "lookahead", new)
    monkeypatch.setattr(bench, "action_module", new)
    encoder = SimpleNamespace(speed_scale=1.0, heading_scale=1.0, max_speed=1.0)
    monkeypatch.setattr(bench, "record", lambda steps: ([((1.0,), {})], [((1.0,), {})],
                                                        [((encoder, 1.0), {})]))
    bench.main()
    assert log[:6] == ["old", "new"] * 3            # the warm-up
    rounds = [log[6 + 6 * i: 12 + 6 * i] for i in range(3)]
    assert rounds == [["old", "new"] * 3, ["new", "old"] * 3, ["old", "new"] * 3]
    assert capsys.readouterr().out.count("answers identical") == 9
