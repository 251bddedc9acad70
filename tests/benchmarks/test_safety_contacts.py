"""benchmarks/safety_contacts.py: the contact log's summary and the stacks it runs."""

from __future__ import annotations

import math

import pytest

from tests.benchmarks.conftest import load_benchmark, refused


def _period(speed, escaping=True, yielding=False, static_active=0, error=0.2, std=0.15):
    return {"escaping": escaping, "yielding": yielding, "speed": speed,
            "static_active": static_active,
            "track": {"error": error, "std": std, "velocity_error": 0.1}}


def test_summary_counts_contacts_and_their_situations():
    bench = load_benchmark("safety_contacts")
    dash = [_period(0.0, escaping=False)] * 8 + [_period(2.0)] * 8
    # the track's std is read in the three periods before the contact's
    pinned = ([_period(0.0, escaping=False)] * 14 + [_period(0.0, escaping=False, std=0.17)]
              + [_period(0.05, escaping=False, static_active=2, yielding=True)])
    rows = [{"density": 0.5, "moving_contacts": 2, "static_contacts": 0, "complete": False,
             "coverage": 0.8, "min_separation": -0.01, "path_length": 900.0, "time": 3880.0,
             "contacts": [{"period": 10, "history": dash}, {"period": 99, "history": pinned}]},
            {"density": 0.1, "moving_contacts": 0, "static_contacts": 0, "complete": True,
             "coverage": 1.0, "min_separation": 2.0, "path_length": 1100.0, "time": 2000.0,
             "contacts": []}]
    out = bench.summary(rows)
    assert out["episodes"] == 2 and out["moving_contacts"] == 2
    assert math.isclose(out["moving_per_100"], 100.0)
    assert out["escaping_in_last_8"] == 1          # the pinned one had not escaped lately
    assert out["at_speed"] == 1 and out["pinned"] == 1 and out["yielding"] == 1
    assert out["by_density"]["0.5"] == [1, 2] and out["by_density"]["0.1"] == [1, 0]
    assert math.isclose(out["track_std_max"], 0.17)
    assert out["complete"] == 1
    assert out["path_length"] == 1000.0 and out["time"] == 2940.0


def test_the_stacks_are_benchmarks_safety_pys():
    bench = load_benchmark("safety_contacts")
    cf, one = bench.STACKS["clearance-first"], bench.STACKS["one-cost"]
    assert cf.shortfall_tolerance == 1.0 and cf.yield_shortfall_tolerance == 1.0
    assert one.shortfall_tolerance is None and one.yield_shortfall_tolerance is None
    assert bench.STACKS["yield-one-cost"].shortfall_tolerance == 1.0
    assert bench.STACKS["yield-one-cost"].yield_shortfall_tolerance is None
    assert bench.STACKS["yield-tolerance"].yield_shortfall_tolerance == 3.0
    stack = bench.STACKS["stack"]                                # the defaults
    assert stack.shortfall_tolerance == 1.0 and stack.yield_shortfall_tolerance is None


@pytest.mark.parametrize(("argv", "message"), [
    (["--set", "escape_budgt=10"], "did you mean 'escape_budget'"),
    (["--set", "escape_budget=-1"], "escape_budget=-1 must be a number"),
    (["--set", "escape_budget"], "--set 'escape_budget': expected FIELD=JSON"),
    (["--set", "escape_budget=ten"], "'ten' is not JSON"),
    (["--env", "replan_exces=30"], "did you mean 'replan_excess'"),
    (["--episodes", "0"], "--episodes must be at least 1, got 0"),
    (["--jobs", "0"], "--jobs must be at least 1, got 0"),
])
def test_bad_fields_and_counts_are_refused_before_any_episode(capsys, tmp_path, argv, message):
    bench = load_benchmark("safety_contacts")
    out = tmp_path / "log.jsonl"
    with pytest.raises(SystemExit) as exc:
        bench.main([*argv, "--out", str(out)])
    assert exc.value.code == 2
    assert message in capsys.readouterr().err
    assert not out.exists()
    assert bench.STACKS["stack"] == bench.STACKS["stack"].__class__()   # left as it was


def test_a_bad_summary_file_or_out_folder_is_one_line(tmp_path, monkeypatch, capsys):
    bad = tmp_path / "bad.jsonl"
    bad.write_text("not json\n")
    blocker = tmp_path / "file"
    blocker.write_text("")
    for argv, message in (
            (["--summary", str(bad)], f"--summary {bad}: not a safety_contacts.py --out file"),
            (["--summary", str(tmp_path / "none")], "--summary"),
            # an unusable --out used to be found after the episodes, losing them
            (["--episodes", "1", "--out", str(blocker / "x.jsonl")],
             f"--out {blocker / 'x.jsonl'}: {blocker} is a file, not a folder")):
        assert refused(monkeypatch, capsys, "safety_contacts", *argv).startswith(message)
