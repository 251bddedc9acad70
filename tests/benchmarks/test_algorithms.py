"""benchmarks/algorithms.py on a tiny budget: every algorithm trains, evaluates and is tabled."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from tests.benchmarks.conftest import load_benchmark

TINY = ["--timesteps", "12", "--eval-every", "6", "--eval-episodes", "1", "--seeds", "0",
        "--env-kwargs", "field_size:30", "n_nodes:10", "time_limit_factor:1.0"]


@pytest.fixture(scope="module")
def bench():
    """``benchmarks/algorithms.py`` loaded as a module."""
    return load_benchmark("algorithms")


def test_every_algorithm_trains_and_is_tabled(bench, tmp_path: Path):
    results = bench.main([*TINY, "--out", str(tmp_path)])
    algos = ["zero-action", "ppo", "sac", "td3", "recurrent-ppo", "recurrent-td3"]
    assert sorted(results) == sorted((a, 0) for a in algos)
    with (tmp_path / "curves.csv").open() as f:
        curves = list(csv.DictReader(f))
    for algo in algos[1:]:      # evaluated every 6 of the 12 steps, after the budget's end last
        assert [int(r["steps"]) for r in curves if r["algo"] == algo] == [6, 12]
    with (tmp_path / "final.csv").open() as f:
        final = {r["algo"]: float(r["final_return"]) for r in csv.DictReader(f)}
    assert final.keys() == set(algos)
    assert final["ppo"] == pytest.approx(results[("ppo", 0)]["curve"][-1][1], abs=1e-4)
    table = (tmp_path / "summary.md").read_text()
    assert "after 12 agent steps on AOASS-Quick-v0" in table
    assert all(f"| {a} | 1 |" in table for a in algos)
    assert (tmp_path / "curves.png").stat().st_size > 10_000


def test_the_evaluation_episodes_are_held_out(bench):
    run = bench.Run("ppo", 0, "AOASS-Train-v0", 1, 1, 1)
    sampler = bench._eval_env(run).envs[0].env
    while not hasattr(sampler, "maps"):
        sampler = sampler.env
    assert [m.name for m in sampler.maps] and all(m.name.startswith("d") for m in sampler.maps)
    assert sampler.cycle                  # the validation maps in turn, never maps/test
    assert bench.EVAL_KWARGS["AOASS-Train-v0"]["split"] == "validation"


@pytest.mark.parametrize("argv, message", [
    (["--algos", "ppo,a2c"], "--algos 'ppo,a2c': each must be one of"),
    (["--timesteps", "0"], "--timesteps must be >= 1, got 0"),
    (["--env-kwargs", "n_node:3"], "n_node"),
    (["--env-kwargs", "n_nodes"], "--env-kwargs: must be key:value"),
])
def test_bad_options_are_one_line_errors(bench, tmp_path: Path, capsys, argv, message):
    with pytest.raises(SystemExit) as exit_:
        bench.main([*argv, "--out", str(tmp_path)])
    assert exit_.value.code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "final.csv").exists()
