"""What the registered ids promise: a truthful spec, copying, config dicts, the cost signal and
the benchmark setups (issue 22)."""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import pickle
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import aoass_env  # noqa: F401  (registers the environments)
from agents.sections import read_yaml
from aoass_env.config import AOASSConfig, ConfigError
from aoass_env.env import COST_KEYS, max_episode_steps
from aoass_env.maps import list_maps, load_map, validation_split
from aoass_env.planning import AdaptiveConfig
from aoass_env.registration import (
    ADAPTIVE_TRAIN_ENV_ID,
    ENV_IDS,
    QUICK_ENV_ID,
    SAFE_ENV_ID,
    TRAIN_ENV_ID,
)
from aoass_env.wrappers import ActionRepeat, MapSampler

ROOT = Path(__file__).resolve().parents[1]
SMALL = dict(field_size=30.0, n_nodes=20, obstacle_density=0.2, n_moving_obstacles=3)
#: full speed while turning: drives into obstacles and walls (the bare environment)
RAM = np.array([1.0, 0.6], np.float32)


def wrapper(env: gym.Env, kind: type) -> gym.Env:
    """The first wrapper of type ``kind`` in ``env``'s chain."""
    while not isinstance(env, kind):
        env = env.env
    return env


def test_spec_counts_agent_steps_under_an_action_repeat():
    assert gym.make(SAFE_ENV_ID, action_repeat=16).spec.max_episode_steps == math.ceil(7760 / 16)
    # a time limit that ends the episode before the sweep does: the agent steps it takes
    env = gym.make(SAFE_ENV_ID, action_repeat=7, time_limit_factor=1.0, **SMALL)
    limit = env.unwrapped.max_episode_steps
    assert env.spec.max_episode_steps == math.ceil(limit / 7)
    env.reset(seed=0)
    steps, truncated, terminated = 0, False, False
    while not (terminated or truncated):
        *_, terminated, truncated, info = env.step(np.zeros(env.action_space.shape, np.float32))
        steps += 1
    assert truncated and not terminated
    assert steps == env.spec.max_episode_steps
    assert info["episode_metrics"]["steps"] == limit


@pytest.mark.parametrize("env_id", [ENV_IDS[0], QUICK_ENV_ID])
def test_a_user_time_limit_keeps_the_episode_metrics(env_id):
    env = gym.make(env_id, max_episode_steps=5)
    assert env.spec.max_episode_steps == 5
    env.reset(seed=0)
    for step in range(5):
        *_, terminated, truncated, info = env.step(np.zeros(env.action_space.shape, np.float32))
        assert truncated == (step == 4) and not terminated
    repeat = env.unwrapped.spec.kwargs.get("action_repeat", 1)
    assert info["episode_metrics"]["steps"] == 5 * repeat
    assert info["episode_metrics"]["beacons"] == info["beacons"] > 0
    assert env.unwrapped.beacon_log.n_beacons == info["beacons"]
    with pytest.raises(RuntimeError, match="episode has ended"):
        env.unwrapped.step(np.zeros(env.unwrapped.action_space.shape, np.float32))


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_every_id_serialises_and_remakes_from_its_spec(env_id):
    env = gym.make(env_id, n_nodes=20)
    again = gym.make(gym.envs.registration.EnvSpec.from_json(env.spec.to_json()))
    assert json.loads(again.spec.to_json()) == json.loads(env.spec.to_json())
    assert again.unwrapped.config == env.unwrapped.config


@pytest.mark.parametrize("env_id, repeat", [(ENV_IDS[0], 1), (SAFE_ENV_ID, 4)])
def test_an_env_remade_from_its_spec_keeps_each_episodes_limit(env_id, repeat):
    from aoass_env.maps import ObstacleMap
    small = dict(field_size=20.0, n_nodes=10, time_limit_factor=1.0,
                 **({"action_repeat": repeat} if repeat > 1 else {}))
    bigger = ObstacleMap(30.0, 30.0, name="empty30")
    stop = np.array([-1.0, 0.0], np.float32)     # speed 0: only the time limit ends it
    env = gym.make(env_id, **small)
    remade = gym.make(env.spec)                  # adds a TimeLimit of the limit it reports
    for e in (env, remade):
        e.reset(seed=510070)
        first = e.spec.max_episode_steps
        e.reset(seed=510070, options={"map": bigger})
        own = math.ceil(e.unwrapped.max_episode_steps / repeat)
        # the spec is the recipe: the limit of the env as made, whatever map a reset brings
        assert e.spec.max_episode_steps == first < own
        steps, truncated = 0, False
        while not truncated:
            *_, terminated, truncated, info = e.step(stop)
            steps += 1
            assert not terminated
        # the remade env used to cut the bigger map's episode at the first limit
        assert steps == own and "episode_metrics" in info
    user = gym.make(env_id, max_episode_steps=5, **small)
    user.reset(seed=510070, options={"map": bigger})
    assert user.spec.max_episode_steps == 5      # a limit of the user's own stays
    # one above the environment's own was reported by the spec, and never reached (the
    # environment truncated at its own)
    with pytest.raises(ConfigError, match=rf"max_episode_steps={first + 1} is above the "
                                          rf"environment's own limit of {first} agent steps"):
        gym.make(env_id, max_episode_steps=first + 1, **small)


@pytest.mark.parametrize("env_id, repeat", [(ENV_IDS[0], 1), (SAFE_ENV_ID, 4)])
@pytest.mark.parametrize("side", [15.0, 30.0], ids=["smaller", "bigger"])
def test_an_env_remade_from_its_spec_after_a_reset_on_another_map_is_the_same_env(
        env_id, repeat, side):
    """The spec used to report the last episode's limit: remade after a reset on a smaller map,
    the env cut every episode at that map's limit; after a bigger one, gym.make refused it."""
    from aoass_env.maps import ObstacleMap
    small = dict(field_size=20.0, n_nodes=10, time_limit_factor=1.0,
                 **({"action_repeat": repeat} if repeat > 1 else {}))
    stop = np.array([-1.0, 0.0], np.float32)     # speed 0: only the time limit ends it
    env = gym.make(env_id, **small)
    made = env.spec.max_episode_steps
    env.reset(seed=510071, options={"map": ObstacleMap(side, side, name=f"empty{side:g}")})
    remade = gym.make(env.spec)
    assert remade.spec.max_episode_steps == made
    remade.reset(seed=510071)                    # the recipe's own field again
    steps, truncated = 0, False
    while not truncated:
        *_, terminated, truncated, info = remade.step(stop)
        steps += 1
        assert not terminated
    assert steps == made == math.ceil(remade.unwrapped.max_episode_steps / repeat)
    assert "episode_metrics" in info


def pickled(env: gym.Env) -> gym.Env:
    """``env`` through stdlib pickle."""
    return pickle.loads(pickle.dumps(env))


@pytest.mark.parametrize("env_id", ENV_IDS)
@pytest.mark.parametrize("clone", [pickled, copy.deepcopy], ids=["pickle", "deepcopy"])
def test_every_id_copies_mid_episode_and_the_copy_runs_on_identically(env_id, clone):
    env = gym.make(env_id, n_nodes=20)
    env.reset(seed=3)
    rng = np.random.default_rng(0)
    for _ in range(3):
        env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
    twin = clone(env)
    for _ in range(3):
        action = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        obs, reward, *_ = env.step(action)
        obs_twin, reward_twin, *_ = twin.step(action)
        np.testing.assert_array_equal(obs, obs_twin)
        assert reward == reward_twin


@pytest.mark.parametrize("clone", [pickled, copy.deepcopy], ids=["pickle", "deepcopy"])
def test_a_rendering_env_copies_and_the_copy_draws_the_same_frames(clone):
    """pygame's font and surfaces used to make an env that had rendered fail to pickle."""
    env = gym.make("AOASS-v0", n_nodes=20, field_size=40.0, render_mode="rgb_array")
    env.reset(seed=3)
    for _ in range(4):
        env.step(np.full(2, 0.2, np.float32))
    first = env.render()
    twin = clone(env)
    for _ in range(4):
        env.step(np.full(2, -0.4, np.float32))
        twin.step(np.full(2, -0.4, np.float32))
    frame = env.render()
    assert not np.array_equal(frame, first)          # the anchor moved on the frame
    np.testing.assert_array_equal(twin.render(), frame)


@pytest.mark.parametrize("env_id, typo, meant", [
    ("AOASS-v0", "action_typ", "action_type"), ("AOASS-v0", "render_mod", "render_mode"),
    ("AOASS-Safe-v0", "action_repet", "action_repeat"),
    ("AOASS-Safe-v0", "energy_weigth", "energy_weight"), ("AOASS-Safe-v0", "safty", "safety"),
    ("AOASS-Train-v0", "splt", "split"), ("AOASS-Train-v0", "densitys", "densities"),
    ("AOASS-Train-v0", "n_node", "n_nodes")])
def test_a_misspelt_wrapper_keyword_gets_its_did_you_mean(env_id, typo, meant):
    """Only the config's fields used to be suggested: "action_repet" got 'action_speed_scale'."""
    with pytest.raises(ConfigError, match=rf"unknown config keyword '{typo}'; did you mean "
                                          rf"'{meant}'\? \(valid: .*{meant}"):
        gym.make(env_id, **{typo: 1})


def test_config_dict_or_object_beside_keywords():
    env = gym.make("AOASS-v0", config={"n_nodes": 7, "field_size": 40.0}, n_nodes=9)
    assert (env.unwrapped.config.n_nodes, env.unwrapped.config.field_size) == (9, 40.0)
    env = gym.make("AOASS-v0", config=AOASSConfig(n_nodes=7), radio_range=20.0)
    assert (env.unwrapped.config.n_nodes, env.unwrapped.config.radio_range) == (7, 20.0)
    env = gym.make(SAFE_ENV_ID, config={"n_nodes": 7}, action_heading_scale=0.5)
    assert (env.unwrapped.config.n_nodes, env.unwrapped.config.action_heading_scale) == (7, 0.5)
    # a map keeps its own size: a config object's default field_size gives way to it, a
    # dict's field_size counts as given and a map of another size is refused
    assert gym.make("AOASS-v0", config=AOASSConfig(map="test/d0.10_f200_s518")
                    ).unwrapped.config.field_size == 200.0
    assert gym.make("AOASS-v0", config={"map": "test/d0.10_f200_s518"}
                    ).unwrapped.config.field_size == 200.0
    with pytest.raises(ConfigError, match="field_size"):
        gym.make("AOASS-v0", config={"map": "test/d0.40_f100_s509", "field_size": 200.0})
    with pytest.raises(ConfigError, match="did you mean 'n_nodes'"):
        gym.make("AOASS-v0", config={"n_node": 7})
    with pytest.raises(ConfigError, match="config must be"):
        gym.make("AOASS-v0", config=3)


def test_cost_is_each_steps_new_contacts_static_and_moving_apart():
    env = gym.make("AOASS-v0", **SMALL)
    env.reset(seed=0)
    total = np.zeros(3)
    terminated = truncated = False
    while not (terminated or truncated):
        *_, terminated, truncated, info = env.step(RAM)
        assert info["cost"] == info["cost_static"] + info["cost_moving"]
        total += [info[k] for k in COST_KEYS]
    metrics = info["episode_metrics"]
    assert total.tolist() == [metrics["collisions"], metrics["collisions_static"],
                              metrics["collisions_moving"]]
    assert total[1] > 0 and total[2] > 0     # both kinds happened


def test_an_action_repeat_sums_the_cost_of_its_periods():
    plain = gym.make("AOASS-v0", **SMALL)
    held = ActionRepeat(gym.make("AOASS-v0", **SMALL), 4)
    plain.reset(seed=1)
    held.reset(seed=1)
    for _ in range(40):
        costs = np.zeros(3)
        for _ in range(4):
            *_, info = plain.step(RAM)
            costs += [info[k] for k in COST_KEYS]
        *_, info_held = held.step(RAM)
        assert [info_held[k] for k in COST_KEYS] == costs.tolist()
    assert info_held["collisions"] == info["collisions"] > 0


def test_the_training_id_is_the_shipped_policys_setup():
    env = gym.make(TRAIN_ENV_ID)
    shipped = read_yaml(ROOT / "configs" / "aoass.yml")["td3-lstm"]["env"]
    config = env.unwrapped.config
    assert wrapper(env, ActionRepeat).repeat == shipped["action_repeat"] == 16
    assert config.action_heading_scale == shipped["action_heading_scale"]
    assert config.n_nodes == shipped["n_nodes"] and config.field_size == shipped["field_size"]
    fit, _ = validation_split(list_maps("train", field_size=100.0,
                                        densities=tuple(shipped["densities"])))
    assert fit and all(name.startswith("train/") for name in fit)
    sampled = wrapper(env, MapSampler).maps
    assert [m.name for m in sampled] == [load_map(name).name for name in fit]


def test_the_adaptive_training_id_is_the_shipped_adaptive_policys_setup():
    env = gym.make(ADAPTIVE_TRAIN_ENV_ID)
    shipped = read_yaml(ROOT / "configs" / "aoass_adaptive.yml")["td3-lstm"]["env"]
    run = read_yaml(ROOT / "checkpoints" / "aoass_adaptive" / "run.yml")
    base = env.unwrapped
    assert base.adaptive == AdaptiveConfig(**shipped["adaptive"])
    # every field of the rule named: a later change of AdaptiveConfig's defaults leaves it be
    assert set(shipped["adaptive"]) == {f.name for f in dataclasses.fields(AdaptiveConfig)}
    assert shipped["adaptive"] == run["hyperparameters"]["env"]["adaptive"]
    assert wrapper(env, ActionRepeat).repeat == shipped["action_repeat"]
    assert base.config.obs_coverage_sectors == shipped["obs_coverage_sectors"]
    assert base.config.action_heading_scale == shipped["action_heading_scale"]


def test_the_quick_id_is_a_50_m_field_of_the_same_agent():
    env = gym.make(QUICK_ENV_ID)
    config = env.unwrapped.config
    assert config.field_size == 50.0
    assert wrapper(env, ActionRepeat).repeat == 16 and config.action_heading_scale == 0.2618
    limit = max_episode_steps(config)
    assert env.spec.max_episode_steps == math.ceil(limit / 16) < gym.make(
        TRAIN_ENV_ID).spec.max_episode_steps / 2
