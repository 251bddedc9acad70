"""AOASS-v0 registration and compliance: env checkers, vector envs and SB3 algorithms."""

from __future__ import annotations

import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3 import PPO, SAC, TD3
from stable_baselines3.common.env_checker import check_env as sb3_check_env
from stable_baselines3.common.vec_env import SubprocVecEnv

import aoass_env
from aoass_env.env import AOASSEnv

SMALL = dict(field_size=30.0, n_nodes=20, obstacle_density=0.1, n_moving_obstacles=1)


def test_make_without_prior_import_registers_the_env():
    code = ("import gymnasium as gym; env = gym.make('aoass_env:AOASS-v0', n_nodes=5); "
            "print(type(env.unwrapped).__name__, env.spec.max_episode_steps)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == ["AOASSEnv", "7760"]


def test_import_registers_once():
    aoass_env.register()
    assert gym.spec("AOASS-v0").entry_point == "aoass_env.env:make_env"
    assert gym.spec("AOASS-Safe-v0").entry_point == "aoass_env.wrappers:make_safe_env"


def test_gymnasium_env_checker_passes_without_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gym_check_env(gym.make("AOASS-v0", **SMALL).unwrapped, skip_render_check=False)


def test_sb3_env_checker_passes_without_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sb3_check_env(AOASSEnv(**SMALL), warn=True)


@pytest.mark.parametrize("algo", [PPO, SAC, TD3])
def test_sb3_algorithms_train_without_an_adapter(algo):
    env = gym.make("AOASS-v0", **SMALL)
    kwargs = dict(n_steps=64, batch_size=32) if algo is PPO else dict(learning_starts=32,
                                                                          batch_size=32)
    model = algo("MlpPolicy", env, seed=0, device="cpu", **kwargs)
    model.learn(total_timesteps=128)
    action, _ = model.predict(env.reset(seed=0)[0], deterministic=True)
    assert env.action_space.contains(action)


def test_async_vector_env():
    envs = gym.make_vec("AOASS-v0", num_envs=4, vectorization_mode="async", **SMALL)
    try:
        obs, _ = envs.reset(seed=[1, 2, 3, 4])
        assert obs.shape == (4, *envs.single_observation_space.shape)
        assert not np.array_equal(obs[0], obs[1])
        for _ in range(5):
            obs, reward, terminated, truncated, info = envs.step(envs.action_space.sample())
        assert reward.shape == (4,) and envs.single_observation_space.contains(obs[0])
        assert "coverage" in info
    finally:
        envs.close()


def test_sb3_subproc_vec_env():
    venv = SubprocVecEnv([lambda: gym.make("aoass_env:AOASS-v0", **SMALL) for _ in range(2)])
    try:
        venv.seed(0)
        obs = venv.reset()
        obs, reward, done, infos = venv.step(np.zeros((2, 2), dtype=np.float32))
        assert obs.shape[0] == 2 and reward.shape == (2,) and len(infos) == 2
    finally:
        venv.close()


def test_import_registers_without_loading_the_heavy_parts():
    """``import aoass_env`` registers both ids and loads neither the simulator (pymunk,
    shapely), the safety stack (filterpy) nor the localizer (torch); names load on first use."""
    import subprocess
    import sys
    probe = ("import sys, gymnasium, aoass_env; "
             "print(sorted(m for m in ('torch', 'filterpy', 'pymunk', 'shapely') "
             "if m in sys.modules)); "
             "print('AOASS-v0' in gymnasium.registry and 'AOASS-Safe-v0' in gymnasium.registry); "
             "aoass_env.AOASSConfig; print('aoass_env.config' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", probe], check=True, capture_output=True,
                         text=True).stdout.split("\n")
    assert out[:3] == ["[]", "True", "True"]


def test_specs_serialise_and_unknown_names_fail():
    import aoass_env
    for env_id in ("AOASS-v0", "AOASS-Safe-v0"):
        assert gym.spec(env_id).to_json()
    with pytest.raises(AttributeError, match="no attribute 'Nope'"):
        aoass_env.Nope  # noqa: B018
    assert "make_safe_env" in dir(aoass_env)
