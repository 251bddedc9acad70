"""Action types: one meaning of an action, shared by AOASS-v0 and the safety filter."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env.action import AdaptiveAction, ResidualAction, checked_action
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
    for bad in (np.array([np.nan, 0.0]), np.array([np.inf, 0.0], np.float32), np.zeros(3)):
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
