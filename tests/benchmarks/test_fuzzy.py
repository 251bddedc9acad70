"""benchmarks/fuzzy.py: the ratio to scikit-fuzzy's control system, or a clear line without
it; bad flags refused in one line."""

from __future__ import annotations

import sys

import pytest

from tests.benchmarks.conftest import load_benchmark, refused

SMALL = ["--calls", "20", "--batch", "10", "--sk-calls", "2"]


def test_the_ratio_is_ours_over_skfuzzys_scalar_call(capsys):
    pytest.importorskip("skfuzzy")
    load_benchmark("fuzzy").main(SMALL)
    lines = capsys.readouterr().out.splitlines()
    ours, sk = (float(line.split(":")[1].split()[0]) for line in (lines[0], lines[2]))
    assert lines[2].startswith("scikit-fuzzy scalar call")
    assert lines[3].startswith("ratio ours / skfuzzy (scalar calls): ")
    ratio = float(lines[3].split(": ")[1].split()[0])
    assert ratio == pytest.approx(ours / sk, rel=0.02)


def test_without_skfuzzy_it_says_so_and_prints_no_ratio(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "skfuzzy", None)      # import skfuzzy: ImportError
    load_benchmark("fuzzy").main(SMALL)
    out = capsys.readouterr().out
    assert out.splitlines()[-1].startswith("skfuzzy not installed")
    assert "ratio ours" not in out and "scikit-fuzzy scalar call" not in out


def test_a_bad_count_is_one_line(monkeypatch, capsys):
    assert refused(monkeypatch, capsys, "fuzzy", "--sk-calls", "0").startswith(
        "argument --sk-calls: ")
