"""benchmarks/safety_filter_speed.py: a --ref that is not a commit is refused in one line
before any episode."""

from __future__ import annotations

from tests.benchmarks.conftest import refused


def test_a_reference_that_is_not_a_commit_is_one_line(monkeypatch, capsys):
    """It used to be a CalledProcessError traceback from ``git show``."""
    assert refused(monkeypatch, capsys, "safety_filter_speed", "--ref", "no-such-commit") == (
        "--ref no-such-commit: no such commit in this repository")
