"""benchmarks/action_repeat.py: the deferring and the building twins play the same episodes."""

from __future__ import annotations

import pytest

from aoass_env.registration import TRAIN_ENV_ID
from tests.benchmarks.conftest import load_benchmark


def test_the_twins_play_the_same_episodes_and_the_line_reads_both(capsys):
    bench = load_benchmark("action_repeat")
    twins = bench._twins(TRAIN_ENV_ID, seed=3)
    assert twins[True][1]._source is not None and twins[False][1]._source is None
    bench.measure(TRAIN_ENV_ID, steps=6, chunk=3, seed=3)    # raises when the episodes differ
    line = capsys.readouterr().out
    assert line.startswith(TRAIN_ENV_ID) and "every observation" in line and "deferred" in line


@pytest.mark.parametrize("argv", [["--steps", "0"], ["--chunk", "-2"]])
def test_bad_counts_are_refused_in_one_line(capsys, argv):
    bench = load_benchmark("action_repeat")
    with pytest.raises(SystemExit):
        bench.main(argv)
    assert f"--{argv[0][2:]} must be an integer >= 1" in capsys.readouterr().err
