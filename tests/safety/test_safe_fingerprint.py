"""Pins whole AOASS-Safe-v0 episodes bit for bit (issue 20: speed-ups of the safety stack --
the tracker, ORCA, the look-ahead, the braking envelope -- must not change what it does).

Like ``tests/test_episode_fingerprint.py`` for the bare env: seeded random-action episodes of
the full stack, hashed per part (world state, observation, reward, the safety report). The
hashes were recorded on the tree before the safety stack's speed-ups of issue 20; a change that
alters the maths on purpose (e.g. new safety defaults) regenerates them with
``OPENBLAS_CORETYPE=Haswell python3 -m tests.safety.test_safe_fingerprint`` (on x86-64:
the kernels tests/conftest.py pins) from the repository root and says so.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import aoass_env  # noqa: F401  (registers AOASS-Safe-v0)
from aoass_env.safety.config import SafetyConfig
from tests.test_episode_fingerprint import _Hashes

#: name -> (AOASS-Safe-v0 keywords, seed, steps); many fast moving obstacles, so that the
#: look-ahead escapes and the ORCA lines of moving obstacles are active
CASES: dict[str, tuple[dict, int, int]] = {
    "f70_d0.2_moving8": ({"field_size": 70.0, "obstacle_density": 0.2, "n_moving_obstacles": 8,
                          "moving_obstacle_speed": (0.5, 1.5)}, 13, 400),
    "f50_moving12": ({"field_size": 50.0, "obstacle_density": 0.3, "n_moving_obstacles": 12,
                      "moving_obstacle_speed": (0.5, 1.5)}, 12, 300),
}

#: the safety report's entries that are hashed
REPORT_KEYS = ("intervention", "orca_correction", "flc_turn", "flc_speed", "speed_cmd",
               "heading_cmd", "constraints", "static", "active", "active_static", "escaping",
               "look_ahead_shortfall", "yielding")

EXPECTED: dict[str, dict[str, str]] = {
    'f50_moving12': {'observation': 'c56f67201fcc3c9d', 'reward': 'a3970fa81adc015d',
                     'safety': 'a499d6dcde40f081', 'world': '9c2b7ea1695c2bad'},
    'f70_d0.2_moving8': {'observation': 'ad9d2a50eae0b7eb', 'reward': '0b62b2223a00d0db',
                         'safety': 'f04402ad948acd9f', 'world': '965b48eac69fc49d'},
}
#: the same episodes with issue 24's first defaults (``one-cost``: the look-ahead's shortfall
#: and prices on one cost, also while yielding), the hashes recorded before the defaults moved
#: to the clearance first (issue 24, third round): the old behaviour stays reachable
ONE_COST = SafetyConfig(shortfall_tolerance=None, yield_shortfall_tolerance=None)
EXPECTED_ONE_COST: dict[str, dict[str, str]] = {
    'f50_moving12': {'observation': '2422a27ef15c7469', 'reward': '21aec93d5a4c0c41',
                     'safety': '8de962506222f6be', 'world': 'cb1e3ba98f20e339'},
    'f70_d0.2_moving8': {'observation': '672bb70049685343', 'reward': '3c4183e47d9d24c7',
                         'safety': '28f785b0848f2390', 'world': 'bde015e0e0b3e696'},
}


def fingerprint(name: str, safety: SafetyConfig | None = None) -> tuple[dict[str, str], int]:
    """The per-part hashes of case ``name`` (with ``safety``, default: the defaults) and the
    number of steps that escaped."""
    kwargs, seed, steps = CASES[name]
    env = gym.make("AOASS-Safe-v0", **kwargs, safety=safety)
    rng = np.random.default_rng(2000 + seed)
    hashes = _Hashes()
    obs, _ = env.reset(seed=seed)
    hashes.add("observation", obs)
    world = env.unwrapped.sim.world
    escapes = 0
    for action in rng.uniform(-1.0, 1.0, size=(steps, 2)).astype(np.float32):
        obs, reward, terminated, truncated, info = env.step(action)
        world = env.unwrapped.sim.world
        hashes.add("world", world.position, world.velocity, [world.heading, world.speed],
                   world.moving_positions, world.moving_velocities)
        hashes.add("observation", obs)
        hashes.add("reward", reward, [float(info["collisions"]), terminated, truncated])
        report = info["safety"]
        hashes.add("safety", [float(report[k]) for k in REPORT_KEYS])
        escapes += bool(report["escaping"])
        if terminated or truncated:
            break
    env.close()
    return hashes.digests(), escapes


@pytest.mark.parametrize("name", sorted(CASES))
def test_safe_episodes_unchanged_bit_for_bit(name):
    digests, escapes = fingerprint(name)
    assert escapes > 0           # the look-ahead's escape path is exercised
    assert digests == EXPECTED[name]


@pytest.mark.parametrize("name", sorted(CASES))
def test_one_cost_episodes_are_the_first_defaults_bit_for_bit(name):
    digests, escapes = fingerprint(name, ONE_COST)
    assert escapes > 0
    assert digests == EXPECTED_ONE_COST[name]


if __name__ == "__main__":
    for table, safety in (("EXPECTED", None), ("EXPECTED_ONE_COST", ONE_COST)):
        print(f"{table}: dict[str, dict[str, str]] = {{")
        for case in sorted(CASES):
            digests, escapes = fingerprint(case, safety)
            print(f"    {case!r}: {digests!r},  # {escapes} escapes")
        print("}")
