"""The safety-stack wrappers: checkers, layout, determinism, safety, map sampling, bad input."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from hypothesis import given, settings
from hypothesis import strategies as st
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import aoass_env  # noqa: F401  (registers the environments)
from aoass_env import AOASSEnv, ConfigError, wrappers
from aoass_env.action import ResidualAction
from aoass_env.config import AOASSConfig
from aoass_env.maps import ObstacleMap
from aoass_env.registration import SAFE_ENV_ID
from aoass_env.safety.config import SafetyConfig, TrackerConfig
from aoass_env.world import wrap_angle
from aoass_env.wrappers import (
    ActionRepeat,
    EnergyCost,
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
        # the terms of Eq. 14 too (they used to be the last period's alone)
        periods = [i["reward_terms"] for _, _, i in plain[4 * k - 3:4 * k + 1]]
        assert info["reward_terms"] == {key: sum(p[key] for p in periods)
                                        for key in periods[0]}
        assert sum(info["reward_terms"].values()) == pytest.approx(reward)
    assert any(held[k][2]["reward_terms"]["coverage"] > 0 for k in range(1, len(held)))
    for bad in (0, 1.5, True):
        with pytest.raises(ValueError, match="action_repeat"):
            make_safe_env(**SMALL, action_repeat=bad)
    with pytest.raises(TypeError, match="defer must be a bool"):
        ActionRepeat(make_safe_env(**SMALL), 4, defer="no")
    assert ActionRepeat(make_safe_env(**SMALL), 4, defer=False)._source is None


def test_energy_cost_charges_the_energy_spent_in_each_step():
    """The shaped stack plays the same episode as the plain one; each reward is Eq. 14's less
    the weight times the growth of E_total in the step, held steps summed."""
    plain = run(make_safe_env(**SMALL), seed=4, steps=300)
    shaped = run(make_safe_env(**SMALL, energy_weight=0.5), seed=4, steps=300)
    assert isinstance(make_safe_env(**SMALL, energy_weight=0.5), EnergyCost)
    assert not isinstance(make_safe_env(**SMALL), EnergyCost)
    charged = 0.0
    for k in range(1, len(plain)):
        np.testing.assert_array_equal(shaped[k][0], plain[k][0])
        spent = plain[k][2]["energy_total"] - plain[k - 1][2]["energy_total"]
        assert shaped[k][2]["energy_cost"] == pytest.approx(-0.5 * spent, abs=1e-12)
        assert shaped[k][1] == pytest.approx(plain[k][1] - 0.5 * spent, abs=1e-9)
        charged += spent
    assert charged > 1.0          # the anchor moved: the term is not vacuous
    action = np.array([0.3, 0.1], np.float32)
    steady = run(make_safe_env(**SMALL), seed=4, steps=300, actions=action)
    held = run(make_safe_env(**SMALL, energy_weight=0.5, action_repeat=4), seed=4, steps=75,
               actions=action)
    for k in range(1, len(held)):
        spent = steady[4 * k][2]["energy_total"] - steady[4 * k - 4][2]["energy_total"]
        assert held[k][2]["energy_cost"] == pytest.approx(-0.5 * spent, abs=1e-9)
    assert isinstance(make_safe_env(**SMALL, energy_weight=0.5, action_repeat=4).env,
                      ActionRepeat)
    for bad in (-1.0, math.nan, math.inf, True, False, "0.1", None):
        with pytest.raises(ValueError, match="energy_weight"):
            make_safe_env(**SMALL, energy_weight=bad)


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
    env._look_ahead(v, v, env.unwrapped.anchor, env._static_obstacles())
    env.escape_budget.yielding = True
    env._look_ahead(v, v, env.unwrapped.anchor, env._static_obstacles())
    assert seen == [(1.0, 2.0, 0.5), (3.0, 10.0, 0.0)]


def test_the_look_ahead_predicts_the_tracks_off_every_wall_they_can_reach(monkeypatch):
    """The look-ahead's obstacles bounce off the walls within their own reach, not only off
    those within the anchor's (an obstacle out of the anchor's reach ran through walls in its
    prediction, and out of the anchor's way): on every call of an episode with many moving
    obstacles, their predicted paths with the edges the wrapper passes are the paths with all
    the map's edges, where the anchor's edges alone give other paths on some calls."""
    import aoass_env.wrappers as wrappers
    from aoass_env.safety.lookahead import predict_obstacles

    calls = []
    real = wrappers.escape_velocity

    def spy(*args, **kwargs):
        calls.append((args[5].copy(), kwargs))
        return real(*args, **kwargs)

    monkeypatch.setattr(wrappers, "escape_velocity", spy)
    env = make_safe_env(field_size=40.0, n_nodes=30, obstacle_density=0.3,
                        n_moving_obstacles=8, moving_obstacle_speed=(0.5, 1.5))
    run(env, 5, 600)
    static = env._static_obstacles()
    every = (static.point, static.point[static.next])
    assert len(calls) > 50
    differ = 0
    for tracks, kw in calls:
        n_steps = math.ceil(kw["horizon"] / kw["step"] - 1e-9)
        radius = np.full(len(tracks), kw["obstacle_radius"])

        def paths(starts, ends, tracks=tracks, kw=kw, n_steps=n_steps, radius=radius):
            return predict_obstacles(tracks[:, :4], kw["step"], n_steps, starts, ends, radius)

        want = paths(*every)
        given = (kw.get("bounce_starts", kw["starts"]), kw.get("bounce_ends", kw["ends"]))
        assert paths(*given).tobytes() == want.tobytes()
        differ += paths(kw["starts"], kw["ends"]).tobytes() != want.tobytes()
    assert differ > 0


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
    for seed in (0, None, None, None):
        cyc.reset(seed=seed)
        names.append(cyc.unwrapped.sim.map.name)
    assert names == [m.split("/")[1] for m in maps] + [maps[0].split("/")[1]]
    # a seeded reset starts the cycle again: the same seed, the same episode (it used to give
    # the next map, so evaluations reseeded alike played other maps)
    obs, _ = cyc.reset(seed=0)
    assert cyc.unwrapped.sim.map.name == names[0]
    # {"map": None} is no map given: the sampler draws (it used to pass None on, and the
    # episode ran on a freshly generated map)
    for sampler in (env, cyc):
        sampler.reset(seed=5, options={"map": None})
        assert sampler.unwrapped.sim.map.name in {m.split("/")[1] for m in maps}
    cyc.reset()
    again, _ = cyc.reset(seed=0)
    np.testing.assert_array_equal(obs, again)


# --- bad input ------------------------------------------------------------------------------
@pytest.mark.parametrize("kwargs, safety, match", [
    ({"anchor_max_turn_rate": 1e-4}, None, r"anchor_max_turn_rate=0.0001 rad/s"),
    ({"anchor_max_accel": 1e-4}, None, r"more than 2000 samples"),
    ({"dt": 0.05}, {"look_ahead_horizon": 60.0}, r"look-ahead horizon 60 s"),
])
def test_a_look_ahead_too_long_to_roll_out_is_refused(kwargs, safety, match):
    # a slow turn rate made every step slow, then asked for tens of GiB at a step
    with pytest.raises(ConfigError, match=match):
        make_safe_env(config=AOASSConfig(**SMALL, **kwargs), safety=safety)
    make_safe_env(config=AOASSConfig(**SMALL, **kwargs), safety={"look_ahead": False})


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
    with pytest.raises(ValueError, match="cycle must be a bool, got 'yes'"):
        MapSampler(AOASSEnv(**SMALL), ["test/d0.10_f100_s500"], cycle="yes")
    # the training env's map filters: three densities used to train on the first two's range
    with pytest.raises(ValueError, match=r"densities must be a pair of finite numbers"):
        gym.make("AOASS-Train-v0", densities=[0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match="cycle must be a bool, got 'yes'"):
        wrappers.make_training_env(cycle="yes")
    # a generated map's density, which the shipped maps' draw would ignore (it was accepted,
    # recorded in run.yml and without effect)
    with pytest.raises(ConfigError, match=r"obstacle_density=0\.55: a training setup draws "
                                          r"shipped maps whose density lies in densities"):
        gym.make("AOASS-Train-v0", obstacle_density=0.55)
    # whole numbers of NumPy or float type are the integers they hold (they used to be refused
    # with a message naming the value they held), any iterable of maps is a list
    assert make_safe_env(**SMALL, action_repeat=np.int64(2)).repeat == 2
    assert make_safe_env(**SMALL, action_repeat=2.0).repeat == 2
    assert make_safe_env(**SMALL, energy_weight=np.float32(0.5)).weight == 0.5
    assert not isinstance(make_safe_env(**SMALL, action_repeat=1.0), ActionRepeat)
    assert len(MapSampler(AOASSEnv(**SMALL), iter(["test/d0.10_f100_s500"])).maps) == 1
    with pytest.raises(ValueError, match="maps must be a non-empty list of maps, got 5"):
        MapSampler(AOASSEnv(**SMALL), 5)
    # a map the sampler would replace every episode used to be taken and ignored
    with pytest.raises(ConfigError, match=r"map='train/d0.10_f100_s000': a training setup "
                                          r"draws its map from the shipped train maps"):
        gym.make("AOASS-Train-v0", map="train/d0.10_f100_s000")
    # a bad seed gets Gymnasium's one-line refusal (it used to be NumPy's, naming no seed)
    sampled = gym.make("AOASS-Train-v0")
    for seed, message in ((-1, "Seed must be greater or equal to zero, actual value: -1"),
                          (3.5, "Seed must be a python integer")):
        with pytest.raises(gym.error.Error, match=message):
            sampled.reset(seed=seed)
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


# --- the fast paths of the wrappers against their old code (issue 20, seventh round) ------------

def _old_observation(self, observation):
    """``KalmanObstacleTracker.observation`` before issue 20's seventh round (the oracle)."""
    self.tracker.step(self._base.detections)
    states = self.tracker.states()
    if len(states) == 0:
        out = np.concatenate([observation, np.zeros(2 * self._slots)])
        out[self._moving] = 0.0
        return np.minimum(np.maximum(out, self._low), self._high).astype(np.float32)
    return _array_track_slots(self, observation, states, self._base.sim.world.position)


def _array_track_slots(tracker, observation, states, anchor):
    """The tracker's observation with confirmed tracks ``states`` by the array code (the
    oracle of the old observation and of the compiled ``_track_slots``)."""
    from aoass_env.observation import MOVING_FIELDS
    c = tracker._base.config
    predicted = states[:, :2] + tracker._horizon * states[:, 2:]
    rel = states[:, :2] - anchor
    order = np.argsort(np.hypot(rel[:, 0], rel[:, 1]), kind="stable")[:tracker._slots]
    m = len(order)
    filtered = np.zeros((tracker._slots, len(MOVING_FIELDS)))
    filtered[:m, :2] = rel[order] / c.sensing_range
    filtered[:m, 2:4] = states[order, 2:4] / tracker._v_scale
    filtered[:m, 4] = 1.0
    ahead = np.zeros((tracker._slots, 2))
    ahead[:m] = (predicted[order] - anchor) / c.sensing_range
    out = np.concatenate([observation, ahead.ravel()])
    out[tracker._moving] = filtered.ravel()
    return np.minimum(np.maximum(out, tracker._low), tracker._high).astype(np.float32)


def _old_filter(self, action):
    """``FuzzyORCASafety._filter`` before issue 20's seventh round (the oracle), with its
    ``_moving_obstacles``."""
    from aoass_env.safety.lookahead import position_std
    from aoass_env.safety.orca import OrcaLines, orca_lines, solve_velocity
    from aoass_env.safety.unicycle import unicycle_command
    from aoass_env.world import wrap_angle

    tracks = self._tracker.tracked_obstacles
    tracks[:, 4] += self.config.moving_margin
    if self.config.covariance_sigma > 0.0 and len(tracks):
        std = position_std(self._tracker.tracked_covariances, np.zeros(1))[:, 0]
        tracks[:, 4] += self.config.covariance_sigma * std
    base, cfg = self._base, self.config
    c = base.config
    nominal = base.nominal_command
    anchor = base.anchor
    (speed_des, heading_des), knobs = self.agent_action.decode(action, nominal)
    v_des = speed_des * np.array([math.cos(heading_des), math.sin(heading_des)])
    heading = anchor.heading
    turn, slow = self.controller(anchor.obstacle_gap, wrap_angle(heading_des - heading))
    max_turn = c.anchor_max_turn_rate * c.dt
    heading_pref = heading + float(turn) * max_turn
    speed_pref = float(slow) * speed_des
    v_pref = speed_pref * np.array([math.cos(heading_pref), math.sin(heading_pref)])
    lines = orca_lines(anchor.position, anchor.velocity, c.anchor_radius + cfg.margin,
                       c.anchor_max_speed, static_obstacles=self._static_obstacles(),
                       moving_obstacles=tracks, time_horizon=cfg.time_horizon,
                       time_horizon_obst=cfg.time_horizon_obst, time_step=c.dt)
    v_star = solve_velocity(lines, v_pref, c.anchor_max_speed)
    escape = None
    if cfg.look_ahead and len(lines) > lines.n_static:
        escape = self._look_ahead(v_star, v_pref, anchor, self._static_obstacles())
        if escape.escaping:
            lines = OrcaLines(lines.point[:lines.n_static], lines.direction[:lines.n_static],
                              lines.n_static)
            v_star = solve_velocity(lines, escape.velocity, c.anchor_max_speed)
    speed_cmd, heading_cmd = unicycle_command(
        v_star, heading, anchor.speed, max_turn, c.anchor_max_accel * c.dt, lines.point,
        lines.direction, heading_pref,
        self._braking_envelope(anchor.position, self._static_obstacles()))
    executed = base.action_type.action(speed_cmd, heading_cmd, nominal, knobs)
    sx, sy = v_star.tolist()
    active = [dx * (py - sy) - dy * (px - sx) > -1e-6 for (px, py), (dx, dy) in
              zip(lines.point.tolist(), lines.direction.tolist(), strict=True)]
    (dsx, dsy), (psx, psy) = (v_star - v_des).tolist(), (v_star - v_pref).tolist()
    report = {"intervention": float(np.hypot(dsx, dsy)),
              "orca_correction": float(np.hypot(psx, psy)),
              "flc_turn": float(turn), "flc_speed": float(slow),
              "speed_cmd": speed_cmd, "heading_cmd": heading_cmd,
              "constraints": len(active), "static": lines.n_static,
              "active": sum(active), "active_static": sum(active[:lines.n_static]),
              "escaping": bool(escape is not None and escape.escaping),
              "look_ahead_shortfall": 0.0 if escape is None else escape.shortfall,
              "yielding": self.escape_budget.yielding}
    return executed, report


def test_tracker_slots_compiled_are_the_array_codes():
    """With confirmed tracks, the compiled observation (``_track_slots``) is the array code's,
    byte for byte: 1 to more tracks than slots, tracks at equal distances (the stable order),
    on the anchor, far out of range (clipped), signed zeros and the observation's own specials;
    and _with_tracks takes it for float32 and float64 observations of the inner shape, and
    refuses another shape."""
    env = make_safe_env(**SMALL)
    tracker = env.env
    c = tracker._base.config
    rng = np.random.default_rng(13)
    n = tracker._inner_shape[0]
    specials = np.array([0.0, -0.0, 1.0, -1.0, np.inf, -np.inf, np.nan, 0.5], np.float32)
    for trial in range(400):
        obs = np.where(rng.random(n) < 0.2, rng.choice(specials, n),
                       rng.standard_normal(n)).astype(np.float32)
        m = int(rng.integers(1, tracker._slots + 3))
        anchor = rng.uniform(0.0, 30.0, 2)
        states = np.column_stack([anchor + rng.normal(0.0, c.sensing_range, (m, 2)),
                                  rng.normal(0.0, 2.0, (m, 2))])
        if trial % 4 == 0 and m > 1:        # equal distances: mirrored about the anchor
            states[1, :2] = 2.0 * anchor - states[0, :2]
        if trial % 5 == 0:
            states[0, :2] = anchor          # on the anchor: a zero offset
            states[0, 2] = -0.0
        got = wrappers._track_slots(obs, states, *anchor.tolist(), tracker._horizon,
                                    c.sensing_range, tracker._v_scale, tracker._slots,
                                    tracker._moving.start, tracker._low, tracker._high)
        want = _array_track_slots(tracker, obs, states, anchor)
        assert got.dtype == np.float32 and got.tobytes() == want.tobytes(), trial
    # in the wrapper: the compiled path for the inner float32 observation, with tracks
    env.reset(seed=4)
    seen = 0
    for _ in range(400):
        env.step(rng.uniform(-1.0, 1.0, 2).astype(np.float32))
        states = tracker.tracker.states()
        if len(states):
            inner = tracker._base._observation_vector()
            anchor = tracker._base.sim.world.position
            want = _array_track_slots(tracker, inner, states, anchor).tobytes()
            assert tracker._with_tracks(inner).tobytes() == want
            # a float64 observation (a wrapper between): the same floats as NumPy's
            assert tracker._with_tracks(inner.astype(np.float64)).tobytes() == want
            assert _array_track_slots(tracker, inner.astype(np.float64), states,
                                      anchor).tobytes() == want
            seen += 1
    assert seen > 20, seen
    with pytest.raises(ValueError, match=r"observation of shape \(\d+,\); the env it wraps"):
        tracker._with_tracks(inner[:-1])


def _same(a, b) -> bool:
    """Equal bit for bit: arrays by dtype and bytes, floats by their bits, dicts by key."""
    if isinstance(a, tuple):
        return type(b) is tuple and len(a) == len(b) and all(map(_same, a, b))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    if isinstance(a, float):
        return type(b) is type(a) and math.copysign(1.0, a) == math.copysign(1.0, b) and (
            a == b or (a != a and b != b))
    return type(a) is type(b) and a == b


@pytest.mark.parametrize("config, seed", [
    (dict(SMALL, n_moving_obstacles=6, moving_obstacle_speed=(0.8, 1.5)), 3),
    (dict(field_size=60.0, n_nodes=40, obstacle_density=0.4, n_moving_obstacles=8), 5),
])
def test_filter_and_tracker_fast_paths_equal_the_old_code(config, seed):
    """Every step's tracker observation, filter verdict and report equal the old code's, bit
    for bit, through episodes with and without tracks, escapes and back-to-back resets."""
    old, new = make_safe_env(**config), make_safe_env(**config)
    tracker = old.env
    tracker.observation = _old_observation.__get__(tracker)
    old._filter = _old_filter.__get__(old)
    rng = np.random.default_rng(seed)
    counts = {"tracks": 0, "escapes": 0, "filtered": 0}
    for episode in range(2):
        o_old, _ = old.reset(seed=seed + episode)
        o_new, _ = new.reset(seed=seed + episode)
        assert _same(o_old, o_new)
        for _ in range(300):
            action = rng.uniform(-1.0, 1.0, 2).astype(rng.choice([np.float32, np.float64]))
            assert _same(old._filter(action), new._filter(action))   # no state changes
            o_old, r_old, te, tr, i_old = old.step(action)
            o_new, r_new, _, _, i_new = new.step(action)
            assert _same(o_old, o_new) and _same(r_old, r_new)
            assert _same(i_old["safety"], i_new["safety"])
            counts["tracks"] += len(new.env.tracked_obstacles) > 0
            counts["escapes"] += i_new["safety"]["escaping"]
            counts["filtered"] += 1
            if te or tr:
                break
    assert counts["tracks"] > 50 and counts["escapes"] > 0, counts


def test_tracked_obstacles_are_the_old_stacked_rows():
    """tracked_obstacles (rows written into one array) gives the old np.hstack of the states
    and a radius column, bit for bit, with 0 to several confirmed tracks."""
    env = make_safe_env(**dict(SMALL, n_moving_obstacles=6))
    tracker = env.env
    env.reset(seed=4)
    rng = np.random.default_rng(4)
    counts = set()
    for _ in range(300):
        env.step(rng.uniform(-1.0, 1.0, 2).astype(np.float32))
        states = tracker.tracker.states()
        want = (np.zeros((0, 5)) if len(states) == 0 else np.hstack(
            [states.reshape(-1, 4), np.full((len(states), 1),
                                            tracker._base.config.moving_obstacle_radius)]))
        got = tracker.tracked_obstacles
        assert got.tobytes() == want.tobytes() and got.shape == want.shape
        counts.add(len(states))
    assert {0, 1} <= counts and max(counts) >= 2, counts


def test_tracker_clips_float32_as_float64():
    """The empty slots' observation clipped in float32 gives the float64 clip's floats: values
    on, inside and past the bounds, signed zeros, infinities and NaN."""
    env = make_safe_env(**SMALL)
    tracker = env.env
    low, high = tracker._low, tracker._high
    rng = np.random.default_rng(0)
    specials = np.array([0.0, -0.0, 1.0, -1.0, np.inf, -np.inf, np.nan, 1e-45, -1e-45,
                         np.nextafter(np.float32(1), np.float32(2)), 0.5], np.float32)
    for _ in range(300):
        out = np.where(rng.random(low.shape) < 0.5,
                       rng.choice(specials, low.shape),
                       (rng.standard_normal(low.shape) * 2.0)).astype(np.float32)
        for bound in (low, high):
            pick = rng.random(low.shape) < 0.2
            out[pick] = bound[pick]
        want = np.minimum(np.maximum(out.astype(np.float64), low), high).astype(np.float32)
        got = tracker._clipped(out)
        assert got.dtype == np.float32 and got.tobytes() == want.tobytes()
        # no confirmed track: the compiled empty slots are the array code's floats
        inner = out[:tracker._inner_shape[0]].copy()
        empty = np.concatenate([inner, tracker._no_ahead])
        empty[tracker._moving] = 0.0
        want = np.minimum(np.maximum(empty.astype(np.float64), low), high).astype(np.float32)
        got = wrappers._empty_slots(inner, tracker._moving.start, tracker._moving.stop, low,
                                    high)
        assert got.dtype == np.float32 and got.tobytes() == want.tobytes()


def _same(a, b) -> bool:
    """Exact equality of nested infos: arrays by their bytes, floats by their bits (NaN too)."""
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return type(a) is type(b) and len(a) == len(b) and all(map(_same, a, b))
    if isinstance(a, np.ndarray):
        return (isinstance(b, np.ndarray) and a.dtype == b.dtype and a.shape == b.shape
                and a.tobytes() == b.tobytes())
    if isinstance(a, float):
        return isinstance(b, float) and np.float64(a).tobytes() == np.float64(b).tobytes()
    return type(a) is type(b) and a == b


@pytest.mark.parametrize("kwargs, limit", [
    (dict(field_size=30.0, n_nodes=30, obstacle_density=0.2, n_moving_obstacles=6,
          moving_obstacle_speed=(0.3, 1.0)), None),
    (dict(field_size=40.0, n_nodes=40, obstacle_density=0.3, n_moving_obstacles=3,
          action_type="adaptive", obs_coverage_sectors=8), 620)],
    ids=["residual-terminated", "adaptive-truncated"])
def test_action_repeat_defers_the_unread_observations_and_plays_the_same_episodes(kwargs, limit):
    """The repeated stack builds the observation vector on the last held step only, or on the
    step that ends the episode: it plays the very episodes of a stack that builds every one
    (an extra wrapper in between turns the deferral off), observations, rewards, ends and infos
    equal by their bits, and builds far fewer vectors."""
    from aoass_env.observation import Observer

    repeat = 7

    def stack(defer: bool) -> ActionRepeat:
        env = make_safe_env(**kwargs)
        if limit is not None:        # a time limit that ends the episode between held steps
            env = gym.wrappers.TimeLimit(env, limit)
        return ActionRepeat(env if defer else gym.Wrapper(env), repeat)

    built = {"n": 0}
    vector = Observer.vector

    def counted(self, *args, **kw):
        built["n"] += 1
        return vector(self, *args, **kw)

    plays, vectors, ends = {}, {}, {}
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(Observer, "vector", counted)
        for defer in (True, False):
            env = stack(defer)
            assert (env._source is not None) is defer
            built["n"] = 0
            plays[defer], ends[defer] = [], []
            for seed in (21, 22):
                rng = np.random.default_rng(seed)
                episode = [env.reset(seed=seed)]
                while True:
                    action = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
                    episode.append(env.step(action))
                    if episode[-1][2] or episode[-1][3]:
                        break
                plays[defer].append(episode)
                ends[defer].append((env.unwrapped._steps, episode[-1][2], episode[-1][3]))
            vectors[defer] = built["n"]
    for got, want in zip(plays[True], plays[False], strict=True):
        assert len(got) == len(want)
        for a, b in zip(got, want, strict=True):
            assert a[0].dtype == np.float32 and a[0].tobytes() == b[0].tobytes()
            assert _same(a[1:], b[1:])
    assert ends[True] == ends[False]
    # each episode ended between held steps: its last observation was built on demand
    assert all(steps % repeat for steps, _, _ in ends[True])
    if limit is not None:
        assert all(truncated for _, _, truncated in ends[True])
    assert vectors[True] == sum(len(episode) for episode in plays[True])   # resets included
    assert vectors[False] > 5 * vectors[True]


@settings(max_examples=300, deadline=None)
@given(st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=6,
                max_size=6))
def test_safety_report_deviations_are_numpys_hypot(v):
    """The report's compiled |v* - v_des| and |v* - v_pref| are ``np.hypot``'s floats, NaN,
    infinities and subnormals included."""
    sx, sy, dx, dy, px, py = v
    with np.errstate(all="ignore"):
        want = (float(np.hypot(sx - dx, sy - dy)), float(np.hypot(sx - px, sy - py)))
    got = wrappers._deviations(sx, sy, dx, dy, px, py)
    assert np.array(got).tobytes() == np.array(want).tobytes()


def test_the_map_sampler_keeps_each_maps_own_size():
    """A map of another size than the config's field is played at its own size, as a map
    given at reset is: the sampler used to rescale it to the config's field (a 200 m map
    shrunk to 100 m, its passages halved below the clearance it was certified for)."""
    from aoass_env.maps import load_map

    sampler = MapSampler(gym.make("AOASS-v0", n_nodes=10),
                         ["test/d0.10_f200_s518", "test/d0.10_f100_s500"])
    big, small = sampler.maps
    assert (big.width, big.height) == (200.0, 200.0)
    assert big.density == pytest.approx(load_map("test/d0.10_f200_s518").density, abs=1e-12)
    # a map of the config's size is read as before (scaled to its side: the training maps)
    assert small is load_map("test/d0.10_f100_s500", field_size=100.0)
    sampler.reset(seed=0, options={"map": big})
    assert sampler.unwrapped.obstacle_map.width == 200.0


@pytest.mark.parametrize("turn_rate", [3.0, 4.0])
def test_a_faster_turning_anchor_tracks_its_heading_without_zig_zag(turn_rate):
    """The fuzzy controller's full turn stands for pi/4 per period (its heading terms close an
    error of pi/4 with it); an anchor allowed to turn faster is not turned farther on its word.
    Scaling the turn by the anchor's own limit overshot every error: at 3 rad/s the heading
    error changed sign in 158 of 200 open-field periods (8 at the default limit)."""
    env = make_safe_env(field_size=40.0, n_nodes=10, obstacle_density=0.0,
                        n_moving_obstacles=0, anchor_max_turn_rate=turn_rate)
    env.reset(seed=0)
    base = env.unwrapped
    errors = []
    for _ in range(200):
        _, _, terminated, truncated, _ = env.step(np.zeros(2, np.float32))
        errors.append(wrap_angle(base.nominal_command[1] - base.anchor.heading))
        if terminated or truncated:
            break
    errors = np.array(errors)
    flips = np.sum((np.abs(errors[1:]) > 0.05) & (np.abs(errors[:-1]) > 0.05)
                   & (np.sign(errors[1:]) != np.sign(errors[:-1])))
    assert np.mean(np.abs(errors)) < 0.1
    assert flips < 20
