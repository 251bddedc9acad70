"""Observation layout, bounds and the moving-obstacle measurements."""

from __future__ import annotations

import numpy as np
import pytest

from aoass_env.config import AOASSConfig
from aoass_env.maps import ObstacleMap
from aoass_env.observation import Observer, observation_layout, observation_space
from aoass_env.planning.square_spiral import episode_spiral
from aoass_env.simulator import Simulator


def test_layout_sizes_follow_the_config():
    cfg = AOASSConfig(obs_waypoints=3, n_rays=7, obs_moving_obstacles=4)
    layout = observation_layout(cfg)
    size = {k: s.stop - s.start for k, s in layout.items()}
    assert size == {"position": 2, "speed": 1, "d_obs": 1, "heading_error": 1, "heading": 2,
                    "waypoints": 6, "rays": 7, "moving_obstacles": 20, "coverage": 1,
                    "progress": 1, "time": 1}
    space = observation_space(cfg)
    assert space.shape == (43,) and space.dtype == np.float32
    assert np.all(space.low[layout["rays"]] == 0) and np.all(space.low[layout["heading"]] == -1)
    assert np.all(space.high == 1)


def test_upcoming_skips_blocked_waypoints_and_repeats_the_last():
    cfg = AOASSConfig(field_size=40.0, obs_waypoints=4)
    spiral = episode_spiral(cfg, ObstacleMap(40.0, 40.0))
    blocked = spiral.blocked.copy()
    blocked[1:3] = True
    spiral = type(spiral)(**{**spiral.__dict__, "blocked": blocked})
    obs = Observer(cfg, spiral, np.random.default_rng(0))
    np.testing.assert_array_equal(obs.upcoming(0), spiral.waypoints[[0, 3, 4, 5]])
    np.testing.assert_array_equal(obs.upcoming(1), spiral.waypoints[[3, 4, 5, 6]])
    last = spiral.waypoints[-1]
    np.testing.assert_array_equal(obs.upcoming(len(blocked) - 2),
                                  [spiral.waypoints[-2], last, last, last])
    np.testing.assert_array_equal(obs.upcoming(len(blocked)), [last] * 4)


def _sim(**kw) -> Simulator:
    cfg = AOASSConfig(field_size=30.0, n_nodes=5, obstacle_density=0.0, sensing_range=12.0,
                      n_moving_obstacles=6, **kw)
    return Simulator(cfg, np.random.default_rng(3))


def test_moving_obstacles_exact_without_noise_nearest_first():
    sim = _sim(obs_position_noise=0.0, obs_velocity_noise=0.0, obs_moving_obstacles=4)
    obs = Observer(sim.config, sim.spiral, np.random.default_rng(0))
    slots = obs.moving(sim.world)
    rel = sim.world.moving_positions - sim.world.position
    dist = np.hypot(*rel.T)
    seen = np.argsort(dist)[: 4]
    seen = seen[dist[seen] <= 12.0]
    m = len(seen)
    np.testing.assert_allclose(slots[:m, :2], rel[seen] / 12.0)
    np.testing.assert_allclose(slots[:m, 2:4], sim.world.moving_velocities[seen] / 2.0)
    assert np.all(slots[:m, 4] == 1) and np.all(slots[m:] == 0)


def test_measurement_noise_has_the_configured_spread():
    cfg = AOASSConfig(field_size=30.0, n_nodes=5, obstacle_density=0.0, sensing_range=100.0,
                      n_moving_obstacles=1, obs_moving_obstacles=1, obs_position_noise=0.5,
                      obs_velocity_noise=0.0)
    sim = Simulator(cfg, np.random.default_rng(3))
    obs = Observer(cfg, sim.spiral, np.random.default_rng(1))
    true = (sim.world.moving_positions - sim.world.position)[0]
    samples = np.array([obs.moving(sim.world)[0, :2] * 100.0 for _ in range(4000)])
    err = samples - true
    assert np.abs(err.mean(axis=0)).max() < 0.05
    assert err.std(axis=0) == pytest.approx([0.5, 0.5], rel=0.08)
