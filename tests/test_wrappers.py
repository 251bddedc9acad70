"""The safety-stack wrappers: checkers, layout, determinism, safety, map sampling, bad input."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import aoass_env  # noqa: F401  (registers the environments)
from aoass_env import AOASSEnv, ConfigError
from aoass_env.action import ResidualAction
from aoass_env.config import AOASSConfig
from aoass_env.maps import ObstacleMap
from aoass_env.registration import SAFE_ENV_ID
from aoass_env.safety.config import SafetyConfig, TrackerConfig
from aoass_env.wrappers import (
    ActionRepeat,
    FuzzyORCASafety,
    KalmanObstacleTracker,
    MapSampler,
    make_safe_env,
)

SMALL = dict(field_size=40.0, n_nodes=30, obstacle_density=0.1, n_moving_obstacles=2)


def run(env: gym.Env, seed: int, steps: int, actions=None):
    """(observations, rewards, infos) of ``steps`` steps from a seeded reset."""
    rng = np.random.default_rng(seed)
    obs, info = env.reset(seed=seed)
    out = [(obs, 0.0, info)]
    for _ in range(steps):
        a = rng.uniform(-1, 1, 2).astype(np.float32) if actions is None else actions
        obs, reward, terminated, truncated, info = env.step(a)
        out.append((obs, reward, info))
        if terminated or truncated:
            break
    return out


# --- checkers and registration --------------------------------------------------------------
@pytest.mark.parametrize("checker", ["gymnasium", "sb3"])
def test_env_checkers_pass_without_warnings(checker):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        # the checker warns about any wrapper; checking the wrappers is the point here
        warnings.filterwarnings("ignore", message=".*different from the unwrapped version")
        if checker == "gymnasium":
            gym_check_env(make_safe_env(**SMALL), skip_render_check=True)
        else:
            sb3_check_env(make_safe_env(**SMALL), warn=True)


def test_registered_id_builds_the_full_stack():
    env = gym.make(SAFE_ENV_ID, **SMALL)
    assert isinstance(env.unwrapped, AOASSEnv)
    kinds = []
    inner = env
    while isinstance(inner, gym.Wrapper):
        kinds.append(type(inner))
        inner = inner.env
    assert FuzzyORCASafety in kinds and KalmanObstacleTracker in kinds
    assert kinds.index(FuzzyORCASafety) < kinds.index(KalmanObstacleTracker)
    env.reset(seed=0)
    info = env.step(np.zeros(2, np.float32))[4]
    assert {"intervention", "active_static", "speed_cmd"} <= set(info["safety"])


# --- Kalman observation wrapper -------------------------------------------------------------
def test_tracker_layout_appends_predictions_and_stays_in_bounds():
    env = make_safe_env(**SMALL)
    layout = env.get_wrapper_attr("obs_layout")
    n = env.unwrapped.observation_space.shape[0]
    assert layout["moving_predicted"] == slice(n, n + 2 * env.unwrapped.config.obs_moving_obstacles)
    assert env.observation_space.shape == (n + 2 * env.unwrapped.config.obs_moving_obstacles,)
    for obs, _, _ in run(env, seed=4, steps=120):
        assert env.observation_space.contains(obs)


def test_noiseless_tracks_match_the_true_obstacles():
    env = KalmanObstacleTracker(AOASSEnv(**{**SMALL, "n_moving_obstacles": 3},
                                         obs_position_noise=0.0, obs_velocity_noise=0.0,
                                         sensing_range=200.0), TrackerConfig(horizon=2.0))
    env.reset(seed=2)
    for _ in range(5):
        env.step(np.zeros(2, np.float32))
    world = env.unwrapped.sim.world
    tracks = env.tracked_obstacles
    assert len(tracks) == 3
    for x, y, vx, vy, radius in tracks:
        j = int(np.argmin(np.hypot(*(world.moving_positions - (x, y)).T)))
        assert math.hypot(x - world.moving_positions[j, 0], y - world.moving_positions[j, 1]) \
            < 0.05
        assert math.hypot(vx - world.moving_velocities[j, 0],
                          vy - world.moving_velocities[j, 1]) < 0.05
        assert radius == env.unwrapped.config.moving_obstacle_radius


def test_filtered_velocities_beat_the_raw_detections():
    env = KalmanObstacleTracker(AOASSEnv(field_size=100.0, n_nodes=20, obstacle_density=0.0,
                                         n_moving_obstacles=3, obs_velocity_noise=0.4,
                                         obs_position_noise=0.6, sensing_range=200.0,
                                         obs_moving_obstacles=3, moving_obstacle_turn_rate=0.0))
    env.reset(seed=5)
    raw, filt = [], []
    for k in range(80):
        env.step(np.zeros(2, np.float32))
        world = env.unwrapped.sim.world
        if k < 20:
            continue
        for x, y, vx, vy in env.last_detections:
            j = int(np.argmin(np.hypot(*(world.moving_positions - (x, y)).T)))
            raw.append(np.hypot(*(world.moving_velocities[j] - (vx, vy))))
        for x, y, vx, vy, _ in env.tracked_obstacles:
            j = int(np.argmin(np.hypot(*(world.moving_positions - (x, y)).T)))
            filt.append(np.hypot(*(world.moving_velocities[j] - (vx, vy))))
    ratio = np.sqrt(np.mean(np.square(filt))) / np.sqrt(np.mean(np.square(raw)))
    assert ratio < 0.6      # measured 0.51 (process noise 0.5 m/s^2, dt 0.5 s)


# --- the safety filter ----------------------------------------------------------------------
def test_same_seed_and_actions_give_the_same_episode():
    a = run(make_safe_env(**SMALL), seed=7, steps=150)
    b = run(make_safe_env(**SMALL), seed=7, steps=150)
    assert len(a) == len(b)
    for (oa, ra, ia), (ob, rb, ib) in zip(a, b, strict=True):
        np.testing.assert_array_equal(oa, ob)
        assert ra == rb and ia.get("safety") == ib.get("safety")


def test_action_repeat_holds_the_action_and_sums_the_rewards():
    """Four held steps of the repeated env are the same four steps of the plain stack."""
    action = np.array([0.4, -0.2], np.float32)
    plain = run(make_safe_env(**SMALL), seed=3, steps=400, actions=action)
    held = run(make_safe_env(**SMALL, action_repeat=4), seed=3, steps=100, actions=action)
    assert isinstance(make_safe_env(**SMALL, action_repeat=4), ActionRepeat)
    for k in range(1, len(held)):
        obs, reward, info = held[k]
        np.testing.assert_array_equal(obs, plain[4 * k][0])
        assert reward == pytest.approx(sum(r for _, r, _ in plain[4 * k - 3:4 * k + 1]))
        assert info.get("safety") == plain[4 * k][2].get("safety")
    for bad in (0, 1.5, True):
        with pytest.raises(ValueError, match="action_repeat"):
            make_safe_env(**SMALL, action_repeat=bad)


def test_action_repeat_stops_at_the_end_of_the_episode():
    env = ActionRepeat(gym.wrappers.TimeLimit(make_safe_env(**SMALL), 10), 4)
    env.reset(seed=0)
    ends = [env.step(np.zeros(2, np.float32))[3] for _ in range(3)]
    assert ends == [False, False, True]   # 4 + 4 + the 2 left


def test_random_agent_in_a_dense_field_never_touches_a_static_obstacle():
    """A worst-case agent (uniform random actions) in a dense field: the bare environment
    lets it scrape obstacles, the stack does not."""
    kwargs = dict(field_size=40.0, n_nodes=20, obstacle_density=0.5, n_moving_obstacles=0)

    def static_contacts(env: gym.Env, seed: int) -> int:
        info = run(env, seed=seed, steps=600)[-1][2]
        return info["static_contacts"] + info["wall_contacts"]

    bare = sum(static_contacts(gym.make("AOASS-v0", **kwargs), s) for s in range(3))
    stacked = sum(static_contacts(make_safe_env(**kwargs), s) for s in range(3))
    assert bare > 0         # the scenario does provoke contacts
    assert stacked == 0


def test_a_standing_anchor_steps_aside_from_an_oncoming_obstacle():
    """A moving obstacle heading straight at the anchor makes the filter move it."""
    kwargs = dict(field_size=40.0, n_nodes=10, obstacle_density=0.0, n_moving_obstacles=1,
                  moving_obstacle_turn_rate=0.0, moving_obstacle_speed=(1.0, 1.0),
                  obs_position_noise=0.0, obs_velocity_noise=0.0)
    stop = np.array([-1.0, 0.0], np.float32)         # desired speed 0: the anchor stands

    def moving_contacts(env: gym.Env) -> int:
        return sum(run(env, seed=s, steps=200, actions=stop)[-1][2]["moving_contacts"]
                   for s in range(4))

    assert moving_contacts(gym.make("AOASS-v0", **kwargs)) > 0    # it does get hit bare
    assert moving_contacts(make_safe_env(**kwargs)) == 0


def test_safety_report_is_consistent():
    env = make_safe_env(**SMALL)
    env.reset(seed=1)
    for _, _, info in run(env, seed=1, steps=60)[1:]:
        s = info["safety"]
        assert s["intervention"] >= 0 and s["orca_correction"] >= 0
        assert 0 <= s["active"] <= s["constraints"] and 0 <= s["active_static"] <= s["static"]
        assert 0.0 <= s["flc_speed"] <= 1.0 and -1.0 <= s["flc_turn"] <= 1.0
        assert 0.0 <= s["speed_cmd"] <= env.unwrapped.config.anchor_max_speed + 1e-12


def test_the_look_ahead_takes_the_yielding_tolerance_and_headway_price_while_yielding(
        monkeypatch):
    """While the escape budget yields to the sweep, the look-ahead's contest runs with
    ``yield_shortfall_tolerance`` and ``yield_progress_weight`` (issue 24, third round),
    otherwise with ``shortfall_tolerance`` and ``progress_weight``."""
    import aoass_env.wrappers as wrappers

    seen = []
    real = wrappers.escape_velocity

    def spy(*args, **kwargs):
        seen.append((kwargs["tolerance"], kwargs["progress_weight"], kwargs["maneuver"]))
        return real(*args, **kwargs)

    monkeypatch.setattr(wrappers, "escape_velocity", spy)
    cfg = SafetyConfig(shortfall_tolerance=1.0, yield_shortfall_tolerance=3.0,
                       progress_weight=2.0, yield_progress_weight=10.0, maneuver_share=0.5)
    env = make_safe_env(safety=cfg, **SMALL)
    env.reset(seed=1)
    v = np.array([1.0, 0.0])
    env._look_ahead(v, v)
    env.escape_budget.yielding = True
    env._look_ahead(v, v)
    assert seen == [(1.0, 2.0, 0.5), (3.0, 10.0, 0.0)]


# --- map sampling ---------------------------------------------------------------------------
def test_map_sampler_draws_reproducibly_and_cycles_in_order():
    maps = ["test/d0.10_f100_s500", "test/d0.20_f100_s503", "test/d0.30_f100_s506"]
    env = MapSampler(AOASSEnv(n_nodes=20), maps)
    first = []
    for seed in (3, 3, 4):
        env.reset(seed=seed)
        first.append(env.unwrapped.sim.map.name)
    assert first[0] == first[1]
    drawn = set()
    for _ in range(12):
        env.reset()
        drawn.add(env.unwrapped.sim.map.name)
    assert drawn == {m.split("/")[1] for m in maps}
    cyc = MapSampler(AOASSEnv(n_nodes=20), maps, cycle=True)
    names = []
    for _ in range(4):
        cyc.reset(seed=0)
        names.append(cyc.unwrapped.sim.map.name)
    assert names == [m.split("/")[1] for m in maps] + [maps[0].split("/")[1]]


# --- bad input ------------------------------------------------------------------------------
def test_safety_filter_needs_full_range_actions_and_its_tracker():
    tracked = KalmanObstacleTracker(AOASSEnv(**SMALL))
    with pytest.raises(ValueError, match="reaches every speed and heading"):
        FuzzyORCASafety(tracked, tracked)
    full = KalmanObstacleTracker(AOASSEnv(**SMALL, action_type=ResidualAction.full_range(
        AOASSConfig(**SMALL))))
    with pytest.raises(TypeError, match="tracker must be the KalmanObstacleTracker"):
        FuzzyORCASafety(full, None)
    with pytest.raises(TypeError, match="tracker must be the KalmanObstacleTracker"):
        FuzzyORCASafety(full, tracked)             # another environment's tracker
    with pytest.raises(ConfigError, match=r"time_horizon=-1.0 must be a number in \(0.0"):
        FuzzyORCASafety(full, full, SafetyConfig(time_horizon=-1.0))
    with pytest.raises(ConfigError, match="moving_margin"):
        FuzzyORCASafety(full, full, {"moving_margin": float("nan")})
    with pytest.raises(ConfigError, match="unknown safety keyword 'heading_scale'"):
        make_safe_env(safety={"heading_scale": 0.3})
    with pytest.raises(ConfigError, match="tracker must be a TrackerConfig"):
        make_safe_env(tracker=[2.0])
    with pytest.raises(TypeError, match="wraps an AOASS-v0"):
        KalmanObstacleTracker(gym.make("Pendulum-v1"))
    with pytest.raises(ValueError, match="non-empty list"):
        MapSampler(AOASSEnv(**SMALL), [])
    env = make_safe_env(**SMALL)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action must be finite"):
        env.step(np.array([np.nan, 0.0]))


def test_free_space_loops_put_free_space_on_the_right():
    m = ObstacleMap(20.0, 10.0, (np.array([[5.0, 2.0], [8.0, 2.0], [8.0, 6.0], [5.0, 6.0]]),))
    loops = m.free_space_loops
    assert len(loops) == 2
    signed = [0.5 * np.sum(lp[:, 0] * np.roll(lp[:, 1], -1) - np.roll(lp[:, 0], -1) * lp[:, 1])
              for lp in loops]
    assert sorted(signed) == pytest.approx([-200.0, 12.0])    # border clockwise, box CCW
