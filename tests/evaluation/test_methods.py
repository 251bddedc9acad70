"""The method registry and its runners: every method plays a small episode; the PlannedMethod
adapter; bad names and a missing policy checkpoint."""

import dataclasses
import math

import numpy as np
import pytest

from aoass_env.config import AOASSConfig
from aoass_env.evaluation import methods as methods_module
from aoass_env.evaluation.episode import run_episode
from aoass_env.evaluation.methods import (
    ADAPTIVE_POLICY_COMMAND,
    METHODS,
    POLICY_COMMAND,
    RunOptions,
    select_methods,
)
from aoass_env.evaluation.store import COLUMNS, EvaluationError
from aoass_env.maps import load_map
from aoass_env.planning import PlannedMethod, polyline_path
from aoass_env.planning.classical import CLASSICAL_METHODS

LOCALIZERS = ("dvhop", "olstm-dvhop")
#: Enough control periods (0.5 s each) to sweep part of the 40 m field.
STEPS = 160


@pytest.mark.parametrize("method", select_methods(None))   # every shipped method
def test_every_method_plays_a_small_episode_with_finite_metrics(method, small_key):
    rows = run_episode(small_key(method), LOCALIZERS, RunOptions(max_steps=STEPS))
    assert [r["localizer"] for r in rows] == list(LOCALIZERS)
    for r in rows:
        assert set(r) == set(COLUMNS)
        assert r["method"] == method and r["n_nodes"] == 20
        assert 0.0 <= r["coverage"] <= 1.0 and r["beacons"] > 1  # no quality asked of policies
        assert 0.0 < r["path_length"] and r["travel_time"] <= STEPS * 0.5 + 1e-9
        for name in ("ideal_length", "ideal_time", "eta_traj", "energy_total", "e_norm", "eer",
                     "wall_seconds", "localize_seconds"):
            assert math.isfinite(r[name]) and r[name] > 0, name
        assert r["collisions"] == r["collisions_static"] + r["collisions_moving"]
        # cut at STEPS, or ended by itself before (the adaptive policy sweeps 40 m in 128)
        assert r["path_complete"] == (r["travel_time"] < STEPS * 0.5 - 1e-9)
        assert r["localized"] == pytest.approx(r["coverage"])   # both localize the covered
        assert math.isfinite(r["rmse"]) or r["localized"] == 0.0
        if METHODS[method].kind in ("aoass", "ablation"):
            assert r["safety_intervention"] >= 0.0
        else:
            assert r["safety_intervention"] is None


def test_every_method_sees_the_same_nodes_for_the_same_seed(small_map):
    obstacle_map = load_map(small_map)
    config = AOASSConfig(field_size=40.0, n_nodes=20, map=str(small_map))
    options = RunOptions(max_steps=2)
    nodes = [METHODS[m].runner(config, obstacle_map, 3, options).log.nodes
             for m in ("spiral", "aoass-scripted")]
    np.testing.assert_array_equal(nodes[0], nodes[1])
    other = METHODS["spiral"].runner(config, obstacle_map, 4, options).log.nodes
    assert not np.array_equal(nodes[0], other)


def test_an_episode_depends_on_its_key_only(small_key):
    def stable(rows):     # NaN (no node localized) compares equal to itself here
        return [{k: "nan" if isinstance(v, float) and math.isnan(v) else v
                 for k, v in r.items() if not k.endswith("seconds")} for r in rows]
    first = run_episode(small_key("aoass-scripted", seed=1), ("dvhop",), RunOptions(max_steps=60))
    run_episode(small_key("aoass-scripted", seed=2), ("dvhop",), RunOptions(max_steps=60))
    again = run_episode(small_key("aoass-scripted", seed=1), ("dvhop",), RunOptions(max_steps=60))
    assert stable(first) == stable(again)


class StopAfter:
    """A controller that drives east at 1 m/s for ``n`` control periods."""

    def __init__(self, n: int) -> None:
        self.left = n

    @property
    def done(self) -> bool:
        return self.left < 0

    def command(self, position, heading, dt):
        self.left -= 1
        return 1.0, 0.0


def _line(_map, config):
    return polyline_path(np.array([[2.0, 5.0], [38.0, 5.0], [38.0, 15.0]]),
                         config.beacon_interval)


@pytest.mark.parametrize("controller", [None, lambda sim: StopAfter(10)])
def test_a_planned_method_is_registered_and_run_by_the_adapter(monkeypatch, small_key,
                                                               controller):
    line = PlannedMethod("test-line", "Test line", "a test", _line, controller)
    monkeypatch.setitem(CLASSICAL_METHODS, "test-line", line)
    registry = methods_module._registry()
    assert registry["test-line"].kind == "classical"
    assert registry["test-line"].label == "Test line"
    monkeypatch.setattr(methods_module, "METHODS", registry)
    monkeypatch.setattr("aoass_env.evaluation.episode.METHODS", registry)
    (row,) = run_episode(small_key("test-line"), ("dvhop",), RunOptions())
    assert row["ideal_length"] == pytest.approx(46.0)          # 36 m east + 10 m north
    assert row["ideal_time"] == pytest.approx(46.0)            # at the nominal 1 m/s
    assert row["path_complete"] == 1
    if controller is None:                                      # the follower sweeps the line
        assert row["path_length"] == pytest.approx(46.0, rel=0.1)
    else:                                                       # stops after 10 periods
        assert row["travel_time"] == pytest.approx(5.0)


def test_a_name_registered_twice_is_an_error(monkeypatch):
    monkeypatch.setitem(CLASSICAL_METHODS, "spiral", PlannedMethod("spiral", "x", "x", _line))
    with pytest.raises(RuntimeError, match="'spiral' is registered twice"):
        methods_module._registry()


def test_unknown_method_lists_the_valid_names():
    with pytest.raises(EvaluationError) as err:
        select_methods(["spiral", "nope"])
    assert "'nope'" in str(err.value)
    assert all(name in str(err.value) for name in METHODS)


def test_missing_policy_names_the_file_and_the_command(tmp_path):
    missing = tmp_path / "best.zip"
    with pytest.raises(EvaluationError) as err:
        select_methods(["spiral", "aoass"], missing)
    assert str(missing) in str(err.value) and POLICY_COMMAND in str(err.value)
    assert "docs/training.md" in str(err.value)
    assert select_methods(["spiral", "aoass-scripted"], missing) == ["spiral", "aoass-scripted"]
    assert select_methods(None) == [m for m, spec in METHODS.items() if spec.available]
    assert [m for m, spec in METHODS.items() if spec.checkpoint is not None] == ["aoass-adaptive"]


def test_a_missing_adaptive_policy_is_left_out_of_all_and_named_when_asked_for(tmp_path,
                                                                                monkeypatch):
    monkeypatch.setitem(METHODS, "aoass-adaptive",
                        dataclasses.replace(METHODS["aoass-adaptive"],
                                            checkpoint=tmp_path / "best.zip"))
    assert "aoass-adaptive" not in select_methods(None)
    assert "aoass-rule" in select_methods(None)
    with pytest.raises(EvaluationError) as err:
        select_methods(["aoass-adaptive"])
    assert str(tmp_path / "best.zip") in str(err.value)
    assert ADAPTIVE_POLICY_COMMAND in str(err.value)


class CountingPolicy:
    """Stands in for the TD3-LSTM policy: the zero action, counting decisions."""

    def __init__(self) -> None:
        self.calls = 0

    def predict(self, obs, state=None, episode_start=None, deterministic=False):
        self.calls += 1
        return np.zeros(2, np.float32), state


def test_the_policy_acts_in_the_stack_it_was_trained_in(monkeypatch, tmp_path, small_key):
    policy = tmp_path / "best.zip"
    assert methods_module.policy_stack(str(policy)) == {}
    (tmp_path / "run.yml").write_text(
        "algo: td3-lstm\nhyperparameters:\n  env: {n_nodes: 100, action_repeat: 4, "
        "safety: {margin: 0.3}}\n")
    assert methods_module.policy_stack(str(policy)) == {"action_repeat": 4,
                                                        "safety": {"margin": 0.3}}
    fake = CountingPolicy()
    monkeypatch.setattr(methods_module, "load_policy", lambda path, algo, record: fake)
    (row,) = run_episode(small_key("aoass"), ("dvhop",),
                         RunOptions(policy=str(policy), max_steps=40))
    assert fake.calls == 10 and row["travel_time"] == pytest.approx(20.0)  # 40 periods of 0.5 s


def test_safety_stack_runs_report_the_eq14_return(small_map):
    """The runner's return is the sum of the stack's rewards over the same control periods."""
    from aoass_env.wrappers import make_safe_env

    obstacle_map = load_map(str(small_map))
    config = AOASSConfig(field_size=40.0, n_nodes=20, map=str(small_map))
    run = METHODS["aoass-scripted"].runner(config, obstacle_map, 3, RunOptions(max_steps=50))
    env = make_safe_env(config=config)
    env.reset(seed=3, options={"map": obstacle_map})
    expected = sum(float(env.step(np.zeros(2, np.float32))[1]) for _ in range(50))
    assert run.episode_return == pytest.approx(expected, rel=1e-12)
    assert run.episode_return != 0.0
    spiral = METHODS["spiral"].runner(config, obstacle_map, 3, RunOptions(max_steps=50))
    assert spiral.episode_return is None


def test_a_constant_action_replaces_the_policy_in_its_stack(monkeypatch, tmp_path, small_map):
    """``constant_action``: the policy is never loaded; its stack still applies (here an action
    repeat of 4); the constant 0 is the zero action's episode; another constant is another
    episode, driven by that action at every step; a wrong length or value is refused by name."""
    policy = tmp_path / "best.zip"
    (tmp_path / "run.yml").write_text(
        "algo: td3-lstm\nhyperparameters:\n  env: {n_nodes: 20, action_repeat: 4}\n")

    def no_policy(*args):
        raise AssertionError("the policy was loaded")

    monkeypatch.setattr(methods_module, "load_policy", no_policy)
    obstacle_map = load_map(str(small_map))
    config = AOASSConfig(field_size=40.0, n_nodes=20, map=str(small_map))

    def run(constant):
        options = RunOptions(policy=str(policy), max_steps=48, constant_action=constant)
        return METHODS["aoass"].runner(config, obstacle_map, 3, options)

    zero = METHODS["aoass-scripted"].runner(config, obstacle_map, 3, RunOptions(max_steps=48))
    held = run((0.0, 0.0))
    # the same rewards, summed four at a time by the action repeat
    assert held.episode_return == pytest.approx(zero.episode_return, rel=1e-12)
    np.testing.assert_array_equal(held.log.anchor_path, zero.log.anchor_path)
    fast = run((1.0, 0.0))
    assert fast.log.anchor_path[-1].tolist() != zero.log.anchor_path[-1].tolist()
    assert len(fast.log.anchor_path) == len(zero.log.anchor_path)    # 48 periods, 12 decisions
    np.testing.assert_array_equal(fast.actions, np.tile(np.float32([1.0, 0.0]), (12, 1)))
    assert zero.actions.shape == (48, 2) and not zero.actions.any()      # one decision a period
    with pytest.raises(ValueError, match="constant_action has 3 entries; .* have 2"):
        run((0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match=r"constant_action=\(0.0, nan\)"):
        run((0.0, math.nan))
    with pytest.raises(ValueError, match="must lie in"):
        run((1.5, 0.0))


def test_the_adaptive_policys_command_is_the_one_its_run_record_names():
    """The command printed for a missing adaptive checkpoint said --seed 3 (an earlier
    policy's) while the shipped one was trained with --seed 4 --threads 1."""
    import yaml

    from aoass_env.evaluation.methods import ADAPTIVE_POLICY
    record = yaml.safe_load(ADAPTIVE_POLICY.with_name("run.yml").read_text())
    args = ADAPTIVE_POLICY_COMMAND.split()
    flags = {a: b for a, b in zip(args, args[1:], strict=False) if a.startswith("--")}
    assert (int(flags["--seed"]), flags["--config"], int(flags["--threads"])) == (
        record["seed"], "configs/aoass_adaptive.yml", 1)
    assert f"--seed {record['seed']} --threads 1" in record["command"]
