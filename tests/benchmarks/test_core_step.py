"""benchmarks/core_step.py: each node count's total is printed as a ratio to Pendulum-v1's step
measured in the same process; bad flags refused in one line."""

from __future__ import annotations

import pytest

from tests.benchmarks.conftest import load_benchmark, refused


def test_the_totals_are_ratios_to_the_mean_pendulum_step(capsys):
    load_benchmark("core_step").main(["--episodes", "1", "--steps", "5",
                                      "--pendulum-steps", "50"])
    reference, *lines = capsys.readouterr().out.splitlines()
    assert reference.startswith("Pendulum-v1 ")
    before = float(reference.split(": ")[1].split()[0])
    after = float(reference.split("before, ")[1].split()[0])
    mean = float(reference.split("their mean ")[1].split()[0])
    assert mean == pytest.approx((before + after) / 2, abs=0.06)
    assert [line.split(":")[0] for line in lines] == ["N = 100", "N = 1000"]
    for line in lines:
        total = float(line.split("total ")[1].split()[0])
        amortised = float(line.split("amortised ")[1].split()[0])
        ratio = float(line.split("ratio to Pendulum-v1 ")[1].split()[0])
        assert ratio == pytest.approx(total / mean, rel=0.01, abs=0.01)
        assert float(line.split("(amortised ")[1].rstrip(")")) == pytest.approx(
            amortised / mean, rel=0.01, abs=0.01)


def test_a_bad_pendulum_count_is_one_line(monkeypatch, capsys):
    assert refused(monkeypatch, capsys, "core_step", "--pendulum-steps", "0").startswith(
        "argument --pendulum-steps: ")
