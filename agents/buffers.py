"""Sequence replay buffer for recurrent off-policy agents (``RecurrentTD3``).

Transitions are stored per env in circular arrays of shape ``(buffer_size, n_envs, ...)`` together
with an episode-start flag and the previous action (zero at an episode start). ``sample`` draws
windows of ``burn_in + train_length`` consecutive steps that end at a uniformly drawn stored step
(the window's *last step*) and keeps only the steps of that step's episode that are still in the
buffer. The kept (valid) steps are moved to the front of the window and the rest is zero padding,
so that a recurrent network run from a zero state over the window starts exactly at the first
valid step: one ``nn.LSTM`` pass over ``(batch, length, features)`` needs no packing or resets.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.buffers import BaseBuffer, ReplayBuffer
from stable_baselines3.common.vec_env import VecNormalize

from aoass_env.validators import integer


class SequenceReplayBufferSamples(NamedTuple):
    """A batch of windows; the valid steps of each window come first, then zero padding.

    Shapes: ``observations``/``next_observations`` ``(B, L, *obs_shape)``, ``prev_actions``/
    ``actions`` ``(B, L, action_dim)``, the rest ``(B, L)``. ``dones`` is 1 only for a terminal
    step (a time-limit truncation stores 0 so that the target bootstraps). ``mask`` is 1 on the
    valid steps; ``loss_mask`` is 1 on the valid steps whose recurrent state is trustworthy:
    past the burn-in, or every valid step when the window starts at its episode's first step.
    """

    observations: th.Tensor
    prev_actions: th.Tensor
    actions: th.Tensor
    next_observations: th.Tensor
    rewards: th.Tensor
    dones: th.Tensor
    mask: th.Tensor
    loss_mask: th.Tensor


def check_sequence_lengths(burn_in: Any, train_length: Any) -> tuple[int, int]:
    """(burn_in, train_length) as ints; ``ValueError`` naming the parameter when one is not an
    integer >= 0 (burn_in) or >= 1 (train_length)."""
    return (integer("burn_in", burn_in, "steps", low=0),
            integer("train_length", train_length, "steps", low=1))


class SequenceReplayBuffer(ReplayBuffer):
    """Replay buffer that samples fixed-length windows that never cross an episode boundary.

    :param buffer_size: total number of transitions kept (split evenly between the envs)
    :param observation_space: observation space (``Dict`` spaces are not supported)
    :param action_space: action space
    :param device: torch device of the sampled tensors
    :param n_envs: number of parallel envs
    :param optimize_memory_usage: not supported; must be False
    :param handle_timeout_termination: store a ``TimeLimit.truncated`` end as not done (bootstrap)
    :param burn_in: leading steps of a window that only warm up the recurrent state
    :param train_length: steps of a window after the burn-in that enter the losses
    """

    def __init__(
        self,
        buffer_size: int,
        observation_space: spaces.Space,
        action_space: spaces.Space,
        device: th.device | str = "auto",
        n_envs: int = 1,
        optimize_memory_usage: bool = False,
        handle_timeout_termination: bool = True,
        burn_in: int = 8,
        train_length: int = 16,
    ):
        if optimize_memory_usage:
            raise ValueError(
                "SequenceReplayBuffer does not support optimize_memory_usage=True "
                "(windows need the next observation of every step); pass False"
            )
        if isinstance(observation_space, spaces.Dict):
            raise ValueError("SequenceReplayBuffer does not support Dict observation spaces")
        burn_in, train_length = check_sequence_lengths(burn_in, train_length)
        buffer_size = integer("buffer_size", buffer_size, "transitions", low=1)
        BaseBuffer.__init__(self, buffer_size, observation_space, action_space, device, n_envs)
        self.buffer_size = max(buffer_size // n_envs, 1)
        self.optimize_memory_usage = False
        self.handle_timeout_termination = handle_timeout_termination
        self.burn_in, self.train_length = burn_in, train_length

        dtype = observation_space.dtype
        obs_dtype = np.float32 if dtype is None or np.issubdtype(dtype, np.floating) else dtype
        shape = (self.buffer_size, self.n_envs)
        self.observations = np.zeros((*shape, *self.obs_shape), dtype=obs_dtype)
        self.next_observations = np.zeros((*shape, *self.obs_shape), dtype=obs_dtype)
        self.actions = np.zeros((*shape, self.action_dim), dtype=np.float32)
        self.prev_actions = np.zeros((*shape, self.action_dim), dtype=np.float32)
        self.rewards = np.zeros(shape, dtype=np.float32)
        self.dones = np.zeros(shape, dtype=np.float32)  # terminal only: 0 after a truncation
        self.timeouts = np.zeros(shape, dtype=np.float32)
        self.episode_starts = np.zeros(shape, dtype=bool)
        # Per-env bookkeeping for the next add(): does it start an episode, and the last action.
        self._next_is_start = np.ones(self.n_envs, dtype=bool)
        self._last_action = np.zeros((self.n_envs, self.action_dim), dtype=np.float32)

    @property
    def sequence_length(self) -> int:
        """Window length ``burn_in + train_length``."""
        return self.burn_in + self.train_length

    def start_new_episodes(self, env_indices: np.ndarray | list[int] | None = None) -> None:
        """Mark that the next stored step of these envs (all when None) starts an episode, e.g.
        after the envs were reset outside of a ``done``."""
        idx = slice(None) if env_indices is None else np.asarray(env_indices)
        self._next_is_start[idx] = True
        self._last_action[idx] = 0.0

    def reset(self) -> None:
        """Empty the buffer; the next stored step of every env starts an episode."""
        super().reset()
        self.start_new_episodes()

    def add(
        self,
        obs: np.ndarray,
        next_obs: np.ndarray,
        action: np.ndarray,
        reward: np.ndarray,
        done: np.ndarray,
        infos: list[dict[str, Any]],
    ) -> None:
        """Store one step of every env (arguments as SB3's ``ReplayBuffer.add``)."""
        n = self.n_envs
        action = np.asarray(action, dtype=np.float32).reshape(n, self.action_dim)
        done = np.asarray(done).reshape(n).astype(bool)
        if self.handle_timeout_termination:
            truncated = np.array([bool(i.get("TimeLimit.truncated", False)) for i in infos])
        else:
            truncated = np.zeros(n, dtype=bool)
        p = self.pos
        self.observations[p] = np.asarray(obs).reshape(n, *self.obs_shape)
        self.next_observations[p] = np.asarray(next_obs).reshape(n, *self.obs_shape)
        self.actions[p] = action
        self.prev_actions[p] = np.where(self._next_is_start[:, None], 0.0, self._last_action)
        self.episode_starts[p] = self._next_is_start
        self.rewards[p] = np.asarray(reward, dtype=np.float32).reshape(n)
        self.dones[p] = done & ~truncated
        self.timeouts[p] = truncated
        self._last_action = action.copy()
        self._next_is_start = done.copy()
        self.pos += 1
        if self.pos == self.buffer_size:
            self.full = True
            self.pos = 0

    def sample(
        self, batch_size: int, env: VecNormalize | None = None
    ) -> SequenceReplayBufferSamples:
        """Draw ``batch_size`` windows ending at uniformly drawn stored steps of random envs
        (NumPy's global generator, which SB3's ``seed`` sets, as in SB3's buffers)."""
        upper = self.size()
        if upper == 0:
            raise RuntimeError("cannot sample from an empty SequenceReplayBuffer")
        end_inds = np.random.randint(0, upper, size=batch_size)  # noqa: NPY002
        env_inds = np.random.randint(0, self.n_envs, size=batch_size)  # noqa: NPY002
        return self._get_samples(end_inds, env=env, env_indices=env_inds)

    def window_indices(
        self, end_inds: np.ndarray, env_inds: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Buffer rows of the windows that end at ``end_inds`` (rows) of ``env_inds``.

        :return: ``rows`` (B, L) with the valid steps first (padding repeats the last step),
            ``mask`` (B, L) bool and ``starts_episode`` (B,) whether the first valid step is its
            episode's first step.
        """
        length = self.sequence_length
        end_inds = np.asarray(end_inds, dtype=np.int64)
        env_col = np.asarray(env_inds, dtype=np.int64)[:, None]
        back = np.arange(length - 1, -1, -1)  # steps back from the last step, oldest first
        oldest = self.pos if self.full else 0
        retained_before = (end_inds - oldest) % self.buffer_size  # stored steps older than end
        rows = (end_inds[:, None] - back[None, :]) % self.buffer_size
        stored = back[None, :] <= retained_before[:, None]
        starts = self.episode_starts[rows, env_col] & stored
        # A step is valid when stored and no episode starts after it inside the window.
        starts_from = np.cumsum(starts[:, ::-1], axis=1)[:, ::-1]
        valid = stored & (starts_from - starts == 0)
        n_valid = valid.sum(axis=1)  # >= 1: the last step is always valid
        k = np.arange(length)[None, :]
        mask = k < n_valid[:, None]
        shift = np.minimum(k, n_valid[:, None] - 1)
        rows = (end_inds[:, None] - n_valid[:, None] + 1 + shift) % self.buffer_size
        starts_episode = self.episode_starts[rows[:, 0], env_col[:, 0]]
        return rows, mask, starts_episode

    def _get_samples(  # type: ignore[override]
        self,
        batch_inds: np.ndarray,
        env: VecNormalize | None = None,
        env_indices: np.ndarray | None = None,
    ) -> SequenceReplayBufferSamples:
        if env_indices is None:
            env_indices = np.random.randint(0, self.n_envs, size=len(batch_inds))  # noqa: NPY002
        rows, mask, starts_episode = self.window_indices(batch_inds, env_indices)
        env_col = np.asarray(env_indices)[:, None]
        loss_mask = mask & ((np.arange(self.sequence_length)[None, :] >= self.burn_in)
                            | starts_episode[:, None])

        def steps(arr: np.ndarray) -> np.ndarray:
            out = arr[rows, env_col]
            return out * mask.reshape(mask.shape + (1,) * (out.ndim - 2)).astype(out.dtype)

        obs = self._normalize_obs(self.observations[rows, env_col], env)
        next_obs = self._normalize_obs(self.next_observations[rows, env_col], env)
        obs_mask = mask.reshape(mask.shape + (1,) * len(self.obs_shape))
        rewards = self._normalize_reward(self.rewards[rows, env_col], env) * mask
        data = (
            np.where(obs_mask, obs, 0).astype(np.float32),
            steps(self.prev_actions),
            steps(self.actions),
            np.where(obs_mask, next_obs, 0).astype(np.float32),
            rewards.astype(np.float32),
            steps(self.dones),
            mask.astype(np.float32),
            loss_mask.astype(np.float32),
        )
        return SequenceReplayBufferSamples(*(th.as_tensor(x, device=self.device) for x in data))
