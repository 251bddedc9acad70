"""benchmarks/rays.py: the compiled rays against Chipmunk's queries, in one process."""

from __future__ import annotations

import pytest

from tests.benchmarks.conftest import load_benchmark


def test_the_readings_agree_and_both_are_timed(capsys):
    load_benchmark("rays").main(["--steps", "200", "--density", "0.3", "--seed", "881001"])
    out = capsys.readouterr().out
    assert "200 readings" in out and "identical to the bit" in out
    assert "Chipmunk, ray by ray" in out and "x faster" in out


def test_a_density_outside_the_generators_is_refused_in_one_line(capsys):
    with pytest.raises(SystemExit):
        load_benchmark("rays").main(["--density", "0.7"])
    assert "--density must be at most 0.6, got 0.7" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        load_benchmark("rays").main(["--density", "-0.1"])
    assert "argument --density: must be a finite number >= 0" in capsys.readouterr().err
