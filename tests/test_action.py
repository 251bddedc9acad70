"""Action types: one meaning of an action, shared by AOASS-v0 and the safety filter."""

from __future__ import annotations

import copy
import math
import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env.action import ActionBox, AdaptiveAction, ResidualAction, checked_action
from aoass_env.config import AOASSConfig, ConfigError
from aoass_env.env import AOASSEnv
from aoass_env.wrappers import make_safe_env

SMALL = dict(field_size=40.0, n_nodes=30, obstacle_density=0.1, n_moving_obstacles=1)


def test_the_residual_adds_scaled_changes_to_the_nominal_command():
    act = ResidualAction(speed_scale=1.0, heading_scale=0.25, max_speed=2.0)
    assert act.command([0.5, -1.0], (1.0, 0.3)) == pytest.approx((1.5, 0.05))
    assert act.command([1.0, 0.0], (1.8, 0.0))[0] == 2.0       # clipped to max_speed
    assert act.command([-1.0, 0.0], (0.4, 0.0))[0] == 0.0      # and to 0
    assert act.command([7.0, -7.0], (1.0, 0.0)) == act.command([1.0, -1.0], (1.0, 0.0))
    assert act.command(np.zeros(2), (0.7, 2.0)) == (0.7, 2.0)  # the zero action follows
    assert act.space.shape == (2,) and act.space.dtype == np.float32


def test_from_config_and_full_range():
    c = AOASSConfig(action_speed_scale=0.5, action_heading_scale=0.2)
    assert ResidualAction.from_config(c) == ResidualAction(0.5, 0.2, c.anchor_max_speed)
    assert not ResidualAction.from_config(c).reaches_every_command
    full = ResidualAction.full_range(c)
    assert full == ResidualAction(c.anchor_max_speed, math.pi, c.anchor_max_speed)
    assert full.reaches_every_command


@pytest.mark.parametrize("key", ["action_speed_scale", "action_heading_scale"])
def test_a_zero_scale_is_refused_by_the_configs_own_name(key):
    # a zero scale would make the residual's inverse divide by zero; the config refuses it
    # before the action type is built, naming the user's key, not the action's field
    with pytest.raises(ConfigError, match=rf"^{key}=0\.0 must be a number in \(0\.0, "):
        AOASSConfig(**{key: 0.0})


@settings(max_examples=200, deadline=None)
@given(st.floats(0.0, 2.0), st.floats(-10.0, 10.0), st.floats(0.0, 2.0), st.floats(-4.0, 4.0))
def test_a_full_range_residual_reaches_every_command(speed, heading, nominal_speed,
                                                     nominal_heading):
    full = ResidualAction.full_range(AOASSConfig())
    nominal = (nominal_speed, nominal_heading)
    got_speed, got_heading = full.command(full.action(speed, heading, nominal), nominal)
    assert got_speed == pytest.approx(speed, abs=1e-6)
    assert math.remainder(got_heading - heading, 2 * math.pi) == pytest.approx(0.0, abs=1e-6)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(-3.0, 3.0), min_size=5, max_size=5), st.floats(0.0, 2.0),
       st.floats(-4.0, 4.0))
def test_decode_is_the_command_and_the_knobs_validated_once(action, speed, heading):
    residual = ResidualAction(1.0, 0.25, 2.0)
    adaptive = AdaptiveAction(1.0, 0.25, 2.0)
    nominal = (speed, heading)
    assert residual.decode(action[:2], nominal) == (residual.command(action[:2], nominal), None)
    assert adaptive.decode(action, nominal) == (adaptive.command(action, nominal),
                                                adaptive.knobs(action))
    assert adaptive.decode(action, nominal)[0] == residual.command(action[:2], nominal)
    with pytest.raises(ValueError, match=r"shape \(5,\) = \[dv, dtheta, skip, detour"):
        adaptive.decode(action[:2], nominal)


@pytest.mark.parametrize("bad", [[1.0], [0.0, float("nan")], "ab", [1 + 2j, 0.0], None])
def test_malformed_actions_name_the_action(bad):
    with pytest.raises(ValueError, match="action"):
        checked_action(bad)


@pytest.mark.parametrize("bad", [[0.1, None], np.array([True, False]), [True, False],
                                 np.array([0.1, 0.2], dtype=object),
                                 [True, 0.5], (0.5, np.True_)])   # numpy made these floats
def test_booleans_and_objects_are_not_numbers_of_an_action(bad):
    """[0.1, None] used to read as [0.1, nan] ("NaN or infinite"), booleans as 1 and 0."""
    with pytest.raises(ValueError, match=r"action must be 2 numbers \[dv, dtheta\], got "):
        checked_action(bad)


@pytest.mark.parametrize("kwargs, match", [
    (dict(speed_scale=0.0, heading_scale=1.0, max_speed=2.0), "speed_scale"),
    (dict(speed_scale=1.0, heading_scale=4.0, max_speed=2.0), "heading_scale"),
    (dict(speed_scale=1.0, heading_scale=1.0, max_speed=True), "max_speed"),
])
def test_bad_scales_name_the_parameter(kwargs, match):
    with pytest.raises(ValueError, match=match):
        ResidualAction(**kwargs)


def test_the_env_decodes_with_its_action_type():
    env = AOASSEnv(**SMALL, action_heading_scale=0.3)
    assert env.action_type == ResidualAction.from_config(env.config)
    env.reset(seed=0)
    nominal = env.nominal_command
    wanted = env.action_type.command([0.0, 1.0], nominal)
    assert wanted[1] == pytest.approx(nominal[1] + 0.3)
    assert (AOASSEnv(**SMALL, action_heading_scale=0.3, action_type="residual").action_type
            == env.action_type)
    with pytest.raises(TypeError, match="action_type"):
        AOASSEnv(**SMALL, action_type=3)
    with pytest.raises(ValueError, match="action_type='residul' is not one of"):
        AOASSEnv(**SMALL, action_type="residul")


def test_the_agent_action_means_the_same_inside_the_safety_stack():
    """The filter reads the agent's action with the environment config's scales (one setting),
    and drives its inner environment through a full-range residual."""
    env = make_safe_env(**SMALL, action_heading_scale=0.3, action_speed_scale=0.5)
    safety = env
    base = env.unwrapped
    assert safety.agent_action == ResidualAction(0.5, 0.3, base.config.anchor_max_speed)
    assert base.config.action_heading_scale == 0.3
    assert base.action_type.reaches_every_command
    env.reset(seed=1)
    nominal = base.nominal_command
    speed_des, heading_des = safety.agent_action.command([1.0, -1.0], nominal)
    assert (speed_des, heading_des) == pytest.approx(
        (min(nominal[0] + 0.5, base.config.anchor_max_speed), nominal[1] - 0.3))


# --- oracles: the array code that checked_action and ResidualAction.action replaced -----------

def _checked_action_arrays(action, names=("dv", "dtheta")):
    """checked_action before its float fast path (issue 20, fifth round): every check on
    arrays, np.clip."""
    a = np.asarray(action, dtype=np.float64)
    assert a.shape == (len(names),) and np.all(np.isfinite(a))
    return np.clip(a, -1.0, 1.0).tolist()


def _residual_action_arrays(act, speed, heading, nominal):
    """ResidualAction.action before it clipped in Python floats."""
    from aoass_env.world import wrap_angle
    speed_nom, heading_nom = nominal
    return np.clip([(speed - speed_nom) / act.speed_scale,
                    wrap_angle(heading - heading_nom) / act.heading_scale],
                   -1.0, 1.0).astype(np.float32)


def _same_floats(a, b):
    """Equal lists of floats, signs of zeros included."""
    return len(a) == len(b) and all(x == y and math.copysign(1.0, x) == math.copysign(1.0, y)
                                    for x, y in zip(a, b, strict=True))


def test_checked_action_fast_path_is_the_array_code():
    rng = np.random.default_rng(20)
    specials = [0.0, -0.0, 1.0, -1.0, 1.0 + 1e-16, np.nextafter(1.0, 2.0), -3.0, 1e30,
                np.float32(1.0000001), 5e-324]
    for n, names in ((2, ResidualAction.NAMES), (5, AdaptiveAction.NAMES)):
        for i in range(3000):
            a = rng.uniform(-2.5, 2.5, n) if i % 3 else rng.choice(specials, n)
            for dtype in (np.float64, np.float32):
                action = np.asarray(a, dtype=dtype)
                assert _same_floats(checked_action(action, names),
                                    _checked_action_arrays(action, names))
    # NaN, infinities and wrong shapes still fail on the checked path
    for bad in (np.array([np.nan, 0.0]), np.array([0.5, np.nan]), np.array([-1.0, -np.inf]),
                np.array([np.inf, 0.0], np.float32), np.zeros(3)):
        with pytest.raises(ValueError, match="action"):
            checked_action(bad)


def test_residual_action_in_floats_is_the_array_code():
    rng = np.random.default_rng(21)
    acts = [ResidualAction(1.0, 0.25, 2.0), ResidualAction.full_range(AOASSConfig())]
    for i in range(5000):
        act = acts[i % 2]
        speed, nominal_speed = rng.uniform(-1.0, 3.0, 2)
        heading, nominal_heading = rng.uniform(-10.0, 10.0, 2)
        if i % 7 == 0:
            speed = nominal_speed                       # a zero residual
        if i % 11 == 0:
            heading = nominal_heading + math.pi         # the wrap's end
        got = act.action(speed, heading, (nominal_speed, nominal_heading))
        want = _residual_action_arrays(act, speed, heading, (nominal_speed, nominal_heading))
        assert got.dtype == np.float32 and got.shape == (2,)
        assert _same_floats(got.tolist(), want.tolist())


def _draws(space: spaces.Box, seed: int, n: int = 4) -> list[np.ndarray]:
    space.seed(seed)
    return [space.sample() for _ in range(n)]


def _same_draws(a: list[np.ndarray], b: list[np.ndarray]) -> bool:
    return all(type(x) is type(y) and x.dtype == y.dtype and x.shape == y.shape
               and np.array_equal(x, y, equal_nan=True) for x, y in zip(a, b, strict=True))


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**32 - 1),
       shape=st.lists(st.integers(1, 3), min_size=1, max_size=3).map(tuple),
       dtype=st.sampled_from([np.float16, np.float32, np.float64]),
       bounds=st.tuples(st.floats(-1e4, 1e4), st.floats(0.0, 1e4)))
def test_action_box_draws_what_box_draws(seed, shape, dtype, bounds):
    """The same seed gives the same samples (values, dtype, shape) and leaves the generator
    in the same state; a zero-width box included."""
    low, width = bounds
    args = (np.full(shape, low, dtype), np.full(shape, low + width, dtype), shape, dtype)
    fast, box = ActionBox(*args), spaces.Box(*args)
    assert fast._uniform
    assert _same_draws(_draws(fast, seed), _draws(box, seed))
    assert fast.np_random.bit_generator.state == box.np_random.bit_generator.state


def test_action_box_draws_what_box_draws_with_mixed_bounds():
    low = np.array([-1.0, 0.0, -3.5, 2.0], dtype=np.float32)
    high = np.array([1.0, 5.0, -3.0, 2.0], dtype=np.float32)
    assert _same_draws(_draws(ActionBox(low, high), 7, 50), _draws(spaces.Box(low, high), 7, 50))


@pytest.mark.parametrize("args", [
    (np.array([-np.inf, -1.0]), np.array([0.0, np.inf]), (2,), np.float64),  # unbounded sides
    (-np.inf, np.inf, (3,), np.float64),
    (0, 10, (2,), np.int64),                            # integers
    (-1.0, 1.0, (), np.float32),                        # a scalar shape
    (-1e308, 1e308, (2,), np.float64),                  # the range overflows a double
], ids=["half-bounded", "unbounded", "integers", "scalar", "overflow"])
def test_other_boxes_sample_as_box_does(args):
    fast, box = ActionBox(*args), spaces.Box(*args)
    assert not fast._uniform
    with np.errstate(over="ignore"):                    # Box's own high - low overflows
        try:
            expected = _draws(box, 3)
        except OverflowError as err:                    # Generator.uniform's refusal
            with pytest.raises(OverflowError, match=str(err)):
                _draws(fast, 3)
        else:
            assert _same_draws(_draws(fast, 3), expected)


def test_a_mask_is_refused_as_box_refuses_it():
    with pytest.raises(gym.error.Error, match="cannot be provided a mask"):
        ActionBox(-1.0, 1.0, (2,)).sample(mask=np.ones(2, dtype=np.int8))


def test_a_probability_is_refused_as_box_refuses_it():
    """Gymnasium >= 1.1 refuses it in Box.sample; 1.0 has no such argument (a TypeError)."""
    def refusal(space: spaces.Box) -> type:
        with pytest.raises((gym.error.Error, TypeError)) as refused:
            space.sample(probability=np.ones(2))
        return refused.type
    assert refusal(ActionBox(-1.0, 1.0, (2,))) is refusal(spaces.Box(-1.0, 1.0, (2,)))


def test_the_registered_ids_act_in_action_boxes():
    """Every registered id's action space is an ActionBox: a Box to Gymnasium and SB3, equal
    to the plain Box, kept by pickling and copying, and batched into a plain Box."""
    for env_id, size in [("AOASS-v0", 2), ("AOASS-Safe-v0", 2), ("AOASS-Adaptive-v0", 5)]:
        env = gym.make(env_id, config=SMALL)
        space = env.action_space
        assert type(space) is ActionBox and isinstance(space, spaces.Box)
        assert space == spaces.Box(-1.0, 1.0, (size,), np.float32)
        for other in (pickle.loads(pickle.dumps(space)), copy.deepcopy(space)):
            assert type(other) is ActionBox
            assert _same_draws(_draws(other, 5), _draws(space, 5))
        env.close()
    vec = gym.make_vec("AOASS-v0", num_envs=2, vectorization_mode="sync", config=SMALL)
    assert type(vec.single_action_space) is ActionBox
    assert type(vec.action_space) is spaces.Box and vec.action_space.shape == (2, 2)
    vec.close()
