"""benchmarks/step_parts_speed.py: --steps past the seed-0 episode's end is refused in one line
before stepping."""

from __future__ import annotations

from tests.benchmarks.conftest import refused


def test_steps_past_the_episode_are_one_line_before_stepping(monkeypatch, capsys):
    """A step past the episode's end used to be a RuntimeError traceback after 7760 steps."""
    message = refused(monkeypatch, capsys, "step_parts_speed", "--steps", "100000")
    assert message.startswith("--steps 100000: the seed-0 episode ends at its time limit of ")
    limit = int(message.split("time limit of ")[1].split()[0])
    assert message.endswith(f"give at most {limit - 1}")
