"""benchmarks/recurrent_td3_speed.py: an --env both algorithms cannot train on is refused in
one line before any run."""

from __future__ import annotations

import pytest

from tests.benchmarks.conftest import load_benchmark, refused


@pytest.mark.parametrize("env_id, message", [
    ("NoSuchEnv-v0", "--env NoSuchEnv-v0: Environment `NoSuchEnv` doesn't exist."),
    ("CartPole-v1", "--env CartPole-v1: its actions are Discrete(2); TD3 and RecurrentTD3 need "
                    "Box (continuous) actions"),
])
def test_an_env_without_box_actions_is_one_line(monkeypatch, capsys, one_thread_scripts, env_id,
                                                message):
    """It used to fail inside SB3 when the first model was built: a traceback."""
    bench = load_benchmark("recurrent_td3_speed")
    monkeypatch.setattr(bench, "steps_per_second", lambda *a, **k: pytest.fail("a run started"))
    assert refused(monkeypatch, capsys, "recurrent_td3_speed", "--env", env_id,
                   module=bench).startswith(message)
