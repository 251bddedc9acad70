"""RecurrentTD3: recurrent predict, targets, learn, save/load, callbacks, argument checks."""

from __future__ import annotations

import functools

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from gymnasium import spaces
from hypothesis import given, settings
from hypothesis import strategies as st
from stable_baselines3.common.callbacks import EvalCallback
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.noise import NormalActionNoise, OrnsteinUhlenbeckActionNoise

from agents import RecurrentTD3, RecurrentTD3Policy, SequenceReplayBuffer
from agents.checkpoints import PolicyFileError

EP_LEN = 20
TINY = dict(batch_size=8, burn_in=2, train_length=4, buffer_size=2_000, device="cpu",
            policy_kwargs=dict(lstm_hidden_size=16, net_arch=[16]))


def _record(**hp):
    """A run record of a model built by :func:`_model` (load rebuilds the model from one)."""
    tiny = {k: v for k, v in TINY.items() if k != "device"}
    return {"algo": "td3-lstm", "hyperparameters": {**tiny, **hp}}


def _env(n_envs: int = 1, seed: int = 0):
    return make_vec_env("Pendulum-v1", n_envs=n_envs, seed=seed,
                        env_kwargs=dict(max_episode_steps=EP_LEN))


def _model(n_envs: int = 1, **kwargs) -> RecurrentTD3:
    return RecurrentTD3("MlpLstmPolicy", _env(n_envs), seed=0, **{**TINY, **kwargs})


def _rollout(model: RecurrentTD3, obs_seq: np.ndarray, starts: np.ndarray | None = None
             ) -> list[np.ndarray]:
    """Actions of ``predict`` along ``obs_seq`` (T, n_envs, obs_dim), carrying the state."""
    state, actions = None, []
    for t, obs in enumerate(obs_seq):
        start = None if starts is None else starts[t]
        action, state = model.predict(obs, state=state, episode_start=start, deterministic=True)
        actions.append(action)
    return actions


@pytest.mark.parametrize("n_envs", [1, 3])
def test_predict_shapes_and_determinism(n_envs: int) -> None:
    model = _model(n_envs)
    obs = model.get_env().reset()
    action, (h, c, prev) = model.predict(obs)
    assert action.shape == (n_envs, 1)
    assert h.shape == c.shape == (1, n_envs, 16)
    assert prev.shape == (n_envs, 1)
    assert np.all(np.abs(action) <= 2.0)
    again, state2 = model.predict(obs, state=(h, c, prev))
    again2, _ = model.predict(obs, state=(h, c, prev), deterministic=True)
    np.testing.assert_array_equal(again, again2)
    assert not np.allclose(h, state2[0])  # the state moves on
    single, (h1, _, _) = model.predict(obs[0])
    assert single.shape == (1,) and h1.shape == (1, 1, 16)
    np.testing.assert_allclose(single, action[0], rtol=1e-6)


def test_actor_final_init_starts_near_the_zero_action(tmp_path) -> None:
    obs = np.random.default_rng(0).uniform(-1, 1, (64, 3)).astype(np.float32)
    default = _model(1)
    small = _model(1, policy_kwargs=dict(**TINY["policy_kwargs"], actor_final_init=3e-3))
    a_default = default.predict(obs, state=default.policy.initial_state(64))[0]
    a_small = small.predict(obs, state=small.policy.initial_state(64))[0]
    # Pendulum's actions span [-2, 2]: 0 is the middle of the range
    assert np.abs(a_small).max() < 0.05 < np.abs(a_default).max()
    for name in ("actor", "actor_target"):
        np.testing.assert_array_equal(
            getattr(small.policy, name).mu[-2].weight.detach().numpy(),
            small.policy.actor.mu[-2].weight.detach().numpy())
    small.save(tmp_path / "m.zip")
    record = _record(policy_kwargs=dict(**TINY["policy_kwargs"], actor_final_init=3e-3))
    assert RecurrentTD3.load(tmp_path / "m.zip", env=_env(1),
                             record=record).policy.actor_final_init == 3e-3


def test_episode_start_resets_the_state() -> None:
    model = _model(3)
    rng = np.random.default_rng(0)
    obs_seq = rng.uniform(-1, 1, (6, 3, 3)).astype(np.float32)
    state = None
    for obs in obs_seq[:5]:
        _, state = model.predict(obs, state=state)
    fresh, fresh_state = model.predict(obs_seq[5])
    cont, cont_state = model.predict(obs_seq[5], state=state)
    mixed, mixed_state = model.predict(obs_seq[5], state=state,
                                       episode_start=np.array([True, False, True]))
    assert not np.allclose(fresh, cont)  # the memory matters
    np.testing.assert_allclose(mixed[[0, 2]], fresh[[0, 2]], rtol=1e-6)
    np.testing.assert_allclose(mixed[1], cont[1], rtol=1e-6)
    for a, b, c in zip(mixed_state, fresh_state, cont_state, strict=True):
        np.testing.assert_allclose(a[..., [0, 2], :] if a.ndim == 3 else a[[0, 2]],
                                   b[..., [0, 2], :] if b.ndim == 3 else b[[0, 2]], rtol=1e-6)
        np.testing.assert_allclose(a[..., 1, :] if a.ndim == 3 else a[1],
                                   c[..., 1, :] if c.ndim == 3 else c[1], rtol=1e-6)


def test_evaluate_policy_runs() -> None:
    model = _model(1)
    mean, std = evaluate_policy(model, _env(2, seed=1), n_eval_episodes=2)
    assert np.isfinite(mean) and np.isfinite(std)


def test_rollout_state_matches_the_stored_history() -> None:
    """The LSTM state carried during rollouts (random warm-up and noisy actions) equals the
    actor run over the stored episode, and it is zeroed at episode ends."""
    from stable_baselines3.common.noise import NormalActionNoise

    model = _model(2, learning_starts=15, gradient_steps=0,  # no training: the actor is fixed
                   action_noise=NormalActionNoise(np.zeros(1), 0.3 * np.ones(1)))
    model.learn(2 * EP_LEN)  # one full episode per env
    assert all(np.all(x == 0) for x in model._rollout_state)  # both episodes just ended
    model.learn(2 * 7, reset_num_timesteps=False)  # 7 steps per env into the next episode
    buf = model.replay_buffer
    rows = np.arange(EP_LEN, EP_LEN + 7)
    assert buf.episode_starts[rows[0]].all() and not buf.episode_starts[rows[1:]].any()
    h, c, prev = model._rollout_state
    for env in range(2):
        obs = th.as_tensor(buf.observations[rows, env])[None]
        prev_actions = th.as_tensor(buf.prev_actions[rows, env])[None]
        with th.no_grad():
            _, (h_ref, c_ref) = model.actor(obs, prev_actions)
        np.testing.assert_allclose(h[:, env], h_ref[:, 0].numpy(), atol=1e-5)
        np.testing.assert_allclose(c[:, env], c_ref[:, 0].numpy(), atol=1e-5)
        np.testing.assert_array_equal(prev[env], buf.actions[rows[-1], env])
    assert buf.dones[:EP_LEN].sum() == 0  # Pendulum only truncates: always bootstrap
    assert buf.timeouts[EP_LEN - 1].all()


def test_timeout_bootstraps_and_terminal_does_not() -> None:
    model = _model(1, gamma=0.9, target_policy_noise=0.0)
    buf = model.replay_buffer
    rng = np.random.default_rng(1)
    obs = rng.uniform(-1, 1, (7, 3)).astype(np.float32)
    acts = rng.uniform(-1, 1, (6, 1)).astype(np.float32)
    ends = {2: {"TimeLimit.truncated": True}, 5: {}}  # episode 0 times out, episode 1 terminates
    for t in range(6):
        next_obs = obs[t + 1]
        buf.add(obs[t][None], next_obs[None], acts[t][None], np.array([t + 1.0]),
                np.array([t in ends]), [ends.get(t, {})])
    data = buf._get_samples(np.array([2, 5]), env_indices=np.array([0, 0]))
    targets = model._critic_targets(data)
    # Terminal: no bootstrap.
    assert targets[1, 2].item() == pytest.approx(6.0)
    # Timeout: bootstrap from the target networks' value of the history after the last step.
    seq_obs = th.as_tensor(obs[None, [0, 1, 2, 3]])
    seq_prev = th.as_tensor(np.concatenate([np.zeros((1, 1)), acts[:3]])[None].astype(np.float32))
    with th.no_grad():
        a_next = model.actor_target(seq_obs, seq_prev)[0][:, -1:]
        mem = model.critic_target.memory(seq_obs, seq_prev)
        q = min(model.critic_target.q_value(i, m[:, -1:], a_next).item()
                for i, m in enumerate(mem))
    assert targets[0, 2].item() == pytest.approx(3.0 + 0.9 * q, rel=1e-5, abs=1e-5)
    # Inside an episode every step bootstraps.
    assert targets[1, 0].item() != pytest.approx(4.0)


def _n_step_reference(rewards, dones, valid, next_q, gamma, n):
    """G_t of one window by the definition, step by step."""
    out = []
    for t in range(valid):
        g, k = 0.0, 0
        while k < n and t + k < valid:
            g += gamma**k * rewards[t + k]
            k += 1
        out.append(g + gamma**k * (1.0 - dones[t + k - 1]) * next_q[t + k - 1])
    return out


def _targets(model: RecurrentTD3, rewards, dones, mask, next_q) -> th.Tensor:
    """The targets of ``model._n_step_parts`` for given (B, L) values ``Q'_t``."""
    returns, discount, last = model._n_step_parts(rewards, mask)
    return returns + discount * (1.0 - dones.gather(1, last)) * next_q.gather(1, last)


def test_n_step_returns_by_hand() -> None:
    model = _model(1, gamma=0.5, n_steps=3)
    rewards = th.tensor([[1.0, 2.0, 3.0, 4.0, 5.0]])
    next_q = th.tensor([[10.0, 20.0, 30.0, 40.0, 50.0]])
    mask, no_done = th.ones(1, 5), th.zeros(1, 5)
    g = _targets(model, rewards, no_done, mask, next_q)[0]
    assert g[0].item() == pytest.approx(1 + 0.5 * 2 + 0.25 * 3 + 0.125 * 30)
    assert g[3].item() == pytest.approx(4 + 0.5 * 5 + 0.25 * 50)  # 2 steps left in the window
    assert g[4].item() == pytest.approx(5 + 0.5 * 50)
    # A terminal last valid step (index 3; index 4 is padding): no bootstrap past it.
    done, short = th.tensor([[0.0, 0.0, 0.0, 1.0, 0.0]]), th.tensor([[1.0, 1, 1, 1, 0]])
    g = _targets(model, rewards * short, done, short, next_q)[0]
    assert g[2].item() == pytest.approx(3 + 0.5 * 4)
    assert g[1].item() == pytest.approx(2 + 0.5 * 3 + 0.25 * 4)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 6), st.integers(1, 8), st.booleans(), st.floats(0.0, 1.0),
       st.integers(0, 2**31 - 1))
def test_n_step_returns_match_the_definition(n: int, valid: int, terminal: bool, gamma: float,
                                             seed: int) -> None:
    length = 8
    rng = np.random.default_rng(seed)
    rewards = np.zeros(length, np.float32)
    rewards[:valid] = rng.normal(size=valid)
    next_q = rng.normal(size=length).astype(np.float32)
    dones = np.zeros(length, np.float32)
    dones[valid - 1] = float(terminal)
    mask = (np.arange(length) < valid).astype(np.float32)
    model = _shared_model()
    model.gamma, model.n_steps = gamma, n
    got = _targets(model, *(th.as_tensor(x)[None] for x in (rewards, dones, mask, next_q)))
    want = _n_step_reference(rewards, dones, valid, next_q, gamma, n)
    np.testing.assert_allclose(got[0, :valid].numpy(), want, rtol=1e-4, atol=1e-4)


@functools.cache
def _shared_model() -> RecurrentTD3:
    return _model(1)


def test_one_step_targets_do_not_depend_on_the_window_end() -> None:
    """n_steps=1 is TD3's target at every step; n_steps>1 differs inside the window."""
    one, many = _model(1, target_policy_noise=0.0), _model(1, target_policy_noise=0.0, n_steps=3)
    one.learn(60)
    data = one.replay_buffer.sample(4)
    many.policy.load_state_dict(one.policy.state_dict())
    t1, t3 = one._critic_targets(data), many._critic_targets(data)
    with th.no_grad():
        obs = th.cat([data.observations[:, :1], data.next_observations], dim=1)
        prev = th.cat([data.prev_actions[:, :1], data.actions], dim=1)
        a_next = one.actor_target(obs, prev)[0][:, 1:]
        q = th.stack([one.critic_target.q_value(i, m[:, 1:], a_next)
                      for i, m in enumerate(one.critic_target.memory(obs, prev))]).min(0).values
    expected = data.rewards + one.gamma * (1 - data.dones) * q
    valid = data.mask.bool()
    th.testing.assert_close(t1[valid], expected[valid])
    assert not th.allclose(t1[valid], t3[valid])
    # The n-step targets bootstrap from the same Q' (heads evaluated only where needed) ...
    th.testing.assert_close(t3[valid], _targets(many, data.rewards, data.dones, data.mask,
                                                q)[valid])
    # ... and a selection gives the same values as the full window.
    select = data.loss_mask.bool()
    th.testing.assert_close(many._critic_targets(data, select), t3[select])
    # The last valid step of each window has no step left: both agree there.
    last = data.mask.sum(1).long() - 1
    rows = th.arange(4)
    th.testing.assert_close(t1[rows, last], t3[rows, last])


def test_critic_warmup_holds_the_actor() -> None:
    model = _model(1, learning_starts=20, critic_warmup=10_000)
    before = {k: v.clone() for k, v in model.policy.state_dict().items()}
    model.learn(80)
    after = model.policy.state_dict()

    def changed(prefix: str) -> bool:
        return any(not th.equal(before[k], after[k]) for k in before if k.startswith(prefix))

    assert model._n_updates > 2
    assert not changed("actor.") and not changed("actor_target.")
    assert changed("critic.") and changed("critic_target.")
    model.critic_warmup = 0
    model.learn(20, reset_num_timesteps=False)
    assert any(not th.equal(before[k], model.policy.state_dict()[k])
               for k in before if k.startswith("actor."))


def test_actor_bound_penalty_pulls_a_saturated_actor_off_its_bounds() -> None:
    """An actor pinned at +1 (its last layer's bias at 4) stays pinned under TD3's loss, whose
    gradient tanh all but cancels; with the penalty its pre-tanh outputs come back toward 0.
    The actions are the tanh of ``pre_activation``."""
    obs = th.as_tensor(np.random.default_rng(0).normal(size=(16, 6, 3)), dtype=th.float32)
    prev = th.zeros(16, 6, 1)

    def trained(penalty: float) -> float:
        model = _model(1, learning_starts=20, actor_bound_penalty=penalty, learning_rate=0.01)
        for actor in (model.actor, model.actor_target):
            actor.mu[-2].bias.data.fill_(4.0)
        model.learn(300)
        with th.no_grad():
            memory, _ = model.actor.memory(obs, prev)
            pre = model.actor.pre_activation(memory)
            th.testing.assert_close(th.tanh(pre), model.actor.act(memory), rtol=0, atol=0)
        return float(pre.abs().mean())

    plain, penalised = trained(0.0), trained(1.0)
    assert plain > 3.5 and penalised < 1.0


@pytest.mark.parametrize("n_envs", [1, 2])
def test_learn_changes_weights(n_envs: int) -> None:
    model = _model(n_envs, learning_starts=100)
    before = {k: v.clone() for k, v in model.policy.state_dict().items()}
    model.learn(300)
    after = model.policy.state_dict()
    for prefix in ("actor.lstm", "actor.mu", "critic.lstms", "critic.q_networks",
                   "actor_target.lstm", "critic_target.lstms"):
        keys = [k for k in before if k.startswith(prefix)]
        assert keys and any(not th.equal(before[k], after[k]) for k in keys), prefix
    assert model._n_updates > 0
    assert model.replay_buffer.size() * n_envs == 300


def test_save_load_round_trip(tmp_path) -> None:
    model = _model(2, learning_starts=50)
    model.learn(100)
    model.save(tmp_path / "model.zip")
    loaded = RecurrentTD3.load(tmp_path / "model.zip", env=_env(2), device="cpu",
                               record=_record(learning_starts=50))
    assert loaded._rollout_state is None
    assert (loaded.burn_in, loaded.train_length) == (2, 4)
    assert isinstance(loaded.policy, RecurrentTD3Policy)
    rng = np.random.default_rng(2)
    obs_seq = rng.uniform(-1, 1, (8, 2, 3)).astype(np.float32)
    starts = np.zeros((8, 2), bool)
    starts[[0, 5], 0] = True
    for a, b in zip(_rollout(model, obs_seq, starts), _rollout(loaded, obs_seq, starts),
                    strict=True):
        np.testing.assert_array_equal(a, b)
    loaded.set_env(_env(2))
    loaded.learn(20, reset_num_timesteps=False)  # training continues after loading


def test_load_refuses_an_env_of_other_bounds_and_applies_keywords_before_setup(tmp_path
                                                                              ) -> None:
    model = _model(1, learning_starts=20)
    model.learn(30)
    model.save(tmp_path / "model.zip")
    record = _record(learning_starts=20)

    def rescaled():
        return gym.wrappers.RescaleAction(gym.make("Pendulum-v1", max_episode_steps=EP_LEN),
                                          -0.1, 0.1)

    # the same shapes, other bounds: it used to load and act at 1/20 of its trained actions
    with pytest.raises(PolicyFileError, match=r"model.zip: action_space: saved with low \[-2\.\]"
                                              r", the given env's is Box\(-0\.1, 0\.1"):
        RecurrentTD3.load(tmp_path / "model.zip", env=make_vec_env(rescaled, n_envs=1),
                          record=record)
    # constructor keywords reach the set-up (they used to be set after it: the optimizers
    # kept the old rate, the buffer the old burn-in)
    loaded = RecurrentTD3.load(tmp_path / "model.zip", env=_env(1), record=record,
                               learning_rate=1e-5, burn_in=0)
    loaded.learn(20, reset_num_timesteps=False)
    assert loaded.actor.optimizer.param_groups[0]["lr"] == pytest.approx(1e-5)
    assert loaded.critic.optimizer.param_groups[0]["lr"] == pytest.approx(1e-5)
    assert loaded.burn_in == loaded.replay_buffer.burn_in == 0
    with pytest.raises(PolicyFileError, match=r"no_such/last.zip: no such model file"):
        RecurrentTD3.load(tmp_path / "no_such" / "last.zip", env=_env(1), record=record)


def test_load_with_an_env_keeps_the_records_exploration_noise(tmp_path) -> None:
    model = _model(1, learning_starts=20)
    model.learn(30)
    model.save(tmp_path / "model.zip")
    record = _record(learning_starts=20, action_noise={"kind": "normal", "sigma": 0.3})
    # it used to come back None: a load -> learn went on without exploration, silently
    loaded = RecurrentTD3.load(tmp_path / "model.zip", env=_env(1), record=record)
    assert isinstance(loaded.action_noise, NormalActionNoise)
    np.testing.assert_array_equal(loaded.action_noise._sigma, [0.3])
    mine = OrnsteinUhlenbeckActionNoise(np.zeros(1), np.ones(1))
    assert RecurrentTD3.load(tmp_path / "model.zip", env=_env(1), record=record,
                             action_noise=mine).action_noise is mine


def test_a_replay_buffer_round_trips_under_the_path_it_was_saved_with(tmp_path) -> None:
    model = _model(1, learning_starts=20)
    model.learn(30)
    model.save_replay_buffer(tmp_path / "buffer")          # written as buffer.npz
    observations = model.replay_buffer.observations.copy()
    model.replay_buffer.observations[:] = 0.0
    model.load_replay_buffer(tmp_path / "buffer")          # used to look for "buffer" alone
    np.testing.assert_array_equal(model.replay_buffer.observations, observations)


class _MakesAFile:
    def __init__(self, path) -> None:
        self.path = str(path)

    def __reduce__(self):
        return (open, (self.path, "w"))


@pytest.mark.parametrize("cls", ["RecurrentTD3Policy", "RecurrentActor", "RecurrentCritic"])
def test_policy_files_are_not_unpickled(tmp_path, cls) -> None:
    from agents import policies
    marker = tmp_path / "code_ran"
    th.save({"data": _MakesAFile(marker), "state_dict": {}}, tmp_path / "policy.pth")
    with pytest.raises(PolicyFileError, match=rf"policy.pth: {cls}.load would unpickle the "
                                              rf"file"):
        getattr(policies, cls).load(tmp_path / "policy.pth")
    assert not marker.exists()


@pytest.mark.parametrize("state, start, message", [
    ("hc", None, r"state must be the \(h, c, prev_action\) that predict returned, got a tuple "
                 r"of length 2"),
    ("prev12", None, r"state prev_action must have shape \(2, 1\), got \(1, 2\)"),
    (None, [True, False, True], r"episode_start must be 2 flag\(s\), shape \(2,\), got "
                                r"shape \(3,\)"),
])
def test_predict_names_a_state_or_episode_start_of_the_wrong_shape(state, start,
                                                                   message) -> None:
    model = _model(1)
    obs = np.zeros((2, 3), np.float32)
    h, c, _ = model.policy.initial_state(2)
    state = {"hc": (h, c), "prev12": (h, c, np.zeros((1, 2), np.float32)), None: None}[state]
    with pytest.raises(ValueError, match=message):
        model.predict(obs, state=state, episode_start=start)


def test_eval_callback_works(tmp_path) -> None:
    model = _model(1, learning_starts=20)
    callback = EvalCallback(_env(1, seed=3), n_eval_episodes=1, eval_freq=30,
                            log_path=str(tmp_path), verbose=0)
    model.learn(60, callback=callback)
    assert callback.n_calls == 60 and np.isfinite(callback.last_mean_reward)
    assert len(callback.evaluations_results) == 2


@pytest.mark.parametrize(("kwargs", "name"), [
    (dict(burn_in=-1), "burn_in"),
    (dict(burn_in=1.5), "burn_in"),
    (dict(train_length=0), "train_length"),
    (dict(batch_size=0), "batch_size"),
    (dict(policy_delay=0), "policy_delay"),
    (dict(n_steps=0), "n_steps"),
    (dict(critic_warmup=-1), "critic_warmup"),
    (dict(critic_warmup=2.5), "critic_warmup"),
    (dict(actor_bound_penalty=-0.1), "actor_bound_penalty"),
    (dict(actor_bound_penalty="big"), "actor_bound_penalty"),
    (dict(optimize_memory_usage=True), "optimize_memory_usage"),
    # these five used to be taken as given: a negative clip made the smoothing noise constant
    (dict(tau=2.0), r"tau=2.0 must be a number in \(0.0, 1.0\]"),
    (dict(tau=0.0), "tau"),
    (dict(gamma=1.5), r"gamma=1.5 must be a number in \(0.0, 1.0\]"),
    (dict(target_noise_clip=-0.5), r"target_noise_clip=-0.5 must be a number in \[0.0, inf\)"),
    (dict(target_policy_noise=-0.2), "target_policy_noise"),
    (dict(learning_starts=-5), r"learning_starts=-5 must be an integer in \[0, inf\) steps"),
    (dict(replay_buffer_kwargs=dict(burn_in=3)), "burn_in"),
    (dict(policy_kwargs=dict(lstm_hidden_size=0)), "lstm_hidden_size"),
    (dict(policy_kwargs=dict(actor_final_init=-1.0)), "actor_final_init"),
    (dict(policy_kwargs=dict(actor_final_init="small")), "actor_final_init"),
    (dict(policy_kwargs=dict(net_arch=5)), r"net_arch must be a list of layer widths"),
    (dict(policy_kwargs=dict(net_arch=[8, 0])), r"net_arch\[1\]=0 must be an integer"),
    (dict(policy_kwargs=dict(net_arch=dict(pi=[8]))), r"net_arch must be .* got the keys \['pi'\]"),
    (dict(policy_kwargs=dict(current_features="no")), "current_features='no' must be True or"),
    (dict(policy_kwargs=dict(normalize_images=3)), "normalize_images=3 must be True or False"),
])
def test_bad_constructor_values_name_the_parameter(kwargs: dict, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        RecurrentTD3("MlpLstmPolicy", "Pendulum-v1", device="cpu", **kwargs)


def test_rejects_other_buffers_and_dict_observations() -> None:
    from stable_baselines3.common.buffers import ReplayBuffer

    with pytest.raises(ValueError, match="replay_buffer_class"):
        RecurrentTD3("MlpLstmPolicy", "Pendulum-v1", replay_buffer_class=ReplayBuffer)

    class DictObs(gym.ObservationWrapper):
        def __init__(self, env: gym.Env):
            super().__init__(env)
            self.observation_space = spaces.Dict({"x": env.observation_space})

        def observation(self, observation):
            return {"x": observation}

    with pytest.raises(ValueError, match="Dict"):
        RecurrentTD3("MlpLstmPolicy", DictObs(gym.make("Pendulum-v1")), device="cpu")
    assert SequenceReplayBuffer is RecurrentTD3("MlpLstmPolicy", "Pendulum-v1",
                                                **TINY).replay_buffer_class


def test_image_shaped_box_observations_are_flattened() -> None:
    class Grid(gym.ObservationWrapper):
        def __init__(self, env: gym.Env):
            super().__init__(env)
            self.observation_space = spaces.Box(-8.0, 8.0, (2, 3), np.float32)

        def observation(self, observation):
            return np.stack([observation, -observation]).astype(np.float32)

    env = Grid(gym.make("Pendulum-v1", max_episode_steps=EP_LEN))
    model = RecurrentTD3("MlpLstmPolicy", env, seed=0, learning_starts=20, **TINY)
    model.learn(40)
    action, _ = model.predict(env.observation_space.sample())
    assert action.shape == (1,)
