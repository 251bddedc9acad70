"""Recurrent actor and twin critics for ``RecurrentTD3`` (TD3-LSTM).

Every network reads the sequence ``x_t = [features(o_t), a_{t-1}]`` (the previous action is in
the scaled ``[-1, 1]`` space and zero at an episode start) with its own ``nn.LSTM``:

* actor: ``LSTM(x) -> [memory_t, features_t] -> MLP -> tanh``;
* critic ``i``: ``LSTM_i(x) -> [memory_t, features_t, a_t] -> MLP -> Q_i``.

Concatenating the current features to the memory is the "current feature extraction" branch of
LSTM-TD3 (Meng et al. 2021); ``current_features=False`` gives the plain LSTM networks. All networks
take whole windows ``(batch, length, ...)`` so that training runs one LSTM pass per network.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.policies import BaseModel, BasePolicy
from stable_baselines3.common.preprocessing import get_action_dim
from stable_baselines3.common.torch_layers import (
    BaseFeaturesExtractor,
    FlattenExtractor,
    create_mlp,
    get_actor_critic_arch,
)
from stable_baselines3.common.type_aliases import PyTorchObs, Schedule
from torch import nn

from agents.errors import PolicyFileError
from aoass_env.validators import integer, real

LSTMState = tuple[th.Tensor, th.Tensor]


def check_net_arch(net_arch: Any, name: str = "net_arch"
                   ) -> list[int] | dict[str, list[int]] | None:
    """``net_arch`` of a TD3 policy checked: None (the default), a list of layer widths
    (integers >= 1, possibly empty) or ``{pi: [...], qf: [...]}``; ``ValueError`` naming ``name``
    otherwise (SB3 asserts, torch fails deep inside, or a width 0 builds an empty layer)."""
    if net_arch is None:
        return None
    if isinstance(net_arch, dict):
        if set(net_arch) != {"pi", "qf"}:
            raise ValueError(f"{name} must be a list of layer widths or {{pi: [...], qf: [...]}}"
                             f", got the keys {sorted(map(str, net_arch))}")
        return {key: _widths(net_arch[key], f"{name}.{key}") for key in ("pi", "qf")}
    return _widths(net_arch, name)


def _widths(value: Any, name: str) -> list[int]:
    if not isinstance(value, (list, tuple)):
        raise ValueError(f"{name} must be a list of layer widths (integers >= 1), got "
                         f"{value!r}")
    return [integer(f"{name}[{i}]", width, "units", low=1) for i, width in enumerate(value)]


def _sequence_features(model: BaseModel, obs: th.Tensor) -> th.Tensor:
    """Features ``(B, L, F)`` of observations ``(B, L, *obs_shape)`` in one extractor call."""
    batch, length = obs.shape[:2]
    flat = obs.reshape(batch * length, *obs.shape[2:])
    return model.extract_features(flat, model.features_extractor).reshape(batch, length, -1)


class _NoPickledFile:
    """Refuses SB3's ``BaseModel.load``, which unpickles the file it is given
    (``torch.load(weights_only=False)``: a crafted file runs code)."""

    @classmethod
    def load(cls, path: Any, device: Any = "auto") -> Any:  # noqa: ARG003 (SB3's signature)
        raise PolicyFileError(
            f"{path}: {cls.__name__}.load would unpickle the file (SB3's policy files are "
            f"pickles, which can run code); load the model with RecurrentTD3.load, or weights "
            f"saved with torch.save(policy.state_dict(), path) by "
            f"policy.load_state_dict(torch.load(path, weights_only=True))")


class RecurrentActor(_NoPickledFile, BasePolicy):
    """Deterministic recurrent actor: LSTM over ``[features, previous action]``, MLP, tanh."""

    def __init__(
        self,
        observation_space: spaces.Space,
        action_space: spaces.Box,
        net_arch: list[int],
        features_extractor: BaseFeaturesExtractor,
        features_dim: int,
        lstm_hidden_size: int = 64,
        n_lstm_layers: int = 1,
        current_features: bool = True,
        activation_fn: type[nn.Module] = nn.ReLU,
        normalize_images: bool = True,
    ):
        super().__init__(observation_space, action_space, features_extractor=features_extractor,
                         normalize_images=normalize_images, squash_output=True)
        action_dim = get_action_dim(action_space)
        self.net_arch = net_arch
        self.features_dim = features_dim
        self.lstm_hidden_size = lstm_hidden_size
        self.n_lstm_layers = n_lstm_layers
        self.current_features = current_features
        self.activation_fn = activation_fn
        self.lstm = nn.LSTM(features_dim + action_dim, lstm_hidden_size, n_lstm_layers,
                            batch_first=True)
        head_dim = lstm_hidden_size + (features_dim if current_features else 0)
        self.mu = nn.Sequential(*create_mlp(head_dim, action_dim, net_arch, activation_fn,
                                            squash_output=True))

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        data.update(net_arch=self.net_arch, features_dim=self.features_dim,
                    lstm_hidden_size=self.lstm_hidden_size, n_lstm_layers=self.n_lstm_layers,
                    current_features=self.current_features, activation_fn=self.activation_fn,
                    features_extractor=self.features_extractor)
        return data

    def memory(
        self, obs: th.Tensor, prev_actions: th.Tensor, lstm_state: LSTMState | None = None
    ) -> tuple[th.Tensor, LSTMState]:
        """Inputs ``(B, L, D)`` of the action MLP (LSTM output, and the current features when
        ``current_features``) and the final LSTM state (zero initial state when None)."""
        features = _sequence_features(self, obs)
        memory, state = self.lstm(th.cat([features, prev_actions], dim=-1), lstm_state)
        return (th.cat([memory, features], dim=-1) if self.current_features else memory), state

    def act(self, memory: th.Tensor) -> th.Tensor:
        """Actions in ``[-1, 1]`` from ``memory`` outputs (any leading shape)."""
        return self.mu(memory)

    def pre_activation(self, memory: th.Tensor) -> th.Tensor:
        """The action MLP's output before its final tanh: :meth:`act` is its tanh."""
        return self.mu[:-1](memory)

    def forward(  # type: ignore[override]
        self, obs: th.Tensor, prev_actions: th.Tensor, lstm_state: LSTMState | None = None
    ) -> tuple[th.Tensor, LSTMState]:
        """Actions ``(B, L, action_dim)`` in ``[-1, 1]`` for observation sequences
        ``(B, L, *obs_shape)``, and the final LSTM state (zero initial state when None)."""
        memory, state = self.memory(obs, prev_actions, lstm_state)
        return self.mu(memory), state

    def _predict(self, observation: PyTorchObs, deterministic: bool = False) -> th.Tensor:
        # Stateless single step from a zero state; stateful prediction is the policy's predict.
        assert isinstance(observation, th.Tensor)
        n = observation.shape[0]
        prev = th.zeros(n, 1, get_action_dim(self.action_space), device=observation.device)
        return self(observation.unsqueeze(1), prev)[0][:, 0]


class RecurrentCritic(_NoPickledFile, BaseModel):
    """``n_critics`` recurrent Q-networks, each with its own LSTM over the same input sequence.

    One features extractor is shared by the Q-networks of this critic (as SB3's
    ``ContinuousCritic``); ``memory`` and ``q_value`` split the forward pass so that the actor
    loss can reuse a memory computed without gradients.
    """

    def __init__(
        self,
        observation_space: spaces.Space,
        action_space: spaces.Box,
        net_arch: list[int],
        features_extractor: BaseFeaturesExtractor,
        features_dim: int,
        lstm_hidden_size: int = 64,
        n_lstm_layers: int = 1,
        current_features: bool = True,
        activation_fn: type[nn.Module] = nn.ReLU,
        normalize_images: bool = True,
        n_critics: int = 2,
    ):
        super().__init__(observation_space, action_space, features_extractor=features_extractor,
                         normalize_images=normalize_images)
        action_dim = get_action_dim(action_space)
        self.n_critics = n_critics
        self.current_features = current_features
        self.lstms = nn.ModuleList(
            nn.LSTM(features_dim + action_dim, lstm_hidden_size, n_lstm_layers, batch_first=True)
            for _ in range(n_critics)
        )
        head_dim = lstm_hidden_size + (features_dim if current_features else 0) + action_dim
        self.q_networks = nn.ModuleList(
            nn.Sequential(*create_mlp(head_dim, 1, net_arch, activation_fn))
            for _ in range(n_critics)
        )

    def memory(self, obs: th.Tensor, prev_actions: th.Tensor, n: int | None = None
               ) -> list[th.Tensor]:
        """History summaries ``(B, L, D)`` of the first ``n`` critics (all when None)."""
        features = _sequence_features(self, obs)
        inputs = th.cat([features, prev_actions], dim=-1)
        out = []
        for lstm in list(self.lstms)[: n or self.n_critics]:
            memory, _ = lstm(inputs)
            out.append(th.cat([memory, features], dim=-1) if self.current_features else memory)
        return out

    def q_value(self, index: int, memory: th.Tensor, actions: th.Tensor) -> th.Tensor:
        """Q-values of critic ``index`` from ``memory`` outputs ``(..., D)`` and actions
        ``(..., action_dim)``, shape ``(...)``."""
        return self.q_networks[index](th.cat([memory, actions], dim=-1)).squeeze(-1)

    def forward(self, obs: th.Tensor, prev_actions: th.Tensor, actions: th.Tensor
                ) -> tuple[th.Tensor, ...]:
        """Q-values ``(B, L)`` of every critic for the actions taken along the sequences."""
        memories = self.memory(obs, prev_actions)
        return tuple(self.q_value(i, m, actions) for i, m in enumerate(memories))

    def q1_forward(self, obs: th.Tensor, prev_actions: th.Tensor, actions: th.Tensor
                   ) -> th.Tensor:
        """Q-values ``(B, L)`` of the first critic only."""
        return self.q_value(0, self.memory(obs, prev_actions, n=1)[0], actions)


class RecurrentTD3Policy(_NoPickledFile, BasePolicy):
    """Recurrent actor, twin recurrent critics and their target copies for ``RecurrentTD3``.

    :param observation_space: observation space (any space SB3's extractors flatten; not Dict)
    :param action_space: Box action space
    :param lr_schedule: learning-rate schedule
    :param net_arch: MLP after the LSTM: a list (actor and critics) or ``dict(pi=..., qf=...)``;
        default ``[64, 64]``
    :param activation_fn: MLP activation
    :param features_extractor_class: features extractor (``FlattenExtractor`` by default)
    :param features_extractor_kwargs: its keyword arguments
    :param normalize_images: divide image observations by 255
    :param optimizer_class: optimizer (Adam by default)
    :param optimizer_kwargs: optimizer keyword arguments besides the learning rate
    :param n_critics: number of critics (2 for clipped double-Q)
    :param lstm_hidden_size: LSTM hidden units of every network
    :param n_lstm_layers: stacked LSTM layers of every network
    :param current_features: feed the current step's features to the MLP beside the memory
    :param actor_final_init: when set, the actor's output layer starts with weights and biases
        drawn from ``U(-actor_final_init, actor_final_init)`` (DDPG's 3e-3, Lillicrap et al.
        2016), so the first policy outputs about 0: for a residual action such as AOASS's, the
        untrained agent then behaves like the nominal controller
    """

    actor: RecurrentActor
    actor_target: RecurrentActor
    critic: RecurrentCritic
    critic_target: RecurrentCritic

    def __init__(
        self,
        observation_space: spaces.Space,
        action_space: spaces.Box,
        lr_schedule: Schedule,
        net_arch: list[int] | dict[str, list[int]] | None = None,
        activation_fn: type[nn.Module] = nn.ReLU,
        features_extractor_class: type[BaseFeaturesExtractor] = FlattenExtractor,
        features_extractor_kwargs: dict[str, Any] | None = None,
        normalize_images: bool = True,
        optimizer_class: type[th.optim.Optimizer] = th.optim.Adam,
        optimizer_kwargs: dict[str, Any] | None = None,
        n_critics: int = 2,
        lstm_hidden_size: int = 64,
        n_lstm_layers: int = 1,
        current_features: bool = True,
        actor_final_init: float | None = None,
    ):
        if isinstance(observation_space, spaces.Dict):
            raise ValueError("RecurrentTD3Policy does not support Dict observation spaces")
        net_arch = check_net_arch(net_arch)
        for flag, value in (("current_features", current_features),
                            ("normalize_images", normalize_images)):
            if not isinstance(value, (bool, np.bool_)):
                raise ValueError(f"{flag}={value!r} must be True or False")
        lstm_hidden_size = integer("lstm_hidden_size", lstm_hidden_size, "units", low=1)
        n_lstm_layers = integer("n_lstm_layers", n_lstm_layers, "layers", low=1)
        n_critics = integer("n_critics", n_critics, "critics", low=1)
        if actor_final_init is not None:
            actor_final_init = real("actor_final_init", actor_final_init, low=0.0,
                                    doc="or None")
        super().__init__(observation_space, action_space, features_extractor_class,
                         features_extractor_kwargs, optimizer_class=optimizer_class,
                         optimizer_kwargs=optimizer_kwargs, squash_output=True,
                         normalize_images=normalize_images)
        if net_arch is None:
            net_arch = [64, 64]
        actor_arch, critic_arch = get_actor_critic_arch(net_arch)
        self.net_arch = net_arch
        self.activation_fn = activation_fn
        self.n_critics = n_critics
        self.lstm_hidden_size = lstm_hidden_size
        self.n_lstm_layers = n_lstm_layers
        self.current_features = current_features
        self.actor_final_init = actor_final_init
        common = dict(observation_space=observation_space, action_space=action_space,
                      lstm_hidden_size=lstm_hidden_size, n_lstm_layers=n_lstm_layers,
                      current_features=current_features, activation_fn=activation_fn,
                      normalize_images=normalize_images)
        self.actor_kwargs = {**common, "net_arch": actor_arch}
        self.critic_kwargs = {**common, "net_arch": critic_arch, "n_critics": n_critics}
        self._build(lr_schedule)

    def _build(self, lr_schedule: Schedule) -> None:
        self.actor = self.make_actor()
        if self.actor_final_init is not None:
            last = [m for m in self.actor.mu if isinstance(m, nn.Linear)][-1]
            nn.init.uniform_(last.weight, -self.actor_final_init, self.actor_final_init)
            nn.init.uniform_(last.bias, -self.actor_final_init, self.actor_final_init)
        self.actor_target = self.make_actor()
        self.actor_target.load_state_dict(self.actor.state_dict())
        self.actor.optimizer = self.optimizer_class(self.actor.parameters(), lr=lr_schedule(1),
                                                    **self.optimizer_kwargs)
        self.critic = self.make_critic()
        self.critic_target = self.make_critic()
        self.critic_target.load_state_dict(self.critic.state_dict())
        self.critic.optimizer = self.optimizer_class(self.critic.parameters(), lr=lr_schedule(1),
                                                     **self.optimizer_kwargs)
        self.actor_target.set_training_mode(False)
        self.critic_target.set_training_mode(False)

    def make_actor(self) -> RecurrentActor:
        """A new actor with its own features extractor."""
        kwargs = self._update_features_extractor(self.actor_kwargs, None)
        return RecurrentActor(**kwargs).to(self.device)

    def make_critic(self) -> RecurrentCritic:
        """A new set of critics with its own features extractor."""
        kwargs = self._update_features_extractor(self.critic_kwargs, None)
        return RecurrentCritic(**kwargs).to(self.device)

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        data.update(
            net_arch=self.net_arch, activation_fn=self.activation_fn, n_critics=self.n_critics,
            lr_schedule=self._dummy_schedule, optimizer_class=self.optimizer_class,
            optimizer_kwargs=self.optimizer_kwargs,
            features_extractor_class=self.features_extractor_class,
            features_extractor_kwargs=self.features_extractor_kwargs,
            lstm_hidden_size=self.lstm_hidden_size, n_lstm_layers=self.n_lstm_layers,
            current_features=self.current_features, actor_final_init=self.actor_final_init,
        )
        return data

    @property
    def lstm_state_shape(self) -> tuple[int, int]:
        """``(n_lstm_layers, lstm_hidden_size)``: the state of one env is (n_layers, 1, hidden)."""
        return self.n_lstm_layers, self.lstm_hidden_size

    def initial_state(self, n_envs: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Zero rollout state ``(h, c, prev_action)`` for ``n_envs`` envs."""
        h = np.zeros((self.n_lstm_layers, n_envs, self.lstm_hidden_size), dtype=np.float32)
        prev = np.zeros((n_envs, get_action_dim(self.action_space)), dtype=np.float32)
        return h, h.copy(), prev

    def forward(self, observation: PyTorchObs, deterministic: bool = False) -> th.Tensor:
        return self._predict(observation, deterministic=deterministic)

    def _predict(self, observation: PyTorchObs, deterministic: bool = False) -> th.Tensor:
        return self.actor._predict(observation, deterministic)

    def predict(  # type: ignore[override]
        self,
        observation: np.ndarray | dict[str, np.ndarray],
        state: tuple[np.ndarray, ...] | None = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
        """One recurrent step of the actor, like sb3-contrib's ``RecurrentPPO.predict``.

        :param observation: one observation or a batch ``(n_envs, *obs_shape)``
        :param state: ``(h, c, prev_action)`` from the previous call; None for a fresh start.
            ``h``/``c`` are ``(n_lstm_layers, n_envs, lstm_hidden_size)``, ``prev_action`` is
            ``(n_envs, action_dim)`` in ``[-1, 1]``
        :param episode_start: ``(n_envs,)`` flags: the state of these envs is zeroed first
        :param deterministic: ignored (the TD3 actor is deterministic)
        :return: actions in the env's action space and the next state, whose ``prev_action``
            is the returned action (scaled to ``[-1, 1]``)
        """
        self.set_training_mode(False)
        obs_tensor, vectorized_env = self.obs_to_tensor(observation)
        assert isinstance(obs_tensor, th.Tensor)
        n_envs = obs_tensor.shape[0]
        if state is not None and (not isinstance(state, (tuple, list)) or len(state) != 3):
            got = f" of length {len(state)}" if isinstance(state, (tuple, list)) else ""
            raise ValueError(f"state must be the (h, c, prev_action) that predict returned, got "
                             f"a {type(state).__name__}{got}")
        h, c, prev = self.initial_state(n_envs) if state is None else state
        h, c = np.array(h, dtype=np.float32), np.array(c, dtype=np.float32)
        prev = np.array(prev, dtype=np.float32)
        expected = (self.n_lstm_layers, n_envs, self.lstm_hidden_size)
        if h.shape != expected or c.shape != expected:
            raise ValueError(f"state h and c must have shape {expected}, got {h.shape}, {c.shape}")
        action_dim = get_action_dim(self.action_space)
        if prev.shape != (n_envs, action_dim):
            raise ValueError(f"state prev_action must have shape {(n_envs, action_dim)}, got "
                             f"{prev.shape}")
        if episode_start is not None:
            start = np.asarray(episode_start)
            if start.shape != (n_envs,) and not (n_envs == 1 and start.shape == ()):
                raise ValueError(f"episode_start must be {n_envs} flag(s), shape ({n_envs},), got "
                                 f"shape {start.shape}")
            start = start.astype(bool).reshape(n_envs)
            h[:, start], c[:, start], prev[start] = 0.0, 0.0, 0.0
        with th.no_grad():
            lstm_state = (th.as_tensor(h, device=self.device), th.as_tensor(c, device=self.device))
            prev_t = th.as_tensor(prev, device=self.device).unsqueeze(1)
            scaled, (h_t, c_t) = self.actor(obs_tensor.unsqueeze(1), prev_t, lstm_state)
        scaled_np = scaled[:, 0].cpu().numpy()
        actions = self.unscale_action(scaled_np).reshape((-1, *self.action_space.shape))
        if not vectorized_env:
            actions = actions.squeeze(axis=0)
        return actions, (h_t.cpu().numpy(), c_t.cpu().numpy(), scaled_np.copy())

    def set_training_mode(self, mode: bool) -> None:
        self.actor.set_training_mode(mode)
        self.critic.set_training_mode(mode)
        self.training = mode


MlpLstmPolicy = RecurrentTD3Policy
