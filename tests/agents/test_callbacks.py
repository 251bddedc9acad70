"""agents.callbacks: evaluations.npz read without unpickling, and checked; the record written
before the best model it names."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from agents import callbacks
from agents.callbacks import Evaluations, RunEvalCallback, SaveBestAtomically, read_evaluations


def test_reads_what_sb3_writes(tmp_path: Path):
    path = tmp_path / "evaluations.npz"
    np.savez(path, timesteps=[100, 200], results=[[-3.5, -2.0], [1.0, 4.0]],
             ep_lengths=[[10, 12], [9, 11]])
    found = read_evaluations(path)
    assert found.timesteps.tolist() == [100, 200]
    assert found.results.tolist() == [[-3.5, -2.0], [1.0, 4.0]]
    assert found.ep_lengths.tolist() == [[10, 12], [9, 11]]


@pytest.mark.parametrize("arrays, message", [
    ({"timesteps": [100], "results": [[1.0]]}, "not an evaluation record (no 'ep_lengths')"),
    ({"timesteps": [100, 200], "results": [[1.0]], "ep_lengths": [[3]]},
     "timesteps int64[2], results float64[1, 1]"),
    ({"timesteps": [100], "results": [[np.nan]], "ep_lengths": [[3]]}, "one finite return"),
    ({"timesteps": [-1], "results": [[1.0]], "ep_lengths": [[3]]}, "not an evaluation record"),
    ({"timesteps": [1.5], "results": [[1.0]], "ep_lengths": [[3]]}, "timesteps float64[1]"),
    ({"timesteps": [100], "results": [[1.0]], "ep_lengths": [[3, 4]]}, "ep_lengths [1, 2]"),
])
def test_a_malformed_record_is_named(tmp_path: Path, arrays: dict, message: str):
    path = tmp_path / "evaluations.npz"
    np.savez(path, **arrays)
    with pytest.raises(ValueError, match="evaluations.npz: ") as err:
        read_evaluations(path)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_pickled_arrays_are_not_loaded(tmp_path: Path):
    path = tmp_path / "evaluations.npz"
    ragged = np.empty(2, dtype=object)
    ragged[:] = [[1.0], [1.0, 2.0]]
    np.savez(path, timesteps=[1, 2], results=ragged, ep_lengths=ragged)
    with pytest.raises(ValueError, match="not a readable evaluation record .*allow_pickle"):
        read_evaluations(path)


def test_an_unreadable_file_is_named(tmp_path: Path):
    path = tmp_path / "evaluations.npz"
    path.write_bytes(b"PK\x03\x04 truncated")
    with pytest.raises(ValueError, match=f"{path}: not a readable evaluation record"):
        read_evaluations(path)


def test_a_single_array_is_not_a_record(tmp_path: Path):
    path = tmp_path / "evaluations.npz"
    with open(path, "wb") as f:
        np.save(f, np.zeros(3))
    with pytest.raises(ValueError, match="not a readable evaluation record \\(an array, not an"):
        read_evaluations(path)


def _pendulum():
    from stable_baselines3.common.env_util import make_vec_env
    return make_vec_env("Pendulum-v1", n_envs=1, seed=0, env_kwargs=dict(max_episode_steps=20))


def test_the_record_is_written_before_the_best_model_it_names(tmp_path: Path, monkeypatch):
    """SB3 saves the new best model inside its evaluation, before the record: a kill between
    the two left a best model that no row of the record accounts for, and a resume then let a
    worse evaluation replace it."""
    from agents import RecurrentTD3
    model = RecurrentTD3("MlpLstmPolicy", _pendulum(), seed=0, device="cpu", batch_size=8,
                         burn_in=2, train_length=4, buffer_size=200, learning_starts=5,
                         policy_kwargs=dict(lstm_hidden_size=4, net_arch=[4]))
    record, best = tmp_path / "evaluations.npz", tmp_path / "best.zip"

    def killed(*args, **kwargs):
        assert record.is_file()                          # the record holds the evaluation
        raise KeyboardInterrupt
    monkeypatch.setattr(callbacks, "save_atomic", killed)
    evaluation = RunEvalCallback(_pendulum(), record, n_eval_episodes=1, eval_freq=10,
                                 verbose=0, callback_on_new_best=SaveBestAtomically(best))
    with pytest.raises(KeyboardInterrupt):
        model.learn(12, callback=evaluation)
    assert read_evaluations(record).timesteps.tolist() == [10] and not best.exists()


def test_a_resume_beats_the_saved_best_model_s_evaluation(tmp_path: Path):
    previous = Evaluations(timesteps=np.array([10, 20, 30]),
                           results=np.array([[-5.0], [-1.0], [-3.0]]),
                           ep_lengths=np.array([[20], [20], [20]]))
    for best_step, threshold in ((10, -5.0), (20, -1.0), (None, -1.0), (40, -1.0)):
        evaluation = RunEvalCallback(_pendulum(), tmp_path / "e.npz", previous,
                                     best_step=best_step, verbose=0)
        assert evaluation.best_mean_reward == threshold, best_step
    # a resume from step 20: the row of step 30 (a step it replays) leaves the record, but a
    # best model saved there is still the one to beat
    for best_step, threshold in ((30, -3.0), (20, -1.0), (None, -1.0)):
        evaluation = RunEvalCallback(_pendulum(), tmp_path / "e.npz", previous,
                                     best_step=best_step, until=20, verbose=0)
        assert evaluation.best_mean_reward == threshold, best_step
        assert evaluation.evaluations_timesteps == [10, 20]
        assert evaluation.evaluations_results == [[-5.0], [-1.0]]
        assert evaluation.evaluations_length == [[20], [20]]


@pytest.mark.parametrize("steps, every", [(60, 60), (50, 20)])
def test_a_checkpoint_holds_its_steps_transitions_and_updates(tmp_path: Path, steps, every):
    import json
    import zipfile

    import gymnasium as gym

    from agents import RecurrentTD3
    from agents.callbacks import AtomicCheckpointCallback, replay_buffer_path

    model = RecurrentTD3("MlpLstmPolicy", gym.make("Pendulum-v1"), seed=510170,
                         learning_starts=10, batch_size=8, burn_in=2, train_length=4,
                         buffer_size=500, policy_kwargs=dict(lstm_hidden_size=8, net_arch=[8]))
    path = tmp_path / "last.zip"
    model.learn(steps, callback=AtomicCheckpointCallback(every, path))
    data = json.loads(zipfile.ZipFile(path).read("data"))
    buffer = np.load(replay_buffer_path(path))
    step = steps - steps % every
    # written from on_step it held step - 1 transitions tagged `step` and one update fewer
    assert data["num_timesteps"] == int(buffer["num_timesteps"]) == int(buffer["pos"]) == step
    assert data["_n_updates"] == step - 10
    if step == steps:                       # the last save is the model as training left it
        assert data["_n_updates"] == model._n_updates


@pytest.mark.parametrize("eval_seed", [None, 510180])
def test_a_reseeded_evaluation_plays_the_same_episodes_every_time(tmp_path: Path, eval_seed):
    import gymnasium as gym
    from stable_baselines3.common.env_util import make_vec_env

    from agents import RecurrentTD3

    model = RecurrentTD3("MlpLstmPolicy", gym.make("Pendulum-v1", max_episode_steps=20),
                         seed=510181, learning_starts=1000, batch_size=8, burn_in=2,
                         train_length=4, buffer_size=500,
                         policy_kwargs=dict(lstm_hidden_size=8, net_arch=[8]))
    eval_env = make_vec_env("Pendulum-v1", n_envs=1, seed=510182,
                            env_kwargs=dict(max_episode_steps=20))
    callback = RunEvalCallback(eval_env, tmp_path / "evaluations.npz", eval_seed=eval_seed,
                               n_eval_episodes=2, eval_freq=20, deterministic=True)
    model.learn(60, callback=callback)      # no update before learning_starts: one policy
    results = read_evaluations(tmp_path / "evaluations.npz").results
    assert results.shape == (3, 2)
    # reseeded, three evaluations of one policy agree; SB3's way, each went on from the last
    assert (np.ptp(results, axis=0) == 0).all() == (eval_seed is not None)
