"""AOASS-v0: spaces, residual semantics, reward terms, episode end, determinism, bad input."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import aoass_env  # noqa: F401  (registers AOASS-v0)
from aoass_env import AOASSConfig, AOASSEnv, ConfigError, Simulator
from aoass_env.env import max_episode_steps
from aoass_env.registration import TRAIN_ENV_ID
from aoass_env.reward import REWARD_TERMS

SMALL = dict(field_size=40.0, n_nodes=30, obstacle_density=0.1, n_moving_obstacles=2)


def rollout(env: gym.Env, actions, seed: int):
    """Observations, rewards and infos of an episode driven by ``actions(step)``."""
    obs, info = env.reset(seed=seed)
    out = [(obs, 0.0, info)]
    for k in range(100_000):
        obs, reward, terminated, truncated, info = env.step(actions(k))
        out.append((obs, reward, info))
        if terminated or truncated:
            return out, terminated, truncated
    raise AssertionError("episode did not end")


# --- spaces and layout ---------------------------------------------------------------------
def test_spaces_and_layout_cover_the_observation():
    env = AOASSEnv(**SMALL, obs_waypoints=5, obs_moving_obstacles=2, n_rays=12)
    assert env.action_space == gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
    space = env.observation_space
    assert space.dtype == np.float32 and np.all(np.isfinite(space.low))
    assert np.all(np.isfinite(space.high)) and space.shape[0] == 2 + 1 + 1 + 1 + 2 + 10 + 12 \
        + 10 + 3
    layout = env.obs_layout
    assert list(layout)[:4] == ["position", "speed", "d_obs", "heading_error"]
    assert layout["heading_error"].stop == 5            # obs[:5] is Eq. 6's state
    starts = sorted((s.start, s.stop) for s in layout.values())
    assert starts[0][0] == 0 and starts[-1][1] == space.shape[0]
    assert all(a[1] == b[0] for a, b in zip(starts, starts[1:], strict=False))
    assert layout["waypoints"].stop - layout["waypoints"].start == 10
    assert layout["rays"].stop - layout["rays"].start == 12
    assert layout["moving_obstacles"].stop - layout["moving_obstacles"].start == 10


def test_observations_stay_in_bounds_and_match_the_state():
    env = AOASSEnv(**SMALL)
    env.action_space.seed(1)
    obs, _ = env.reset(seed=3)
    lay = env.obs_layout
    for _ in range(150):
        assert env.observation_space.contains(obs)
        world = env.unwrapped.sim.world
        np.testing.assert_allclose(obs[lay["position"]], world.position / 40.0, atol=1e-6)
        np.testing.assert_allclose(obs[lay["rays"]], world.ray_distances() / 10.0, atol=1e-6)
        present = obs[lay["moving_obstacles"]].reshape(-1, 5)[:, 4]
        in_range = np.hypot(*(world.moving_positions - world.position).T) <= 10.0
        assert present.sum() == min(in_range.sum(), 3)
        obs, *_ = env.step(env.action_space.sample())


# --- residual semantics --------------------------------------------------------------------
def test_zero_action_completes_the_spiral_with_full_coverage_in_an_empty_field():
    env = AOASSEnv(field_size=60.0, n_nodes=80, obstacle_density=0.0, n_moving_obstacles=0)
    steps, terminated, truncated = rollout(env, lambda k: np.zeros(2), seed=0)
    assert terminated and not truncated
    info = steps[-1][2]
    assert info["coverage"] == 1.0 and info["collisions"] == 0
    assert info["episode_metrics"]["path_complete"]
    assert info["episode_metrics"]["path_length"] == pytest.approx(env.sim.spiral.length, rel=0.05)


def test_zero_action_reproduces_the_nominal_simulator_episode():
    env = AOASSEnv(**SMALL)
    _, terminated, _ = rollout(env, lambda k: np.zeros(2), seed=11)
    assert terminated
    ref = Simulator(env.config, np.random.default_rng(11)).run()
    log = env.beacon_log
    for key in ("beacons", "receptions", "anchor_path", "node_energy", "nodes"):
        np.testing.assert_array_equal(getattr(log, key), getattr(ref, key), err_msg=key)


def test_actions_steer_the_anchor_off_the_follower():
    env = AOASSEnv(**SMALL)
    env.reset(seed=2)
    for _ in range(10):
        env.step(np.array([-1.0, 0.0]))      # nominal speed 1 m/s - 1 m/s = stop
    assert env.sim.network.distance_travelled < 1e-6
    for _ in range(10):
        env.step(np.array([1.0, 0.0]))
    assert env.sim.world.speed > env.config.anchor_nominal_speed


def test_out_of_range_actions_are_clipped():
    a, b = AOASSEnv(**SMALL), AOASSEnv(**SMALL)
    ra, _, _ = rollout(a, lambda k: np.array([7.0, -3.0]) if k < 30 else np.zeros(2), seed=4)
    rb, _, _ = rollout(b, lambda k: np.array([1.0, -1.0]) if k < 30 else np.zeros(2), seed=4)
    assert len(ra) == len(rb)
    np.testing.assert_array_equal(ra[-1][0], rb[-1][0])


# --- reward --------------------------------------------------------------------------------
def _covered(heard_positions: list[np.ndarray], tol: float) -> bool:
    """Eq. 18 from scratch: >= 3 beacons whose RSS distance to their best line is >= tol."""
    if len(heard_positions) < 3:
        return False
    p = np.array(heard_positions)
    sv = np.linalg.svd(p - p.mean(axis=0), compute_uv=False)
    return sv[-1] >= tol


def test_reward_terms_match_an_independent_recomputation():
    cfg = dict(SMALL, w1=100.0, w2=0.5, w3=0.25, w_collision=3.0)
    env = AOASSEnv(**cfg)
    env.reset(seed=5)
    rx = env.config.packet_bits * env.config.e_elec
    prev_cov = 0.0
    for k in range(120):
        _, reward, terminated, truncated, info = env.step(
            np.array([0.3 * math.sin(k / 7), 0.2]))
        log = env.beacon_log
        heard = [[] for _ in range(log.n_nodes)]
        for b, n in log.receptions:
            heard[n].append(log.beacons[b, 1:])
        covered = np.array([_covered(h, env.config.collinearity_tol) for h in heard])
        energy = np.array([len(h) for h in heard]) * rx
        imbalance = energy.max() / energy.mean() - 1 if energy.mean() > 0 else 0.0
        if covered.any():
            cent = np.array([np.mean(h, axis=0) if h else (0, 0) for h in heard])
            err = np.sum((cent - log.nodes) ** 2, axis=1)[covered]
            rmse = math.sqrt(err.mean())
        else:
            rmse = 0.0
        terms = info["reward_terms"]
        assert set(terms) == set(REWARD_TERMS)
        assert terms["coverage"] == pytest.approx(100.0 * (covered.mean() - prev_cov), abs=1e-9)
        assert terms["energy_balance"] == pytest.approx(-0.5 * imbalance, rel=1e-9, abs=1e-12)
        assert terms["localization"] == pytest.approx(-0.25 * rmse, rel=1e-9, abs=1e-12)
        assert terms["collision"] <= 0.0
        assert reward == pytest.approx(sum(terms.values()))
        prev_cov = covered.mean()
        if terminated or truncated:
            break
    assert prev_cov > 0


def _east(obs: np.ndarray) -> np.ndarray:
    """Full speed due east (+x), whatever the follower wants: drives into the east wall."""
    heading = math.atan2(obs[6], obs[5])
    follower_heading = heading + math.pi * obs[4]
    turn = math.remainder(-follower_heading, 2 * math.pi) / (math.pi / 2)
    return np.array([1.0, min(max(turn, -1.0), 1.0)])


@pytest.mark.parametrize("w_collision", [0.0, 2.0])
def test_collision_shaping_is_off_by_default_and_counts_new_contacts(w_collision):
    env = AOASSEnv(field_size=30.0, n_nodes=5, obstacle_density=0.0, n_moving_obstacles=0,
                   w_collision=w_collision)
    obs, _ = env.reset(seed=0)
    total = 0.0
    for _ in range(60):
        obs, _, _, _, info = env.step(_east(obs))
        total += info["reward_terms"]["collision"]
    assert info["collisions"] > 0 and info["wall_contacts"] > 0
    assert total == pytest.approx(-w_collision * info["collisions"])
    assert AOASSConfig().w_collision == 0.0


# --- episode end ---------------------------------------------------------------------------
def test_truncation_at_the_step_limit_with_episode_metrics():
    env = gym.make("AOASS-v0", **SMALL, time_limit_factor=1.0)
    limit = max_episode_steps(env.unwrapped.config)
    assert env.spec.max_episode_steps == limit == env.unwrapped.max_episode_steps
    steps, terminated, truncated = rollout(env, lambda k: np.array([-1.0, 0.0]), seed=0)
    assert truncated and not terminated and len(steps) - 1 == limit
    metrics = steps[-1][2]["episode_metrics"]
    assert not metrics["path_complete"] and metrics["steps"] == limit
    assert {"coverage", "e_norm", "eer", "eta_traj", "rmse_online"} <= set(metrics)
    with pytest.raises(RuntimeError, match="reset"):
        env.unwrapped.step(np.zeros(2))


def test_max_episode_steps_follows_the_spiral_and_the_margin():
    cfg = AOASSConfig()
    assert cfg.time_limit_factor == 5.0
    assert max_episode_steps(cfg) == math.ceil(5.0 * 776.0 / 0.5)
    assert max_episode_steps(cfg.replace(field_size=200.0)) == math.ceil(5.0 * 2364.0 / 0.5)
    assert max_episode_steps(cfg.replace(time_limit_factor=2.0)) == math.ceil(2.0 * 776.0 / 0.5)


def test_termination_carries_the_eq16_to_19_metrics():
    env = AOASSEnv(**SMALL)
    steps, terminated, _ = rollout(env, lambda k: np.zeros(2), seed=1)
    m = steps[-1][2]["episode_metrics"]
    net = env.sim.network
    assert terminated and m["path_complete"]
    assert m["eer"] == pytest.approx(net.beacons_sent / net.energy_total)
    assert m["e_norm"] == pytest.approx(1.0 / m["eer"])
    assert 0.0 < m["eta_traj"] <= 1.0 + 1e-9
    assert env.beacon_log.n_beacons == net.beacons_sent
    # one summary, one set of keys: evaluation's episodes.csv columns are the env's too
    from aoass_env.evaluation.store import EPISODE_FIELDS
    from aoass_env.simulator import episode_summary
    summary = episode_summary(env.sim, True)
    assert {k: m[k] for k in summary} == summary
    assert set(summary) <= set(EPISODE_FIELDS)
    assert set(m) - set(summary) == {"rmse_online", "steps", "recoveries", "skipped_waypoints",
                                     "area_coverage", "passed_waypoints"}


# --- determinism ---------------------------------------------------------------------------
def test_same_seed_and_actions_give_the_same_episode():
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, size=(10_000, 2))
    runs = []
    for _ in range(2):
        env = AOASSEnv(**SMALL)
        steps, *_ = rollout(env, lambda k: actions[k], seed=21)
        runs.append((steps, env.beacon_log))
    (s1, log1), (s2, log2) = runs
    assert len(s1) == len(s2)
    for (o1, r1, _), (o2, r2, _) in zip(s1, s2, strict=True):
        np.testing.assert_array_equal(o1, o2)
        assert r1 == r2
    for key, value in log1.arrays().items():
        np.testing.assert_array_equal(value, log2.arrays()[key], err_msg=key)


def test_reset_without_seed_draws_a_new_map_but_map_keyword_fixes_it():
    env = AOASSEnv(**SMALL)
    env.reset(seed=0)
    first = env.sim.map.polygons
    env.reset()
    second = env.sim.map.polygons
    assert len(first) != len(second) or not all(
        np.array_equal(a, b) for a, b in zip(first, second, strict=True))
    env = AOASSEnv(map="test/d0.20_f100_s503")
    env.reset(seed=0)
    poly = env.sim.map.polygons
    env.reset(seed=1)
    assert all(np.array_equal(a, b) for a, b in zip(poly, env.sim.map.polygons, strict=True))


# --- bad input -----------------------------------------------------------------------------
@pytest.mark.parametrize("action, match", [
    (np.array([np.nan, 0.0]), "finite"), (np.array([0.0, np.inf]), "finite"),
    (np.zeros(3), r"shape \(2,\)"), ("go", "2 numbers"), (np.zeros((1, 2)), "shape")])
def test_bad_actions_raise_clear_errors(action, match):
    env = AOASSEnv(**SMALL)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        env.step(action)


def test_step_before_reset_is_an_error():
    with pytest.raises(RuntimeError, match="reset"):
        AOASSEnv(**SMALL).step(np.zeros(2))


@pytest.mark.parametrize("kwargs, match", [
    ({"n_node": 10}, "did you mean 'n_nodes'"),
    ({"obstacle_density": 0.9}, "obstacle_density"),
    ({"radio_range": -1}, "radio_range"),
    ({"w1": "high"}, "w1"),
    ({"obs_waypoints": 0}, "obs_waypoints"),
    ({"config": ["n_nodes", 3]}, "config must be a AOASSConfig"),
    ({"config": {"n_node": 3}}, "did you mean 'n_nodes'"),
    # math.ceil(inf) used to escape as an OverflowError
    ({"anchor_nominal_speed": 1e-306}, r"the episode would last inf control periods"),
    ({"dt": 1e-306}, r"over dt=1e-306 s")])
def test_bad_keywords_name_the_parameter(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        gym.make("AOASS-v0", **kwargs)


def test_a_failed_reset_leaves_no_episode_to_step_on():
    """A reset that raised used to leave the previous episode running: step() went on with it."""
    env = AOASSEnv(field_size=20.0, n_nodes=10)
    for seed, options in ((3, None), (0, {"map": 42})):   # in the Simulator; in the options
        env.reset(seed=0)
        env.step(np.zeros(2))
        with pytest.raises(ValueError, match="could not place moving obstacle|'map'"):
            env.reset(seed=seed, options=options)
        with pytest.raises(RuntimeError, match=r"call reset\(\) before step\(\)"):
            env.step(np.zeros(2))


def test_bad_render_mode_map_and_reset_option():
    with pytest.raises(ValueError, match="render_mode"):
        AOASSEnv(render_mode="ascii")
    with pytest.raises(ConfigError, match="map='no/such_map'"):
        AOASSEnv(map="no/such_map")
    env = AOASSEnv(**SMALL)
    with pytest.raises(ValueError, match="reset option"):
        env.reset(seed=0, options={"mpa": "x"})


@pytest.mark.parametrize("options", ["x", 5, [("map", None)], {1: "x"}])
def test_reset_options_that_are_not_a_dict_are_refused_naming_them(options):
    # "x" failed deep in dict() ("dictionary update sequence element #0 ..."), 5 with "'int'
    # object is not iterable", and a list of pairs was taken as a dict
    for env in (AOASSEnv(**SMALL), gym.make(TRAIN_ENV_ID, n_nodes=10)):
        with pytest.raises(ValueError, match=r"^reset options must be a dict like "):
            env.reset(seed=0, options=options)


def test_config_object_and_keywords_combine():
    env = AOASSEnv(config=AOASSConfig(n_nodes=12), field_size=50.0)
    assert env.config.n_nodes == 12 and env.config.field_size == 50.0


def test_a_deferred_observation_is_built_on_demand_and_only_then():
    """defer_observation: the step returns None and its observation is built by
    deferred_observation(), the vector the step would have returned; asking for it after a
    step that returned its own (or before any step) is an error naming the method."""
    deferring, plain = (gym.make("AOASS-v0", field_size=40.0, n_moving_obstacles=4)
                        for _ in range(2))
    for env in (deferring, plain):
        env.reset(seed=12)
    base = deferring.unwrapped
    with pytest.raises(RuntimeError, match="deferred_observation"):
        base.deferred_observation()
    rng = np.random.default_rng(12)
    for k in range(60):
        action = rng.uniform(-1, 1, 2).astype(np.float32)
        base.defer_observation = k % 3 != 0    # the checker of gym.make reads the first
        got = deferring.step(action)
        want = plain.step(action)
        if base.defer_observation:
            assert got[0] is None
            obs = base.deferred_observation()
            assert obs.tobytes() == base.deferred_observation().tobytes()   # no side effects
        else:
            obs = got[0]
            with pytest.raises(RuntimeError, match="deferred_observation"):
                base.deferred_observation()
        assert obs.tobytes() == want[0].tobytes() and got[1] == want[1]


@pytest.mark.parametrize("env_id", ["AOASS-v0", "AOASS-Adaptive-v0"])
def test_generated_maps_are_freed_after_their_episodes(env_id):
    """A map generated for an episode, and what the env derives from it (planner grid, coverage
    raster, line-of-sight test, plans), is freed once no episode and no cache holds it: resets
    on fresh maps do not grow memory without bound (each map pinned itself through its coverage
    raster's radio before)."""
    import gc
    import weakref

    from aoass_env.maps import generator

    env = gym.make(env_id, field_size=40.0, obstacle_density=0.2, n_nodes=20).unwrapped
    env.reset(seed=0)
    first = weakref.ref(env.obstacle_map)
    for seed in range(1, 3):
        env.reset(seed=seed)
    generator.clear_cache()
    gc.collect()
    assert first() is None
    env.close()


def test_a_map_option_is_the_episodes_map_in_its_config_and_log():
    """A map given at reset is the one the episode's config (and its beacon log) names: it
    used to keep the constructor's map, so a log was keyed by a map it was not played on."""
    from aoass_env.maps import load_map

    env = gym.make("AOASS-v0", map="test/d0.10_f100_s500", n_nodes=20).unwrapped
    env.reset(seed=0, options={"map": "test/d0.40_f100_s509"})
    assert env.episode_config.map == "test/d0.40_f100_s509"
    assert env.beacon_log.config["config"]["map"] == "test/d0.40_f100_s509"
    env.reset(seed=0, options={"map": load_map("test/d0.40_f100_s509")})
    assert env.episode_config.map is None                 # a map object: no name to give
    env.reset(seed=0)
    assert env.episode_config.map == "test/d0.10_f100_s500"


def test_a_generated_maps_density_with_a_map_is_refused():
    """obstacle_density shapes generated maps only: given with map= it was ignored, yet
    recorded as the episode's."""
    with pytest.raises(ConfigError, match=r"obstacle_density=0\.5 sets the density of generated "
                                          r"maps; map='test/d0\.10_f100_s500' brings its own "
                                          r"obstacles \(density 0\.10\): give one of the two"):
        gym.make("AOASS-v0", map="test/d0.10_f100_s500", obstacle_density=0.5)
    with pytest.raises(ConfigError, match="obstacle_density=0.3 sets the density"):
        AOASSEnv(config={"map": "test/d0.10_f100_s500", "obstacle_density": 0.3})
    # a config object's own density was accepted and ignored (helper-46), in both envs
    both = AOASSConfig(map="test/d0.10_f100_s500", obstacle_density=0.5)
    for env_id in ("AOASS-v0", "AOASS-Safe-v0"):
        with pytest.raises(ConfigError, match="obstacle_density=0.5 sets the density"):
            gym.make(env_id, config=both)
    assert gym.make("AOASS-v0", config=both.replace(
        obstacle_density=AOASSConfig().obstacle_density)).unwrapped.config.map is not None


def test_a_config_mapping_with_a_key_that_is_no_name_is_refused_in_one_line():
    """coerce passed the mapping on as keywords: a non-string key raised a bare TypeError
    naming nothing, and a read-only mapping (MappingProxyType) was refused as 'not a
    mapping'."""
    from types import MappingProxyType

    with pytest.raises(ConfigError, match=r"config: keys must be AOASSConfig's keyword names "
                                          r"\(strings\), got 1"):
        AOASSConfig.coerce({1: 2}, "config")
    assert AOASSConfig.coerce(MappingProxyType({"n_nodes": 30}), "config").n_nodes == 30
