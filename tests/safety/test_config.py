"""The safety stack's validated configs: ranges, did-you-mean, docs tables kept true."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from aoass_env.safety.config import SafetyConfig, TrackerConfig
from aoass_env.validators import ConfigError

DOCS = Path(__file__).resolve().parents[2] / "docs" / "safety.md"


@pytest.mark.parametrize("cls", [TrackerConfig, SafetyConfig])
def test_docs_tables_match_the_dataclasses(cls):
    assert cls.markdown() in DOCS.read_text(encoding="utf-8")


@pytest.mark.parametrize("cls, kwargs, match", [
    (TrackerConfig, {"horizon": 0.0}, r"horizon=0.0 must be a number in \(0.0, 60.0\] s"),
    (TrackerConfig, {"gate": 1.0}, "gate=1.0"),
    (TrackerConfig, {"birth_hits": 1.5}, "birth_hits=1.5 must be an integer"),
    (TrackerConfig, {"max_misses": True}, "max_misses=True"),
    (TrackerConfig, {"maneuver_speed": 0.0}, r"maneuver_speed=0.0 must be a number in "
                                             r"\(0.0, 100.0\] m/s"),
    (SafetyConfig, {"margin": -0.1}, "margin=-0.1"),
    (SafetyConfig, {"time_horizon": "4"}, "time_horizon='4'"),
    (SafetyConfig, {"moving_margin": float("inf")}, "moving_margin=inf"),
])
def test_bad_values_name_the_field_and_range(cls, kwargs, match):
    with pytest.raises(ConfigError, match=match):
        cls(**kwargs)


def test_unknown_keywords_get_did_you_mean():
    with pytest.raises(ConfigError, match="unknown safety keyword 'margn'; did you mean 'margin'"):
        SafetyConfig.from_kwargs(margn=0.3)
    with pytest.raises(ConfigError, match="unknown tracker keyword 'horizn'"):
        TrackerConfig.coerce({"horizn": 1.0}, "tracker")


def test_numpy_scalars_and_mappings_are_accepted():
    assert TrackerConfig(birth_hits=np.int64(3)).birth_hits == 3
    assert SafetyConfig.coerce({"margin": np.float32(0.25)}, "safety").margin == pytest.approx(0.25)
    assert SafetyConfig.coerce(None, "safety") == SafetyConfig()
    with pytest.raises(ConfigError, match="safety must be a SafetyConfig"):
        SafetyConfig.coerce(0.3, "safety")


def test_gym_make_takes_the_dataclasses_or_their_keywords():
    import gymnasium as gym

    import aoass_env  # noqa: F401  (registers the environments)
    env = gym.make("AOASS-Safe-v0", field_size=40.0, n_nodes=10, obstacle_density=0.1,
                   safety=SafetyConfig(margin=0.3), tracker={"horizon": 1.0})
    filt = env.unwrapped
    wrapper = env
    while not hasattr(wrapper, "agent_action"):
        wrapper = wrapper.env
    assert wrapper.config == SafetyConfig(margin=0.3)
    assert wrapper._tracker.config == TrackerConfig(horizon=1.0)
    assert filt.config.field_size == 40.0
    with pytest.raises(ConfigError, match="unknown tracker keyword 'horizen'"):
        gym.make("AOASS-Safe-v0", tracker={"horizen": 1.0})


def test_the_stack_s_tracker_takes_the_maneuver_speed():
    """The tracker's maneuver model was fixed at 2 m/s whatever the obstacles' speed: faster
    obstacles lost their tracks at bounces with nothing to set."""
    from aoass_env.wrappers import make_safe_env

    default = make_safe_env(field_size=30.0, n_nodes=5)
    assert default.env.tracker.maneuver_speed == 2.0 == TrackerConfig().maneuver_speed
    fast = make_safe_env(field_size=30.0, n_nodes=5, moving_obstacle_speed=(2.0, 4.0),
                         tracker={"maneuver_speed": 8.0})
    assert fast.env.tracker.maneuver_speed == 8.0
