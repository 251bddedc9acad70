"""benchmarks/agent_vs_spiral.py's ``--constant`` and ``--localizer`` flags."""

import dataclasses
import types

import numpy as np
import pytest

from tests.benchmarks.conftest import load_benchmark

bench = load_benchmark("agent_vs_spiral")


def test_constant_is_one_action_of_the_stack_in_bounds():
    assert bench.parse_constant("1,0,1,1,1", adaptive=True) == (1.0, 0.0, 1.0, 1.0, 1.0)
    assert bench.parse_constant("-1,0.5", adaptive=False) == (-1.0, 0.5)
    for text, adaptive, message in (("1,0", True, "5 numbers in"),
                                    ("1,0,0,0,0", False, "2 numbers"),
                                    ("1,x", False, "not 2 comma-separated numbers"),
                                    ("1.5,0", False, r"in \[-1, 1\]"),
                                    ("nan,0", False, r"in \[-1, 1\]")):
        with pytest.raises(ValueError, match=rf"--constant '{text}': .*{message}"):
            bench.parse_constant(text, adaptive)


def test_action_summary_is_the_mean_per_entry_and_the_share_at_the_bounds():
    actions = np.array([[1.0, -0.95, 0.0], [0.9, 0.2, -0.89]])
    summary = bench.action_summary(actions, ("dv", "dtheta", "skip"))
    assert summary == pytest.approx({"mean_dv": 0.95, "mean_dtheta": -0.375,
                                     "mean_skip": -0.445, "saturated": 3 / 6})


def test_the_constant_reaches_the_runner_of_the_agent_only(monkeypatch):
    seen = {}

    def runner(config, obstacle_map, seed, options):
        seen[options.constant_action is None] = options
        return types.SimpleNamespace(episode_return=0.0, actions=np.zeros((3, 5), np.float32))

    metrics = dict.fromkeys(("eta_traj", "coverage", "energy_total", "collisions",
                             "travel_time", "path_complete"), 0.0)
    monkeypatch.setattr(bench, "episode_metrics", lambda run: metrics)
    for method in ("aoass-adaptive", "aoass-rule"):
        monkeypatch.setitem(bench.METHODS, method,
                            dataclasses.replace(bench.METHODS[method], runner=runner))
    model = "checkpoints/aoass_adaptive/best.zip"
    agent = bench.episode(("td3-lstm", "test/d0.10_f100_s501", 100, model, True, (1.0,) * 5,
                           None))
    zero = bench.episode(("zero", "test/d0.10_f100_s501", 100, model, True, None, None))
    assert seen[False].constant_action == (1.0,) * 5 and seen[True].adaptive_policy == model
    assert (agent["policy"], zero["policy"]) == ("agent", "zero")
    assert "rmse" not in agent


def test_the_localizer_localizes_the_episodes_own_log(monkeypatch):
    log = object()

    def runner(config, obstacle_map, seed, options):
        return types.SimpleNamespace(episode_return=0.0, actions=np.zeros((3, 5), np.float32),
                                     log=log)

    localized = []

    def localization_row(got, localizer):
        localized.append((got, localizer))
        return {"rmse": 0.75}

    metrics = dict.fromkeys(("eta_traj", "coverage", "energy_total", "collisions",
                             "travel_time", "path_complete"), 0.0)
    monkeypatch.setattr(bench, "episode_metrics", lambda run: metrics)
    monkeypatch.setattr(bench, "localization_row", localization_row)
    monkeypatch.setitem(bench.METHODS, "aoass-rule",
                        dataclasses.replace(bench.METHODS["aoass-rule"], runner=runner))
    row = bench.episode(("zero", "test/d0.10_f100_s501", 100, "x.zip", True, None,
                         "olstm-dvhop"))
    assert localized == [(log, "olstm-dvhop")] and row["rmse"] == 0.75


def test_paired_rmse_is_the_mean_agent_minus_zero_difference():
    rows = [{"map": "m", "seed": s, "policy": p, "rmse": r}
            for s, (a, z) in enumerate(((1.0, 0.8), (0.9, 0.9), (1.2, 1.0)))
            for p, r in (("agent", a), ("zero", z))]
    mean, half = bench.paired(rows, "rmse")
    assert mean == pytest.approx(0.4 / 3) and half > 0


def test_a_fresh_map_is_the_generator_s_map_of_its_seed_density_and_index():
    name = bench.fresh_name(4711, "0.20", 3)
    assert name.split("/")[1][1:5] == "0.20"          # the density column reads it there
    expected = bench.generate_map(100.0, 0.2, np.random.default_rng([4711, 20, 3]))
    got = bench.fresh_map(name)
    assert got.union.equals(expected.union) and got.width == 100.0
    assert not got.union.equals(bench.fresh_map(bench.fresh_name(4711, "0.20", 4)).union)


@pytest.mark.parametrize("argv, message", [
    (["--maps", "fresh"], "--fresh SEED goes with --maps fresh"),
    (["--fresh", "3"], "--fresh SEED goes with --maps fresh"),
    (["--maps", "fresh", "--fresh", "-1"], "--fresh must be a non-negative seed"),
    # these used to fail in the pool: an IndexError, multiprocessing's error, a traceback
    (["--seeds", "0"], "argument --seeds: must be an integer >= 1, got '0'"),
    (["--jobs", "0"], "argument --jobs: must be an integer >= 1, got '0'"),
    (["--model", "README.md"], "README.md: no run.yml beside it"),
    (["--densities", "0.7"], "--densities: '0.7' is not one of 0.10, 0.20, 0.30, 0.40, 0.50"),
    (["--densities", "dense"], "--densities: 'dense' is not one of"),
])
def test_fresh_flags_are_checked_before_any_episode(monkeypatch, capsys, argv, message):
    monkeypatch.setattr("sys.argv", ["agent_vs_spiral.py", "--adaptive", "--model",
                                     "checkpoints/aoass_adaptive/best.zip", *argv])
    monkeypatch.setattr(bench, "Pool", None)      # an episode would fail on it
    with pytest.raises(SystemExit):
        bench.main()
    assert message in capsys.readouterr().err


@pytest.mark.parametrize("text, name", [("0.5", "0.50"), ("0.10", "0.10"), (".6", "0.60")])
def test_a_density_is_named_as_the_maps_name_it(text, name):
    assert bench.density_name(text) == name
