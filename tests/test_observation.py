"""Observation layout, bounds and the moving-obstacle measurements."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env.config import AOASSConfig
from aoass_env.maps import ObstacleMap
from aoass_env.observation import Observer, _vector, observation_layout, observation_space
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


def test_no_observed_slot_still_records_the_detections_the_tracker_reads():
    """obs_moving_obstacles=0 left the detections empty too: the Kalman tracker never made a
    track and the safety stack avoided no moving obstacle. The detections do not depend on
    how many slots the observation holds."""
    sims = [_sim(obs_moving_obstacles=m) for m in (0, 3)]
    observers = [Observer(sim.config, sim.spiral, np.random.default_rng(0)) for sim in sims]
    seen = 0
    for _ in range(60):
        slots = [obs.moving(sim.world) for obs, sim in zip(observers, sims, strict=True)]
        assert slots[0].shape == (0, 5)
        np.testing.assert_array_equal(observers[0].detections, observers[1].detections)
        seen += len(observers[0].detections)
        for sim in sims:
            sim.step(1.0, 0.3)
    assert seen > 0


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


def _old_moving(self: Observer, world) -> np.ndarray:
    """``Observer.moving`` before issue 20's seventh round (the oracle)."""
    from aoass_env.observation import MOVING_FIELDS
    c = self.config
    slots = np.zeros((c.obs_moving_obstacles, len(MOVING_FIELDS)))
    self.detections = np.zeros((0, 4))
    n = c.n_moving_obstacles
    if n == 0 or c.obs_moving_obstacles == 0:
        return slots
    rel = world.moving_positions - world.position
    noise = self._rng.normal(size=(n, 4))
    r2 = c.sensing_range * c.sensing_range * (1.0 + 1e-9)
    if all(dx * dx + dy * dy > r2 for dx, dy in rel.tolist()):
        return slots
    seen = np.flatnonzero(np.hypot(rel[:, 0], rel[:, 1]) <= c.sensing_range)
    if seen.size == 0:
        return slots
    meas_pos = rel[seen] + c.obs_position_noise * noise[seen, :2]
    meas_vel = world.moving_velocities[seen] + c.obs_velocity_noise * noise[seen, 2:]
    order = np.argsort(np.hypot(meas_pos[:, 0], meas_pos[:, 1]), kind="stable")
    self.detections = np.hstack([world.position + meas_pos[order], meas_vel[order]])
    order = order[:c.obs_moving_obstacles]
    m = len(order)
    slots[:m, :2] = meas_pos[order] / c.sensing_range
    slots[:m, 2:4] = meas_vel[order] / self._v_scale
    slots[:m, 4] = 1.0
    return slots


@pytest.mark.parametrize("sensing_range", [3.0, 8.0, 12.0])
def test_moving_equals_the_old_code_bit_for_bit(sensing_range):
    """The float test of "none in range" gives the old slots, detections and noise draws, bit
    for bit, along a random walk of the anchor among moving obstacles, and with obstacles
    placed exactly at the sensing range and a hair inside or outside it."""
    import copy

    cfg = AOASSConfig(field_size=50.0, n_nodes=5, obstacle_density=0.2, n_moving_obstacles=8,
                      sensing_range=sensing_range)
    sim = Simulator(cfg, np.random.default_rng(5))
    new = Observer(cfg, sim.spiral, np.random.default_rng(9))
    rng = np.random.default_rng(2)
    counts = [0, 0]
    for step in range(400):
        world = sim.world
        if step % 50 == 49:     # an obstacle on the range and around it
            (px, py), (mx, my) = world.position.tolist(), world.moving_xy[0]
            norm = float(np.hypot(mx - px, my - py))
            scale = sensing_range / norm * [1.0, 1.0 - 1e-16, 1.0 + 1e-16, 1.0 + 1e-10][step % 4]
            world._mpos[0] = (px + (mx - px) * scale, py + (my - py) * scale)
        old = copy.deepcopy(new)
        want = _old_moving(old, world)
        got = new.moving(world)
        assert got.tobytes() == want.tobytes() and got.shape == want.shape
        assert new.detections.tobytes() == old.detections.tobytes()
        assert new.detections.shape == old.detections.shape
        assert new._rng.bit_generator.state == old._rng.bit_generator.state
        counts[len(new.detections) > 0] += 1
        sim.step(float(rng.uniform(0.0, 1.0)), float(rng.uniform(-np.pi, np.pi)))
    assert min(counts) > 5, counts


def _numpy_observation(observer: Observer, world, *, follower_index, heading_error, coverage,
                       progress, time_fraction, coverage_map) -> np.ndarray:
    """The observation as the parts' concatenation, clipped by NumPy: the oracle of
    Observer.__call__'s element-by-element kernel."""
    c = observer.config
    position, h = world.position, world.heading
    x, y = position.tolist()
    gap = world.nearest_obstacle_distance()
    head = np.array([x / c.field_size, y / c.field_size, world.speed / c.anchor_max_speed,
                     gap / c.sensing_range, heading_error / math.pi, math.cos(h), math.sin(h)])
    waypoints = (observer.upcoming(follower_index) - position) / observer._wp_scale
    parts = [head, waypoints.ravel(), world.ray_distances() / c.sensing_range,
             observer.moving(world).ravel(), (coverage, progress, time_fraction)]
    if c.obs_coverage_sectors:
        parts += [coverage_map.sector_deficits(world.position, h, c.obs_coverage_sectors,
                                               2.0 * c.radio_range), (coverage_map.ratio,)]
    low = observation_space(c).low.astype(np.float64)
    return np.minimum(np.maximum(np.concatenate(parts), low), 1.0).astype(np.float32)


@pytest.mark.parametrize("env_id, config", [
    ("AOASS-v0", {"obstacle_density": 0.3, "n_moving_obstacles": 8}),
    ("AOASS-Adaptive-v0", {"obstacle_density": 0.2, "field_size": 60.0})])
def test_observations_are_the_numpy_concatenation_float_for_float(env_id, config):
    """Whole random-action episodes: every observation equals, by its bytes, the parts
    concatenated and clipped by NumPy, read off the same state with the same noise draws."""
    import copy

    import gymnasium as gym

    import aoass_env  # noqa: F401  (registers the ids)
    env = gym.make(env_id, **config)
    base = env.unwrapped
    checked = {"n": 0, "moving": 0}
    env.reset(seed=31)

    class Checking:
        """The episode's observer, each vector checked against the NumPy form."""

        def __init__(self, inner):
            self.inner = inner

        def __getattr__(self, name):
            return getattr(self.inner, name)

        def sense(self, world):
            self.twin = copy.deepcopy(self.inner)     # the same noise generator state
            self.inner.sense(world)

        def vector(self, world, **kwargs):
            got = self.inner.vector(world, **kwargs)
            want = _numpy_observation(self.twin, world, **kwargs)
            assert got.dtype == np.float32 and got.tobytes() == want.tobytes()
            checked["n"] += 1
            checked["moving"] += len(self.inner.detections) > 0
            return got

    base._observe = Checking(base._observe)
    env.action_space.seed(31)
    for _ in range(600):
        *_, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            env.reset()
            base._observe = Checking(base._observe)
    env.close()
    assert checked["n"] >= 600 and checked["moving"] > 0


_ODD = st.sampled_from([0.0, -0.0, 1.0, -1.0, math.nan, math.inf, -math.inf, 1e-300, -1e-300,
                        1.0 + 2.0**-52, -1.0 - 2.0**-52, 2.0**-149, 3.4e38, 3.5e38])
_ELEMENT = st.one_of(_ODD, st.floats(-3.0, 3.0, allow_subnormal=True))


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_the_observation_kernel_clips_and_rounds_as_numpy(data):
    """_vector against the concatenation clipped by NumPy, by the bytes: signed zeros on the
    bounds, NaN, infinities, values just past the bounds and at float32's limits."""
    k, n_rays, m, s = (data.draw(st.integers(0, 4)) for _ in range(4))
    scalars = data.draw(st.lists(_ELEMENT, min_size=10, max_size=10))
    x, y, speed, gap, heading_error, cos_h, sin_h, coverage, progress, time_fraction = scalars[:10]
    field, max_speed, reach = (data.draw(st.sampled_from([1.0, 3.0, 100.0, 0.3]))
                               for _ in range(3))
    wp_scale = data.draw(st.sampled_from([0.5, 10.0, 7.0]))

    def array(*shape):
        return np.array(data.draw(st.lists(_ELEMENT, min_size=int(np.prod(shape)),
                                           max_size=int(np.prod(shape))))).reshape(shape)
    upcoming, rays, slots, extra = array(k, 2), array(n_rays), array(m, 5), array(s)
    low = np.array(data.draw(st.lists(st.sampled_from([0.0, -1.0]),
                                      min_size=7 + 2 * k + n_rays + 5 * m + 3 + s,
                                      max_size=7 + 2 * k + n_rays + 5 * m + 3 + s)))
    with np.errstate(all="ignore"):
        head = np.array([x / field, y / field, speed / max_speed, gap / reach,
                         heading_error / math.pi, cos_h, sin_h])
        parts = [head, ((upcoming - np.array([x, y])) / wp_scale).ravel(), rays / reach,
                 slots.ravel(), (coverage, progress, time_fraction), extra]
        want = np.minimum(np.maximum(np.concatenate(parts), low), 1.0).astype(np.float32)
        got = _vector(x, y, field, speed, max_speed, gap, reach, heading_error, cos_h, sin_h,
                      upcoming, wp_scale, rays, slots, coverage, progress, time_fraction, extra,
                      low)
    assert got.tobytes() == want.tobytes()
