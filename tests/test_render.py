"""Tests of aoass_env.render: frames, incremental history, node colours, human mode, video."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.wrappers import RecordVideo

import aoass_env  # noqa: F401  (registers AOASS-v0)
from aoass_env.config import AOASSConfig
from aoass_env.render import _COVERAGE_ALPHA, COLORS, Renderer
from aoass_env.simulator import Simulator

SMALL = {"field_size": 30, "n_nodes": 20, "obstacle_density": 0.1, "n_moving_obstacles": 1}


def _sim(seed: int = 0, **overrides: object) -> Simulator:
    return Simulator(AOASSConfig(**{**SMALL, **overrides}), np.random.default_rng(seed))


def _count(frame: np.ndarray, color: tuple[int, int, int]) -> int:
    return int(np.all(frame == color, axis=-1).sum())


def _drive(sim: Simulator, steps: int) -> None:
    follower = sim.follower()
    for _ in range(steps):
        speed, heading = follower.command(sim.world.position, sim.world.heading, sim.config.dt)
        sim.step(speed, heading)


def test_rgb_array_frame_shape_and_dtype():
    env = gym.make("AOASS-v0", render_mode="rgb_array", **SMALL)
    env.reset(seed=0)
    frame = env.render()
    env.close()
    assert frame.shape == (640, 640, 3) and frame.dtype == np.uint8
    assert frame.flags.writeable and frame.flags.c_contiguous
    # at the start the coverage map has heard one beacon: the free cells are shaded
    assert _field_pixels(frame) > 0.3 * 640 * 640
    assert _count(frame, COLORS["obstacle"]) > 0


def _field_pixels(frame: np.ndarray) -> int:
    """Pixels of the field's colour, bare or under the coverage map's shade (any deficit)."""
    field = np.array(COLORS["field"], dtype=float)
    toward = np.array(COLORS["uncovered"], dtype=float) - field
    t = np.clip((frame - field) @ toward / (toward @ toward), 0.0, _COVERAGE_ALPHA / 255)
    return int((np.abs(frame - field - t[..., None] * toward).max(axis=-1) <= 1.0).sum())


def test_the_coverage_map_is_shaded_and_fades_as_cells_are_covered():
    env = gym.make("AOASS-v0", render_mode="rgb_array", **SMALL)
    env.reset(seed=0)
    start = env.render()
    for _ in range(300):
        env.step(np.zeros(2, np.float32))
    later = env.render()
    env.close()
    assert _count(later, COLORS["field"]) > _count(start, COLORS["field"]) + 1000


def test_frame_size_is_configurable():
    renderer = Renderer("rgb_array", 20, size=200)
    sim = _sim()
    frame = renderer.draw(sim, sim.follower())
    renderer.close()
    assert frame.shape == (200, 200, 3)


def test_trail_and_beacons_appear_as_the_episode_advances_and_vanish_on_reset():
    env = gym.make("AOASS-v0", render_mode="rgb_array", **SMALL)
    env.reset(seed=0)
    env.render()
    # the coverage map's translucent shading lies over the trail: counted without it
    env.unwrapped._renderer.show_coverage = False
    start = env.render()
    for _ in range(30):
        env.step(np.zeros(2))
    later = env.render()
    env.reset(seed=1)
    fresh = env.render()
    env.close()
    assert _count(start, COLORS["trail"]) == 0
    assert _count(later, COLORS["trail"]) > 100
    assert _count(later, COLORS["beacon"]) > _count(start, COLORS["beacon"])
    assert _count(fresh, COLORS["trail"]) == 0      # new episode, new history layer


def test_trail_drawn_incrementally_matches_trail_drawn_at_once():
    """Frames drawn every step and a frame drawn once at the end show the same picture."""
    every, once = Renderer("rgb_array", 20, show_rays=False), Renderer("rgb_array", 20,
                                                                       show_rays=False)
    sim = _sim(seed=2)
    follower = sim.follower()
    for _ in range(25):
        speed, heading = follower.command(sim.world.position, sim.world.heading, sim.config.dt)
        sim.step(speed, heading)
        every.draw(sim, follower)
    a, b = every.draw(sim, follower), once.draw(sim, follower)
    # joins between separately drawn 2 px segments may differ by a pixel here and there
    assert np.mean(np.any(a != b, axis=-1)) < 1e-3


def test_nodes_are_coloured_by_coverage():
    sim = _sim(seed=3, n_nodes=60)
    _drive(sim, 120)
    renderer = Renderer("rgb_array", 20, show_rays=False)
    frame = renderer.draw(sim, sim.follower())
    net = sim.network
    heard, covered = net.heard > 0, net.covered
    px = renderer.to_screen(sim.nodes)
    # nodes clear of other nodes, moving bodies, the anchor, the target and the status line
    others = np.r_[sim.world.moving_positions, sim.world.position[None]]
    clear = np.ones(len(px), dtype=bool)
    for i, p in enumerate(px):
        near_node = np.delete(np.hypot(*(px - p).T), i).min() < 10
        near_body = np.hypot(*(renderer.to_screen(others) - p).T).min() < 20
        clear[i] = not (near_node or near_body or p[1] < 30)
    for key, mask in (("node_silent", ~heard), ("node_heard", heard & ~covered),
                      ("node_covered", covered)):
        centres = np.round(px[mask & clear]).astype(int)
        assert len(centres) > 0, f"no {key} node to check"
        for x, y in centres:
            assert tuple(frame[y, x]) == COLORS[key], (key, x, y)


def test_world_y_up_maps_to_screen_y_down():
    renderer = Renderer("rgb_array", 20)
    sim = _sim()
    renderer.draw(sim, sim.follower())
    (x0, y0), (x1, y1) = renderer.to_screen(np.array([[0.0, 0.0], [30.0, 30.0]]))
    assert x1 > x0 and y1 < y0
    assert 0 <= x0 < x1 < 640 and 0 <= y1 < y0 < 640


def test_recorder_exposes_beacons_and_path_so_far():
    sim = _sim()
    _drive(sim, 10)
    log = sim.finish()
    np.testing.assert_array_equal(sim.recorder.beacon_positions, log.beacons[:, 1:])
    np.testing.assert_array_equal(sim.recorder.path_points, log.anchor_path[:, 1:])
    assert sim.recorder.path_points.shape == (11, 2)


def test_human_mode_runs_headless(monkeypatch):
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    env = gym.make("AOASS-v0", render_mode="human", **SMALL)
    env.reset(seed=0)                  # human mode draws on reset and on every step
    for _ in range(3):
        env.step(np.zeros(2))
    assert env.render() is None
    env.close()


def test_two_human_windows_in_one_process_close_in_any_order(monkeypatch):
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    first = gym.make("AOASS-v0", render_mode="human", **SMALL)
    second = gym.make("AOASS-v0", render_mode="human", **SMALL)
    first.reset(seed=520001)
    second.reset(seed=520002)
    first.close()
    # pygame has one display: the first close used to quit it under the second
    second.step(np.zeros(2, np.float32))
    second.close()
    import pygame
    assert not pygame.display.get_init()


def test_the_coverage_shade_stays_inside_a_field_of_partial_cells():
    # 51 m is not a whole number of coverage cells: the last cells reach past the field
    sim = _sim(520008, field_size=51.0, n_nodes=10, n_moving_obstacles=0)
    assert sim.map.width % sim.coverage_map.cell != 0
    shaded, bare = Renderer("rgb_array", 20), Renderer("rgb_array", 20, show_coverage=False)
    frame, plain = shaded.draw(sim, sim.follower()), bare.draw(sim, sim.follower())
    left, bottom = shaded._origin
    right = left + sim.map.width * shaded._scale
    top = bottom - sim.map.height * shaded._scale
    inside = np.zeros(frame.shape[:2], dtype=bool)
    inside[int(np.floor(top)):int(np.ceil(bottom)) + 1,
           int(np.floor(left)):int(np.ceil(right)) + 1] = True
    # outside the field (the margin, the status line) the frame is the one without the shade:
    # the shade used to spill over both
    assert (frame != plain).any(axis=-1)[inside].any()
    np.testing.assert_array_equal(frame[~inside], plain[~inside])


def test_closed_renderer_refuses_to_draw():
    renderer = Renderer("rgb_array", 20)
    renderer.close()
    renderer.close()
    sim = _sim()
    with pytest.raises(RuntimeError, match="closed"):
        renderer.draw(sim, sim.follower())


def test_bad_render_mode_is_rejected():
    with pytest.raises(ValueError, match="render_mode"):
        Renderer("ansi", 20)


def test_record_video_writes_a_video(tmp_path):
    env = gym.make("AOASS-v0", render_mode="rgb_array", max_episode_steps=40, **SMALL)
    env = RecordVideo(env, str(tmp_path / "videos"), episode_trigger=lambda episode: True)
    env.reset(seed=0)
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        done = terminated or truncated
    env.close()
    videos = list((tmp_path / "videos").glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 1000
