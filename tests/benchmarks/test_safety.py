"""benchmarks/safety.py: a Kalman row without samples says so instead of printing NaN (its
counts: tests/benchmarks/test_count_flags.py)."""

from __future__ import annotations

import json
import math

import pytest

from tests.benchmarks.conftest import load_benchmark


def test_rms_of_no_errors_is_none_and_of_some_is_their_root_mean_square():
    bench = load_benchmark("safety")
    assert bench.rms([]) is None
    assert bench.rms([3.0, 4.0]) == pytest.approx(math.sqrt(12.5))


def test_kalman_rows_without_samples_say_so_and_store_none(capsys):
    bench = load_benchmark("safety")
    out = bench.run_kalman(steps=3)     # too few steps for a detection
    printed = capsys.readouterr().out
    assert "nan" not in printed and "raise --kalman-steps" in printed
    assert all(row["raw"] is None and row["tracked"] is None and row["samples"] == 0
               for row in out.values())
    json.loads(json.dumps(out, allow_nan=False))     # strict JSON: no NaN written

