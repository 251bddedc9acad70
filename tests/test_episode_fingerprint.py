"""Pins whole AOASS-v0 episodes bit for bit (issue 20: speed-ups must not change episodes).

Each case runs seeded episodes of random actions (from a seeded generator), with a reset in the
middle, and hashes what they produced: the world state after every step (anchor position,
velocity, heading, speed, moving obstacles, rays and d_obs in float64), the observations,
rewards and reward terms, the info counters, the beacon log and the reset's map and nodes.
One hash per part, so a failure names what changed. The hashes were recorded on the tree before
the optimisations of issue 20; a change that alters the maths on purpose regenerates them with
``OPENBLAS_CORETYPE=Haswell python3 -m tests.test_episode_fingerprint`` from the repository root
(on x86-64, the kernels tests/conftest.py pins) and says so in its commit.
"""

from __future__ import annotations

import hashlib

import gymnasium as gym
import numpy as np
import pytest

import aoass_env  # noqa: F401  (registers AOASS-v0)
from aoass_env.config import AOASSConfig
from aoass_env.simulator import Simulator

#: name -> (AOASS-v0 keywords, seed)
CASES: dict[str, tuple[dict, int]] = {
    "d0.2": ({"obstacle_density": 0.2}, 0),
    "d0.5_moving6": ({"obstacle_density": 0.5, "n_moving_obstacles": 6}, 1),
    "d0.3_doi0.3": ({"obstacle_density": 0.3, "doi": 0.3}, 2),
    "d0.2_n1000": ({"obstacle_density": 0.2, "n_nodes": 1000}, 3),
    "d0.4_f200": ({"obstacle_density": 0.4, "field_size": 200.0}, 4),
    "f50_moving12": ({"field_size": 50.0, "obstacle_density": 0.3, "n_moving_obstacles": 12,
                      "moving_obstacle_speed": (0.5, 1.5)}, 5),
}
STEPS = (300, 100)     # random steps of the first episode, then after a reset without seed

INFO_KEYS = ("coverage", "covered_nodes", "collisions", "static_contacts", "wall_contacts",
             "moving_contacts", "path_length", "beacons", "energy_anchor", "energy_nodes",
             "energy_total", "rmse_online", "progress", "time", "recoveries",
             "skipped_waypoints", "cost", "cost_static", "cost_moving")

EXPECTED: dict[str, dict[str, str]] = {
    'd0.2': {
        'beacon_log': 'eaa7de19488980df',
        'info': '30d8e029835b433a',
        'observation': 'c8fcfa7eb9e18711',
        'reset': '8130b9b3cbae0534',
        'reward': 'f5427a75a6f78600',
        'sensing': 'fff5b634c98ee554',
        'world': '4637225cb476724f',
    },
    'd0.2_n1000': {
        'beacon_log': '79d57f734d6e8393',
        'info': '8f499fdd950d7f72',
        'observation': '3e4646015f3bb852',
        'reset': '64b1f6aa75f89e90',
        'reward': '0536e96f44513927',
        'sensing': '64ec8a2d53bad4d2',
        'world': '7c3879b993b574f3',
    },
    'd0.3_doi0.3': {
        'beacon_log': '01c55f2ef9e8f60c',
        'info': 'c9c2885531ac613c',
        'observation': 'd9bf1ad64f9cf8bb',
        'reset': '5e2a4b66b3bd9dee',
        'reward': '4c7e9d5afef07030',
        'sensing': '76557fe92caf490d',
        'world': 'd870f9a42234998d',
    },
    'd0.4_f200': {
        'beacon_log': '988f0a6fb7946209',
        'info': '8ce216584cfc657f',
        'observation': '85d52886766f4a59',
        'reset': '29028791b48ca031',
        'reward': '6467f411250e7e3b',
        'sensing': 'ee59335b586417eb',
        'world': '872ee7ef4fdb03bf',
    },
    'd0.5_moving6': {
        'beacon_log': '22f56c3268d80bee',
        'info': '9c229a4698930765',
        'observation': 'aa7cc6e50a98d9b5',
        'reset': '28c3f7816972e98b',
        'reward': 'b4a5d84bf6351cac',
        'sensing': '8ee30e36f4aa976d',
        'world': 'eb73f7f44c158127',
    },
    'f50_moving12': {
        'beacon_log': '37e4c29bd9835d9a',
        'info': '4187a3bc4aa4abdc',
        'observation': '72df5e47c36ecaf8',
        'reset': '049d6561aa7f5582',
        'reward': '77d57d50fd2d88f2',
        'sensing': '3f06edfa8b97273d',
        'world': 'a2e1834a09741e89',
    },
    'nominal_sweep': {
        'sweep': '7b8aa4ab59f0b13a',
    },
}


class _Hashes:
    """One running sha256 per part."""

    def __init__(self) -> None:
        self._h: dict[str, hashlib._Hash] = {}

    def add(self, part: str, *values: object) -> None:
        h = self._h.setdefault(part, hashlib.sha256())
        for v in values:
            a = np.asarray(v)
            h.update(str((a.dtype.str, a.shape)).encode())
            h.update(np.ascontiguousarray(a).tobytes())

    def digests(self) -> dict[str, str]:
        return {k: h.hexdigest()[:16] for k, h in sorted(self._h.items())}


def _episode(env: gym.Env, hashes: _Hashes, steps: int, rng: np.random.Generator,
             seed: int | None) -> None:
    obs, info = env.reset(seed=seed)
    sim = env.unwrapped.sim
    hashes.add("reset", sim.map.edges, sim.nodes, obs,
               [info[k] for k in INFO_KEYS if k in info])
    for action in rng.uniform(-1.0, 1.0, size=(steps, 2)).astype(np.float32):
        obs, reward, terminated, truncated, info = env.step(action)
        world = sim.world
        hashes.add("world", world.position, world.velocity, [world.heading, world.speed],
                   world.moving_positions, world.moving_velocities)
        hashes.add("sensing", world.ray_distances(), world.nearest_obstacle_distance())
        hashes.add("observation", obs)
        terms = info["reward_terms"]
        hashes.add("reward", reward, [terms[k] for k in sorted(terms)])
        hashes.add("info", [float(info[k]) for k in INFO_KEYS], [terminated, truncated])
        if terminated or truncated:
            break
    log = env.unwrapped.beacon_log
    hashes.add("beacon_log", log.beacons, *(getattr(log, k) for k in
                                            ("receptions", "node_links", "anchor_path",
                                             "node_energy")), log.anchor_energy,
               log.collisions)


def fingerprint(name: str) -> dict[str, str]:
    """The per-part hashes of case ``name``."""
    kwargs, seed = CASES[name]
    env = gym.make("AOASS-v0", **kwargs)
    rng = np.random.default_rng(1000 + seed)
    hashes = _Hashes()
    _episode(env, hashes, STEPS[0], rng, seed)
    _episode(env, hashes, STEPS[1], rng, None)
    env.close()
    return hashes.digests()


def sweep_fingerprint() -> dict[str, str]:
    """The hashes of a whole nominal sweep (the follower with its detours, no agent) of the
    simulation core on a 50 m field at density 0.4."""
    config = AOASSConfig(field_size=50.0, obstacle_density=0.4, n_moving_obstacles=5)
    sim = Simulator(config, np.random.default_rng(6))
    log = sim.run()
    hashes = _Hashes()
    hashes.add("sweep", log.beacons, log.receptions, log.anchor_path, log.node_energy,
               log.anchor_energy, log.collisions, sim.world.moving_positions)
    return hashes.digests()


@pytest.mark.parametrize("name", sorted(CASES))
def test_episodes_unchanged_bit_for_bit(name):
    assert fingerprint(name) == EXPECTED[name]


def test_nominal_sweep_unchanged_bit_for_bit():
    assert sweep_fingerprint() == EXPECTED["nominal_sweep"]


if __name__ == "__main__":
    print("EXPECTED: dict[str, dict[str, str]] = {")
    for case in sorted(CASES):
        print(f"    {case!r}: {fingerprint(case)!r},")
    print(f"    'nominal_sweep': {sweep_fingerprint()!r},")
    print("}")
