"""SequenceReplayBuffer: windows never cross an episode boundary, wrap-around, timeouts."""

from __future__ import annotations

import numpy as np
import pytest
import torch as th
from gymnasium import spaces
from hypothesis import given, settings
from hypothesis import strategies as st

from agents.buffers import SequenceReplayBuffer

OBS_SPACE = spaces.Box(-np.inf, np.inf, (3,), np.float32)
ACT_SPACE = spaces.Box(-100.0, 100.0, (2,), np.float32)


def _schedule(episodes: list[tuple[int, bool]], total: int) -> list[tuple[int, int, bool, bool]]:
    """``total`` steps (episode, step, last step of the episode, truncated) from episode
    (length, truncated) pairs; after the listed episodes, one episode runs on unfinished."""
    out = []
    for ep, (length, truncated) in enumerate(episodes):
        out += [(ep, k, k == length - 1, truncated) for k in range(length)]
    ep = len(episodes)
    out += [(ep, k, False, False) for k in range(max(0, total - len(out)))]
    return out[:total]


def _transition(env: int, ep: int, step: int) -> dict[str, np.ndarray | float]:
    """The stored data of one step, encoding (env, episode, step)."""
    return {
        "obs": np.array([env, ep, step], np.float32),
        "next_obs": np.array([env, ep, step + 1], np.float32),
        "action": np.array([ep + 1, step + 1], np.float32),
        "reward": float(env * 1000 + ep * 10 + step),
    }


@settings(max_examples=80, deadline=None)
@given(data=st.data())
def test_windows_stay_inside_one_episode(data: st.DataObject) -> None:
    n_envs = data.draw(st.integers(1, 3), label="n_envs")
    capacity = data.draw(st.integers(1, 12), label="capacity per env")
    burn_in = data.draw(st.integers(0, 3), label="burn_in")
    train_length = data.draw(st.integers(1, 4), label="train_length")
    total = data.draw(st.integers(1, 30), label="steps")
    episode = st.tuples(st.integers(1, 6), st.booleans())
    schedules = [_schedule(data.draw(st.lists(episode, max_size=12), label=f"episodes {e}"), total)
                 for e in range(n_envs)]

    buf = SequenceReplayBuffer(capacity * n_envs, OBS_SPACE, ACT_SPACE, device="cpu",
                               n_envs=n_envs, burn_in=burn_in, train_length=train_length)
    for t in range(total):
        steps = [_transition(e, *schedules[e][t][:2]) for e in range(n_envs)]
        dones = np.array([schedules[e][t][2] for e in range(n_envs)])
        infos = [{"TimeLimit.truncated": True} if schedules[e][t][2] and schedules[e][t][3]
                 else {} for e in range(n_envs)]
        buf.add(np.stack([s["obs"] for s in steps]), np.stack([s["next_obs"] for s in steps]),
                np.stack([s["action"] for s in steps]), np.array([s["reward"] for s in steps]),
                dones, infos)

    length = burn_in + train_length
    size = buf.size()
    assert size == min(total, capacity)
    oldest = buf.pos if buf.full else 0
    rows = np.repeat(np.arange(size), n_envs)
    envs = np.tile(np.arange(n_envs), size)
    batch = buf._get_samples(rows, env_indices=envs)
    assert batch.observations.shape == (len(rows), length, 3)
    assert batch.actions.shape == batch.prev_actions.shape == (len(rows), length, 2)
    assert batch.rewards.shape == batch.dones.shape == batch.mask.shape == (len(rows), length)
    for b, (row, env) in enumerate(zip(rows, envs, strict=True)):
        retained = schedules[env][total - size:]  # the steps still in the buffer, oldest first
        i = (row - oldest) % capacity
        ep = retained[i][0]
        n = 1
        while n < length and i - n >= 0 and retained[i - n][0] == ep:
            n += 1
        window = retained[i - n + 1: i + 1]
        mask = batch.mask[b].numpy()
        np.testing.assert_array_equal(mask, np.arange(length) < n)
        expected = [_transition(env, e, k) for e, k, _, _ in window]
        obs = batch.observations[b].numpy()
        np.testing.assert_array_equal(obs[:n], [s["obs"] for s in expected])
        np.testing.assert_array_equal(obs[n:], 0.0)
        np.testing.assert_array_equal(batch.next_observations[b, :n].numpy(),
                                      [s["next_obs"] for s in expected])
        np.testing.assert_array_equal(batch.actions[b, :n].numpy(),
                                      [s["action"] for s in expected])
        np.testing.assert_array_equal(batch.rewards[b, :n].numpy(),
                                      [s["reward"] for s in expected])
        prev = [np.zeros(2) if k == 0 else np.array([e + 1, k]) for e, k, _, _ in window]
        np.testing.assert_array_equal(batch.prev_actions[b, :n].numpy(), prev)
        dones = [float(last and not truncated) for _, _, last, truncated in window]
        np.testing.assert_array_equal(batch.dones[b, :n].numpy(), dones)
        starts_episode = window[0][1] == 0
        loss = (np.arange(length) < n) & ((np.arange(length) >= burn_in) | starts_episode)
        np.testing.assert_array_equal(batch.loss_mask[b].numpy(), loss)

    sampled = buf.sample(5)
    assert sampled.observations.shape == (5, length, 3)
    assert all(x.dtype == th.float32 for x in sampled)
    assert (sampled.mask[:, 0] == 1).all()  # the last step of a window is always valid


def test_truncation_stored_as_not_done_but_still_ends_the_episode() -> None:
    buf = SequenceReplayBuffer(10, OBS_SPACE, ACT_SPACE, device="cpu", burn_in=0, train_length=4)
    for step, (done, info) in enumerate([(False, {}), (True, {"TimeLimit.truncated": True}),
                                         (False, {}), (True, {})]):
        t = _transition(0, step // 2, step % 2)
        buf.add(t["obs"][None], t["next_obs"][None], t["action"][None],
                np.array([t["reward"]]), np.array([done]), [info])
    np.testing.assert_array_equal(buf.dones[:4, 0], [0, 0, 0, 1])
    np.testing.assert_array_equal(buf.timeouts[:4, 0], [0, 1, 0, 0])
    np.testing.assert_array_equal(buf.episode_starts[:4, 0], [1, 0, 1, 0])
    batch = buf._get_samples(np.array([2, 3]), env_indices=np.array([0, 0]))
    np.testing.assert_array_equal(batch.mask.numpy(), [[1, 0, 0, 0], [1, 1, 0, 0]])


def test_start_new_episodes_cuts_windows() -> None:
    buf = SequenceReplayBuffer(10, OBS_SPACE, ACT_SPACE, device="cpu", burn_in=1, train_length=3)
    for step in range(4):
        if step == 2:
            buf.start_new_episodes()  # e.g. the env was reset by a new learn() call
        t = _transition(0, 0, step)
        buf.add(t["obs"][None], t["next_obs"][None], t["action"][None], np.array([0.0]),
                np.array([False]), [{}])
    batch = buf._get_samples(np.array([3]), env_indices=np.array([0]))
    np.testing.assert_array_equal(batch.mask.numpy(), [[1, 1, 0, 0]])
    np.testing.assert_array_equal(batch.prev_actions[0, 0].numpy(), [0, 0])


def test_buffer_rejects_bad_arguments() -> None:
    with pytest.raises(ValueError, match="optimize_memory_usage"):
        SequenceReplayBuffer(10, OBS_SPACE, ACT_SPACE, optimize_memory_usage=True,
                             handle_timeout_termination=False)
    with pytest.raises(ValueError, match="burn_in"):
        SequenceReplayBuffer(10, OBS_SPACE, ACT_SPACE, burn_in=-1)
    with pytest.raises(ValueError, match="train_length"):
        SequenceReplayBuffer(10, OBS_SPACE, ACT_SPACE, train_length=0)
    with pytest.raises(ValueError, match="Dict"):
        SequenceReplayBuffer(10, spaces.Dict({"a": OBS_SPACE}), ACT_SPACE)
    with pytest.raises(RuntimeError, match="empty"):
        SequenceReplayBuffer(10, OBS_SPACE, ACT_SPACE).sample(4)
