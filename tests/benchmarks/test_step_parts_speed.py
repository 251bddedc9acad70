"""benchmarks/step_parts_speed.py: --steps past the seed-0 episode's end is refused in one line
before stepping; each part is printed as a ratio to an in-process Pendulum-v1 step."""

from __future__ import annotations

import pytest

from tests.benchmarks.conftest import load_benchmark, refused


def test_steps_past_the_episode_are_one_line_before_stepping(monkeypatch, capsys):
    """A step past the episode's end used to be a RuntimeError traceback after 7760 steps."""
    message = refused(monkeypatch, capsys, "step_parts_speed", "--steps", "100000")
    assert message.startswith("--steps 100000: the seed-0 episode ends at its time limit of ")
    limit = int(message.split("time limit of ")[1].split()[0])
    assert message.endswith(f"give at most {limit - 1}")


def test_each_part_is_a_ratio_to_the_pendulum_step_timed_in_the_same_process(capsys):
    load_benchmark("step_parts_speed").main(["--steps", "3", "--calls", "5", "--tracks", "0"])
    header, *parts, reference = capsys.readouterr().out.splitlines()
    assert header.startswith("aoass_env from ") and len(parts) == 8
    assert reference.split("  ")[1].startswith("Pendulum-v1 step (the reference)")
    ref = float(reference.split(")")[1].split()[0])
    before = float(reference.split("before the parts ")[1].split(",")[0])
    after = float(reference.split("after ")[1].rstrip(")"))
    assert ref == min(before, after)
    for line in parts:
        *_, us, unit, ratio, _, against = line.split()
        assert (unit, against) == ("us/call", "Pendulum-v1")
        us, ratio = float(us), float(ratio)
        assert ratio == pytest.approx(us / ref, rel=0.01, abs=0.002)


def test_the_state_has_a_confirmed_track_by_default(capsys):
    """At its old default state (400 steps of seed 0) the tracker held no track, so the
    tracker's and the filter's parts were timed with nothing to do."""
    load_benchmark("step_parts_speed").main(["--calls", "1"])
    header = capsys.readouterr().out.splitlines()[0]
    steps = int(header.split("state after ")[1].split()[0])
    tracks = int(header.split("(")[1].split()[0])
    assert steps > 400 and tracks >= 1


def test_too_many_tracks_are_one_line(monkeypatch, capsys):
    message = refused(monkeypatch, capsys, "step_parts_speed", "--steps", "7000", "--tracks",
                      "9")
    assert message.startswith("--tracks 9: the seed-0 episode ends after ")
