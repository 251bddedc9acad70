"""benchmarks/unicycle_follower_speed.py: a --ref that is not a commit is refused in one line
before any episode, and the follower's sides take turns leading the rounds."""

from __future__ import annotations

import numpy as np

from tests.benchmarks.conftest import load_benchmark, refused


def test_a_reference_that_is_not_a_commit_is_one_line(monkeypatch, capsys):
    """It used to be a CalledProcessError traceback from ``git show``."""
    assert refused(monkeypatch, capsys, "unicycle_follower_speed", "--ref", "no-such-commit") == (
        "--ref no-such-commit: no such commit in this repository")


class _Follower:
    """A follower that logs its class and each command (the log shared by the copies)."""

    log: list = []

    def __init__(self):
        self.index, self._clock, self._budget, self.recoveries, self.skipped = 0, 0.0, 1.0, 0, []

    def command(self, position, heading, dt):
        self.log.append(type(self).__name__)
        self.index += 1
        return (float(position[0]), heading)


class _Reference(_Follower):
    pass


def test_the_follower_replay_runs_the_reference_first_in_even_rounds_only():
    """Every round used to replay the reference first; both sides replay the same calls, each
    after ``play`` (the searches' answers handed back from the first)."""
    bench = load_benchmark("unicycle_follower_speed")
    episodes = [(_Follower(), [(np.array([1.0, 2.0]), 0.5, 0.1), (np.array([3.0, 4.0]), 0.0, 0.1)])]
    for i in range(3):
        _Follower.log.clear()
        (_, old), (_, new) = bench.replay_in_turn(i, episodes, _Reference,
                                                  lambda: _Follower.log.append("play"))
        first, second = ("_Reference", "_Follower") if i % 2 == 0 else ("_Follower", "_Reference")
        assert _Follower.log == ["play", first, first, "play", second, second]
        assert old == new == [([(1.0, 0.5), (3.0, 0.0)], (2, 0.0, 1.0, 0, []))]
    assert episodes[0][0].index == 0            # each side replays a copy
