"""benchmarks/pendulum_memory.py: --rtd3-kwargs checked before any training, and
``--eval-freq 0`` (final evaluation only) accepted as its help says."""

from __future__ import annotations

import pytest

from tests.benchmarks.conftest import load_benchmark, refused


@pytest.mark.parametrize("value, message", [
    ("{lstm", "argument --rtd3-kwargs: not JSON ("),
    ("[64]", "argument --rtd3-kwargs: must be a JSON object of keyword arguments, got '[64]'"),
    ('{"lstm_size": 3}', "--rtd3-kwargs: unknown RecurrentTD3 keyword 'lstm_size'"),
    ('{"gamma": 0.5}', "--rtd3-kwargs: 'gamma' is set by the protocol, the same for both "
                       "algorithms"),
    ('{"burn_in": -1}', "--rtd3-kwargs: burn_in=-1 must be an integer in [0, inf)"),
])
def test_bad_rtd3_kwargs_are_one_line_before_any_run(monkeypatch, capsys, one_thread_scripts,
                                                    value, message):
    """They used to fail when the first RecurrentTD3 was built (a TypeError or ValueError
    traceback), after the runs before it had trained."""
    bench = load_benchmark("pendulum_memory")
    monkeypatch.setattr(bench, "run", lambda *args: pytest.fail("a run started"))
    assert refused(monkeypatch, capsys, "pendulum_memory", "--algos", "TD3", "RecurrentTD3",
                   "--rtd3-kwargs", value, module=bench).startswith(message)


def test_eval_freq_zero_evaluates_at_the_end_only(monkeypatch, capsys, one_thread_scripts):
    """The help said 0 means "final only" while the flag refused 0."""
    bench = load_benchmark("pendulum_memory")
    original, calls = bench.run, []

    def run(algo, seed, steps, eval_freq, extra):
        calls.append(eval_freq)
        return {"algo": algo, "seed": seed, "steps": steps, "mean_return": -1.0,
                "std_return": 0.0, "train_seconds": 1.0, "steps_per_second": 1.0,
                "curve": [(steps, -1.0)]}

    monkeypatch.setattr(bench, "run", run)
    monkeypatch.setattr("sys.argv", ["pendulum_memory.py", "--eval-freq", "0", "--steps", "5",
                                     "--seeds", "0", "--algos", "TD3"])
    bench.main()
    assert calls == [0]
    assert "TD3" in capsys.readouterr().out
    evaluations = []
    monkeypatch.setattr(bench, "evaluate_policy",
                        lambda model, env, **kwargs: evaluations.append(kwargs) or (-1.0, 0.0))
    result = original("TD3", 0, 5, 0, {})           # one learn call, then the final evaluation
    assert result["curve"] == [(5, -1.0)]
    assert evaluations == [{"n_eval_episodes": 10, "deterministic": True}]
