"""Recurrent TD3 (TD3-LSTM) for Stable-Baselines3.

TD3 (Fujimoto et al. 2018) with LSTM actor and critics trained on replayed windows, following
LSTM-TD3 (Meng, Gorbet, Kulić 2021, "Memory-based Deep Reinforcement Learning for POMDPs") and
R2D2's burn-in (Kapturowski et al. 2019). SB3's off-policy loop is reused unchanged (rollout
collection, action noise, callbacks, logging, save/load, ``learning_starts``, ``train_freq``,
``gradient_steps``); this class only adds what recurrence needs: the sequence replay buffer, the
per-env LSTM state during rollouts, and sequence losses.
"""

from __future__ import annotations

import warnings
from typing import Any, ClassVar, TypeVar

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3 import TD3
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.noise import ActionNoise
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.type_aliases import GymEnv, MaybeCallback, Schedule
from stable_baselines3.common.utils import polyak_update
from torch.nn import functional as F

from agents.buffers import SequenceReplayBuffer, SequenceReplayBufferSamples, check_sequence_lengths
from agents.checkpoints import SafeLoading
from agents.policies import RecurrentActor, RecurrentCritic, RecurrentTD3Policy
from aoass_env.validators import integer, real

SelfRecurrentTD3 = TypeVar("SelfRecurrentTD3", bound="RecurrentTD3")
RolloutState = tuple[np.ndarray, np.ndarray, np.ndarray]


class RecurrentTD3(SafeLoading, TD3):
    """TD3 with recurrent (LSTM) actor and twin critics for partially observable tasks.

    Windows of ``burn_in + train_length`` steps are replayed; each network runs one LSTM pass per
    window from a zero state at the window's first valid step. The first ``burn_in`` steps only
    warm up that state unless the window starts at its episode's first step (then the zero
    state is the true one and every step is trained). Losses are TD3's, averaged over the
    trained steps: clipped double-Q targets with target policy smoothing, delayed actor and
    Polyak target updates.

    Arguments are TD3's (see ``stable_baselines3.TD3``) except:

    :param batch_size: number of windows per gradient step
    :param burn_in: leading steps of a window used only to warm up the LSTM state
    :param train_length: steps of a window after the burn-in that enter the losses
    :param n_steps: n-step TD targets, computed inside each replayed window (SB3's
        ``n_steps``): ``sum_{k<m} gamma^k r_{t+k} + gamma^m Q'(h_{t+m})`` with
        ``m = min(n_steps, steps left in the window)``, no bootstrap after a terminal step and
        no off-policy correction (as in R2D2 and D4PG). 1 is TD3's one-step target.
    :param critic_warmup: gradient steps that train only the critics (and update their
        targets) before the actor's first update, so the actor starts from a critic that has
        seen the replayed data; 0 trains both from the first step (TD3)
    :param actor_bound_penalty: weight of the mean squared pre-tanh output in the actor's loss
        (added to TD3's ``-Q``): it keeps the actor off the bounds of its action box, where
        tanh's gradient vanishes and the actor stops reading its input; 0 is TD3's loss

    ``load`` reads a saved model without unpickling anything (rebuilt from the run.yml beside
    it, :mod:`agents.checkpoints`); replay buffers are saved as ``.npz``.
    ``optimize_memory_usage`` is not supported. LSTM sizes go in
    ``policy_kwargs`` (``lstm_hidden_size``, ``n_lstm_layers``, ``net_arch``,
    ``current_features``; see ``RecurrentTD3Policy``).
    """

    policy_aliases: ClassVar[dict[str, type[BasePolicy]]] = {"MlpLstmPolicy": RecurrentTD3Policy}
    algo_name = "td3-lstm"
    default_policy = "MlpLstmPolicy"
    policy: RecurrentTD3Policy
    actor: RecurrentActor  # type: ignore[assignment]
    actor_target: RecurrentActor  # type: ignore[assignment]
    critic: RecurrentCritic  # type: ignore[assignment]
    critic_target: RecurrentCritic  # type: ignore[assignment]
    replay_buffer: SequenceReplayBuffer  # type: ignore[assignment]

    def __init__(
        self,
        policy: str | type[RecurrentTD3Policy],
        env: GymEnv | str,
        learning_rate: float | Schedule = 1e-3,
        buffer_size: int = 1_000_000,
        learning_starts: int = 100,
        batch_size: int = 64,
        tau: float = 0.005,
        gamma: float = 0.99,
        train_freq: int | tuple[int, str] = 1,
        gradient_steps: int = 1,
        action_noise: ActionNoise | None = None,
        replay_buffer_class: type[ReplayBuffer] | None = None,
        replay_buffer_kwargs: dict[str, Any] | None = None,
        optimize_memory_usage: bool = False,
        policy_delay: int = 2,
        target_policy_noise: float = 0.2,
        target_noise_clip: float = 0.5,
        burn_in: int = 8,
        train_length: int = 16,
        n_steps: int = 1,
        critic_warmup: int = 0,
        actor_bound_penalty: float = 0.0,
        stats_window_size: int = 100,
        tensorboard_log: str | None = None,
        policy_kwargs: dict[str, Any] | None = None,
        verbose: int = 0,
        seed: int | None = None,
        device: th.device | str = "auto",
        _init_setup_model: bool = True,
    ):
        burn_in, train_length = check_sequence_lengths(burn_in, train_length)
        if optimize_memory_usage:
            raise ValueError("optimize_memory_usage=True is not supported by RecurrentTD3")
        batch_size = integer("batch_size", batch_size, "windows", low=1)
        learning_starts = integer("learning_starts", learning_starts, "steps", low=0)
        tau = real("tau", tau, low=0.0, low_open=True, high=1.0)
        gamma = real("gamma", gamma, low=0.0, low_open=True, high=1.0)
        # a negative clip made the target smoothing noise a constant (clamp with min > max)
        target_policy_noise = real("target_policy_noise", target_policy_noise, low=0.0)
        target_noise_clip = real("target_noise_clip", target_noise_clip, low=0.0)
        policy_delay = integer("policy_delay", policy_delay, "updates", low=1)
        n_steps = integer("n_steps", n_steps, "steps", low=1)
        critic_warmup = integer("critic_warmup", critic_warmup, "updates", low=0)
        actor_bound_penalty = real("actor_bound_penalty", actor_bound_penalty, low=0.0)
        if replay_buffer_class is not None and not issubclass(replay_buffer_class,
                                                              SequenceReplayBuffer):
            raise ValueError("replay_buffer_class must be SequenceReplayBuffer or a subclass, got "
                             f"{replay_buffer_class.__name__}")
        for key in ("burn_in", "train_length"):
            if key in (replay_buffer_kwargs or {}):
                raise ValueError(f"pass {key} to RecurrentTD3, not in replay_buffer_kwargs")
        self.burn_in, self.train_length = burn_in, train_length
        self.critic_warmup = critic_warmup
        self.actor_bound_penalty = actor_bound_penalty
        self._rollout_state: RolloutState | None = None
        super().__init__(
            policy, env, learning_rate=learning_rate, buffer_size=buffer_size,
            learning_starts=learning_starts, batch_size=batch_size, tau=tau, gamma=gamma,
            train_freq=train_freq, gradient_steps=gradient_steps, action_noise=action_noise,
            replay_buffer_class=replay_buffer_class, replay_buffer_kwargs=replay_buffer_kwargs,
            optimize_memory_usage=False, n_steps=n_steps, policy_delay=policy_delay,
            target_policy_noise=target_policy_noise, target_noise_clip=target_noise_clip,
            stats_window_size=stats_window_size, tensorboard_log=tensorboard_log,
            policy_kwargs=policy_kwargs, verbose=verbose, seed=seed, device=device,
            _init_setup_model=False,
        )
        if _init_setup_model:
            self._setup_model()

    @property
    def sequence_length(self) -> int:
        """Replayed window length ``burn_in + train_length``."""
        return self.burn_in + self.train_length

    def _setup_model(self) -> None:
        check_sequence_lengths(self.burn_in, self.train_length)
        if isinstance(self.observation_space, spaces.Dict):
            raise ValueError("RecurrentTD3 does not support Dict observation spaces")
        if self.replay_buffer_class is None:
            self.replay_buffer_class = SequenceReplayBuffer
        if self.replay_buffer is None:
            self.replay_buffer = self.replay_buffer_class(  # type: ignore[call-arg]
                self.buffer_size, self.observation_space, self.action_space, device=self.device,
                n_envs=self.n_envs, optimize_memory_usage=False, burn_in=self.burn_in,
                train_length=self.train_length, **self.replay_buffer_kwargs,
            )
        with warnings.catch_warnings():
            # SB3 warns that its own n-step buffer is not set up: the windows' loss does it.
            warnings.filterwarnings("ignore", message=r"`n_steps=\d+` is ignored")
            super()._setup_model()
        self._rollout_state = None

    # ----------------------------------------------------------------------------- rollouts
    def _reset_rollout_state(self, n_envs: int) -> RolloutState:
        self._rollout_state = self.policy.initial_state(n_envs)
        return self._rollout_state

    def _setup_learn(
        self,
        total_timesteps: int,
        callback: MaybeCallback = None,
        reset_num_timesteps: bool = True,
        tb_log_name: str = "run",
        progress_bar: bool = False,
    ) -> tuple[int, Any]:
        resets_env = reset_num_timesteps or self._last_obs is None
        out = super()._setup_learn(total_timesteps, callback, reset_num_timesteps, tb_log_name,
                                   progress_bar)
        if resets_env or self._rollout_state is None:
            # Fresh episodes: zero LSTM state, and the buffer must not join them to the old ones.
            assert self.env is not None
            self._reset_rollout_state(self.env.num_envs)
            if self.replay_buffer is not None:
                self.replay_buffer.start_new_episodes()
        return out

    def _sample_action(
        self,
        learning_starts: int,
        action_noise: ActionNoise | None = None,
        n_envs: int = 1,
    ) -> tuple[np.ndarray, np.ndarray]:
        """TD3's exploration (uniform warm-up, then actor + noise) with the actor's LSTM state
        carried per env; warm-up actions advance the state too, and the previous action fed to
        the actor is the one actually taken (after noise and clipping)."""
        assert self._last_obs is not None, "self._last_obs was not set"
        state = self._rollout_state
        if state is None or state[2].shape[0] != n_envs:
            state = self._reset_rollout_state(n_envs)
        unscaled_action, (h, c, _) = self.policy.predict(self._last_obs, state=state)
        if self.num_timesteps < learning_starts:
            unscaled_action = np.array([self.action_space.sample() for _ in range(n_envs)])
        scaled_action = self.policy.scale_action(unscaled_action)
        if action_noise is not None:
            scaled_action = np.clip(scaled_action + action_noise(), -1, 1)
        buffer_action = scaled_action.astype(np.float32)
        self._rollout_state = (h, c, buffer_action.reshape(n_envs, -1).copy())
        return self.policy.unscale_action(scaled_action), buffer_action

    def _store_transition(
        self,
        replay_buffer: ReplayBuffer,
        buffer_action: np.ndarray,
        new_obs: np.ndarray | dict[str, np.ndarray],
        reward: np.ndarray,
        dones: np.ndarray,
        infos: list[dict[str, Any]],
    ) -> None:
        """Store the step (the buffer records episode starts from ``dones``) and zero the
        rollout state of the envs whose episode ended."""
        super()._store_transition(replay_buffer, buffer_action, new_obs, reward, dones, infos)
        done = np.asarray(dones, dtype=bool)
        if self._rollout_state is not None and done.any():
            h, c, prev = self._rollout_state
            h[:, done], c[:, done], prev[done] = 0.0, 0.0, 0.0

    def predict(  # type: ignore[override]
        self,
        observation: np.ndarray | dict[str, np.ndarray],
        state: tuple[np.ndarray, ...] | None = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
        """Action and next recurrent state ``(h, c, prev_action)``; pass the state back on the
        next call and ``episode_start`` flags to zero it (see ``RecurrentTD3Policy.predict``)."""
        return self.policy.predict(observation, state, episode_start, deterministic)

    # ----------------------------------------------------------------------------- training
    def _critic_targets(self, data: SequenceReplayBufferSamples,
                        select: th.Tensor | None = None) -> th.Tensor:
        """TD targets at the window positions where ``select`` (B, L) is True, shape (N,); all
        positions (B, L) when None.

        With ``Q'_t = min_i Q'_i(h_{t+1}, a'_{t+1})``, the value of the history after step t:
        ``G_t = sum_{k<m} gamma^k r_{t+k} + gamma^m (1 - done_{t+m-1}) Q'_{t+m-1}`` with
        ``m = min(n_steps, valid steps from t to the window's end)``; ``n_steps = 1`` gives
        TD3's ``r_t + gamma (1 - done_t) Q'_t``. A window holds one episode, so only its last
        valid step can be terminal.

        The target networks read the window extended by one step, ``[o_0, next_o_0, ...,
        next_o_{L-1}]`` with previous actions ``[prev_a_0, a_0, ..., a_{L-1}]``; inside an
        episode ``next_o_t = o_{t+1}``, so their output at ``t + 1`` sums the history up to the
        next observation. ``a'`` is the target actor's action plus clipped Gaussian noise.
        """
        batch, length = data.rewards.shape
        with th.no_grad():
            returns, discount, last = self._n_step_parts(data.rewards, data.mask)
            chosen = th.ones_like(data.mask, dtype=th.bool) if select is None else select
            # The heads run only where a selected target bootstraps: (rows, cols) of Q'.
            rows = th.arange(batch, device=last.device)[:, None].expand_as(last)[chosen]
            cols = last[chosen]
            obs = th.cat([data.observations[:, :1], data.next_observations], dim=1)
            prev = th.cat([data.prev_actions[:, :1], data.actions], dim=1)
            actor_memory, _ = self.actor_target.memory(obs, prev)
            next_actions = self.actor_target.act(actor_memory[:, 1:][rows, cols])
            if self.target_policy_noise > 0:
                noise = th.randn_like(next_actions) * self.target_policy_noise
                next_actions = next_actions + noise.clamp(-self.target_noise_clip,
                                                          self.target_noise_clip)
            next_actions = next_actions.clamp(-1, 1)
            memories = self.critic_target.memory(obs, prev)
            next_q = th.stack([self.critic_target.q_value(i, m[:, 1:][rows, cols], next_actions)
                               for i, m in enumerate(memories)]).min(dim=0).values
            targets = (returns[chosen]
                       + discount[chosen] * (1.0 - data.dones[rows, cols]) * next_q)
            return targets.view(batch, length) if select is None else targets

    def _n_step_parts(self, rewards: th.Tensor, mask: th.Tensor
                      ) -> tuple[th.Tensor, th.Tensor, th.Tensor]:
        """Per (B, L) window position t of :meth:`_critic_targets`: the discounted reward sum
        ``sum_{k<m} gamma^k r_{t+k}``, the bootstrap discount ``gamma^m`` and the index
        ``t + m - 1`` of the step whose ``Q'`` it bootstraps from, with
        ``m = min(n_steps, valid steps from t on)``; meaningless past the valid steps."""
        length = rewards.shape[1]
        t = th.arange(length, device=rewards.device)[None, :]
        left = mask.sum(dim=1, keepdim=True).long() - t  # valid steps from t on
        m = left.clamp(min=1, max=self.n_steps)
        returns = th.zeros_like(rewards)
        for k in range(self.n_steps):
            r_k = rewards.gather(1, (t + k).clamp(max=length - 1).expand_as(rewards))
            returns = returns + (k < m) * self.gamma**k * r_k
        return returns, self.gamma**m, (t + m - 1).clamp(max=length - 1).expand_as(rewards)

    def train(self, gradient_steps: int, batch_size: int = 64) -> None:
        """``gradient_steps`` TD3 updates on windows sampled from the sequence buffer; the MLP
        heads run only at the trained (loss-mask) steps, the LSTMs once over each window."""
        self.policy.set_training_mode(True)
        self._update_learning_rate([self.actor.optimizer, self.critic.optimizer])
        actor_losses, critic_losses = [], []
        for _ in range(gradient_steps):
            self._n_updates += 1
            data = self.replay_buffer.sample(batch_size, env=self._vec_normalize_env)
            select = data.loss_mask.bool()
            if not select.any():  # only possible with tiny buffers: nothing to train on
                continue
            targets = self._critic_targets(data, select)
            actions = data.actions[select]
            memories = self.critic.memory(data.observations, data.prev_actions)
            critic_loss = sum(F.mse_loss(self.critic.q_value(i, m[select], actions), targets)
                              for i, m in enumerate(memories))
            assert isinstance(critic_loss, th.Tensor)
            critic_losses.append(critic_loss.item())
            self.critic.optimizer.zero_grad()
            critic_loss.backward()
            self.critic.optimizer.step()

            if self._n_updates % self.policy_delay == 0 and self._n_updates > self.critic_warmup:
                actor_memory, _ = self.actor.memory(data.observations, data.prev_actions)
                with th.no_grad():  # the actor's gradient does not need the critic's LSTM
                    memory = self.critic.memory(data.observations, data.prev_actions, n=1)[0]
                pre = self.actor.pre_activation(actor_memory[select])
                q = self.critic.q_value(0, memory[select], th.tanh(pre))   # actor.act's tanh
                actor_loss = -q.mean()
                if self.actor_bound_penalty > 0.0:
                    actor_loss = actor_loss + self.actor_bound_penalty * pre.pow(2).mean()
                actor_losses.append(actor_loss.item())
                self.actor.optimizer.zero_grad()
                actor_loss.backward()
                self.actor.optimizer.step()
                polyak_update(self.actor.parameters(), self.actor_target.parameters(), self.tau)
            if self._n_updates % self.policy_delay == 0:
                polyak_update(self.critic.parameters(), self.critic_target.parameters(), self.tau)

        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        if actor_losses:
            self.logger.record("train/actor_loss", float(np.mean(actor_losses)))
        self.logger.record("train/critic_loss", float(np.mean(critic_losses)))

    def learn(
        self: SelfRecurrentTD3,
        total_timesteps: int,
        callback: MaybeCallback = None,
        log_interval: int = 4,
        tb_log_name: str = "RecurrentTD3",
        reset_num_timesteps: bool = True,
        progress_bar: bool = False,
    ) -> SelfRecurrentTD3:
        return super().learn(total_timesteps=total_timesteps, callback=callback,
                             log_interval=log_interval, tb_log_name=tb_log_name,
                             reset_num_timesteps=reset_num_timesteps, progress_bar=progress_bar)

    def _excluded_save_params(self) -> list[str]:
        return [*super()._excluded_save_params(), "_rollout_state"]
