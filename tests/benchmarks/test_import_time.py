"""benchmarks/import_time.py: the cases take turns leading the rounds, the ratio is paired round
by round, and too few rounds are warned about (the interpreters are fakes here)."""

from __future__ import annotations

import sys

import pytest

from tests.benchmarks.conftest import load_benchmark


def run(monkeypatch: pytest.MonkeyPatch, repeats: int) -> tuple[list[str], str]:
    """(the statements probed, in order; the output) of ``--repeats repeats`` whose fake
    interpreters take 0.2 s for ``import gymnasium`` in odd-numbered rounds and 0.4 s in the
    others, and 10 ms more for ``import aoass_env`` than gymnasium in the same round."""
    bench = load_benchmark("import_time")
    seen = []

    def probe(statement: str) -> dict:
        seen.append(statement)
        base = 0.2 if (len(seen) - 1) // len(bench.CASES) % 2 else 0.4
        seconds = base + (0.01 if statement == "import aoass_env" else 0.0)
        return {"seconds": seconds, "modules": 1, "torch": False, "filterpy": False}

    monkeypatch.setattr(bench, "probe", probe)
    monkeypatch.setattr(sys, "argv", ["import_time.py", "--repeats", str(repeats)])
    bench.main()
    return seen, bench


def test_each_case_leads_one_round_in_five(monkeypatch, capsys):
    """``import gymnasium`` used to lead every round."""
    seen, bench = run(monkeypatch, 5)
    statements = list(bench.CASES.values())
    rounds = [seen[k * 5:(k + 1) * 5] for k in range(5)]
    assert [r[0] for r in rounds] == statements
    assert all(sorted(r) == sorted(statements) for r in rounds)
    assert "warning" not in capsys.readouterr().out


def test_the_ratio_is_the_median_of_the_rounds_own_ratios(monkeypatch, capsys):
    """Each round's aoass_env against that round's gymnasium: 1.025x and 1.05x in turn."""
    run(monkeypatch, 6)
    out = capsys.readouterr().out
    assert "import aoass_env costs 1.04x import gymnasium (median of 6 rounds' ratios, range " \
           "1.02-1.05; target <= 2.5x: met), +10 ms (range +10 to +10)" in out


@pytest.mark.parametrize("repeats", [1, 4])
def test_fewer_rounds_than_cases_are_warned_about(monkeypatch, capsys, repeats):
    run(monkeypatch, repeats)
    assert capsys.readouterr().out.strip().splitlines()[-1].startswith(
        f"warning: --repeats {repeats} < 5: not every case led a round")
