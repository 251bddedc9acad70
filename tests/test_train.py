"""python train.py: the agent CLI on a tiny budget, --resume, checkpoints, bad hyperparameters."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
import torch as th
import yaml

from agents.callbacks import save_atomic
from agents.hyperparams import HyperparameterError, load_hyperparams
from agents.recurrent_td3 import RecurrentTD3
from agents.training import make_training_env
from aoass_env.maps import list_maps

ROOT = Path(__file__).resolve().parent.parent
TINY = {
    "td3-lstm": {"learning_starts": 60, "batch_size": 4, "buffer_size": 2000, "burn_in": 2,
                 "train_length": 4, "train_freq": 4,
                 "action_noise": {"kind": "normal", "sigma": 0.2},
                 "policy_kwargs": {"lstm_hidden_size": 8, "net_arch": [8]},
                 "env": {"field_size": 100, "densities": [0.1, 0.1], "n_nodes": 20,
                         "time_limit_factor": 1.0},
                 "eval": {"freq": 100, "episodes": 1}, "checkpoint_freq": 50},
    "td3": {"learning_starts": 60, "batch_size": 8, "buffer_size": 2000,
            "policy_kwargs": {"net_arch": [8]},
            "env": {"field_size": 100, "densities": [0.1, 0.1], "n_nodes": 20,
                    "time_limit_factor": 1.0},
            "eval": {"freq": 100, "episodes": 1}, "checkpoint_freq": 50},
}


@pytest.fixture
def tiny(tmp_path: Path) -> Path:
    path = tmp_path / "tiny.yml"
    path.write_text(yaml.safe_dump(TINY))
    return path


def test_cli_trains_checkpoints_and_resumes(tiny: Path, tmp_path: Path, train_script, capsys):
    out = tmp_path / "run"
    train_script.main(["--config", str(tiny), "--timesteps", "120", "--out", str(out),
                       "--log-dir", str(tmp_path / "tb"), "--no-progress"])
    for name in ("final.zip", "last.zip", "last_replay_buffer.npz", "best.zip",
                 "evaluations.npz", "run.yml"):
        assert (out / name).is_file(), name
    assert not list(out.glob(".*.tmp"))                       # atomic writes leave nothing
    record = yaml.safe_load((out / "run.yml").read_text())
    assert record["algo"] == "td3-lstm" and record["timesteps"] == 120
    assert record["command"].startswith("python train.py --config")
    assert list((tmp_path / "tb").rglob("events.out.tfevents*"))
    model = RecurrentTD3.load(out / "final.zip", device="cpu")
    assert model.num_timesteps == 120

    at = RecurrentTD3.load(out / "last.zip", device="cpu").num_timesteps   # periodic: 100
    assert at == 100
    twin = tmp_path / "twin"
    shutil.copytree(out, twin)
    for folder in (out, twin):
        train_script.main(["--config", str(tiny), "--timesteps", "60", "--out", str(folder),
                           "--resume", str(folder / "last.zip"), "--no-tensorboard",
                           "--no-progress"])
    resumed = RecurrentTD3.load(out / "final.zip", device="cpu")
    assert resumed.num_timesteps == at + 60
    # the same resume gives the same run (nothing was seeded: the weights used to differ)
    other = RecurrentTD3.load(twin / "final.zip", device="cpu").policy.state_dict()
    mine = resumed.policy.state_dict()
    assert all(th.equal(mine[k], other[k]) for k in mine)
    assert not all(th.equal(mine[k], v) for k, v in RecurrentTD3.load(
        out / "last.zip", device="cpu").policy.state_dict().items())   # it trained on
    # a model keyword the resume would ignore (it rebuilds the model from run.yml) is refused
    # before any step; it used to train on with the old value and record the new one
    with pytest.raises(SystemExit) as exit_:
        train_script.main(["--config", str(tiny), "--timesteps", "60", "--out", str(out),
                           "--resume", str(out / "last.zip"), "--no-tensorboard",
                           "--no-progress", "--hyperparams", "learning_rate:0.5", "tau:0.1"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith(f"train.py: error: --resume: {out / 'last.zip'}: a resume rebuilds "
                          f"the model and its stack from {out / 'run.yml'}, where "
                          f"learning_rate is ")
    # the advice names what to repeat: the command recorded (it used to say "no
    # --hyperparams", which could never work for a run trained with them)
    assert (", not this run's 0.5 (and 1 more: tau); give the --config, --hyperparams and "
            "--env-kwargs it was trained with (its command: python train.py --config") in err
    # so is a change of the stack the policy acts in: evaluate.py plays a policy in its
    # record's stack, which used to keep the first run's action_repeat after such a resume
    with pytest.raises(SystemExit) as exit_:
        train_script.main(["--config", str(tiny), "--timesteps", "60", "--out", str(out),
                           "--resume", str(out / "last.zip"), "--no-tensorboard",
                           "--no-progress", "--env-kwargs", "action_repeat:4", "n_nodes:30"])
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "where env.action_repeat is unset, not this run's 4; give the --config" in err
    assert RecurrentTD3.load(out / "final.zip", device="cpu").num_timesteps == at + 60


def test_feedforward_ablation_trains(tiny: Path, tmp_path: Path, train_script):
    from stable_baselines3 import TD3
    out = tmp_path / "ff"
    train_script.main(["--algo", "td3", "--config", str(tiny), "--timesteps", "80", "--out",
                       str(out), "--no-tensorboard", "--no-progress"])
    assert TD3.load(out / "final.zip", device="cpu").num_timesteps == 80


def test_interrupted_save_keeps_the_previous_checkpoint(tiny: Path, tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch):
    env = make_training_env(**TINY["td3"]["env"])
    from stable_baselines3 import TD3
    model = TD3("MlpPolicy", env, policy_kwargs={"net_arch": [8]}, learning_starts=10,
                device="cpu")
    path = tmp_path / "model.zip"
    save_atomic(model, path)
    before = path.read_bytes()

    def crash(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(model, "save", crash)
    with pytest.raises(KeyboardInterrupt):
        save_atomic(model, path)
    assert path.read_bytes() == before and not list(tmp_path.glob(".*.tmp"))
    assert TD3.load(path, device="cpu") is not None


def test_a_save_killed_between_its_renames_leaves_a_pair_of_one_save(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """The model used to be renamed before its buffer: a kill between the two left a new model
    beside an old buffer, refused at resume with the advice to delete it (the replay data
    lost)."""
    from stable_baselines3.common.env_util import make_vec_env

    from agents import callbacks, training
    env = make_vec_env("Pendulum-v1", n_envs=1, seed=0, env_kwargs=dict(max_episode_steps=20))
    tiny = dict(batch_size=8, burn_in=2, train_length=4, buffer_size=200, learning_starts=5,
                policy_kwargs=dict(lstm_hidden_size=4, net_arch=[4]))
    model = RecurrentTD3("MlpLstmPolicy", env, seed=0, device="cpu", **tiny)
    path = tmp_path / "last.zip"
    model.learn(10)
    save_atomic(model, path, replay_buffer=True)              # a pair at step 10
    model.learn(10, reset_num_timesteps=False)

    rename = callbacks.os.replace

    def killed(source, target):                               # at the buffer's rename
        if Path(source) == callbacks.pending_buffer_path(path):
            raise KeyboardInterrupt
        rename(source, target)
    monkeypatch.setattr(callbacks.os, "replace", killed)
    with pytest.raises(KeyboardInterrupt):
        save_atomic(model, path, replay_buffer=True)          # the model at step 20 is in place
    monkeypatch.undo()
    record = {"algo": "td3-lstm", "hyperparameters": tiny}
    again = RecurrentTD3.load(path, env=env, record=record)
    assert again.num_timesteps == 20
    assert training._load_buffer(again, path) == callbacks.pending_buffer_path(path)
    assert again.replay_buffer.pos == model.replay_buffer.pos
    np.testing.assert_array_equal(again.replay_buffer.rewards, model.replay_buffer.rewards)
    callbacks.pending_buffer_path(path).unlink()              # the old buffer alone: refused
    with pytest.raises(training.PolicyFileError, match="saved at step 10, the model at step 20"):
        training._load_buffer(again, path)


@pytest.mark.parametrize("section, message", [
    ({"learing_rate": 0.001}, r"td3-lstm.learing_rate: unknown key"),
    ({"learning_rate": -1.0}, r"td3-lstm.learning_rate=-1\.0 must be a number in \(0\.0, 1\.0\]"),
    ({"batch_size": 3.5}, r"td3-lstm.batch_size=3\.5 must be an integer in \[1, inf\)"),
    ({"burn_in": -2}, r"td3-lstm.burn_in=-2 must be an integer in \[0, inf\)"),
    ({"action_noise": "NormalActionNoise(0, 0.1)"}, r"td3-lstm.action_noise: must be"),
    ({"action_noise": {"kind": "normal", "sigma": "big"}}, r"action_noise.sigma"),
    ({"train_freq": [4, "minute"]}, r"td3-lstm.train_freq"),
    ({"env": [1, 2]}, r"td3-lstm.env: must be a mapping"),
])
def test_bad_hyperparameters_name_the_file_and_key(tmp_path: Path, section, message):
    path = tmp_path / "bad.yml"
    path.write_text(yaml.safe_dump({"td3-lstm": section}))
    with pytest.raises(HyperparameterError, match=message) as err:
        load_hyperparams(path, "td3-lstm")
    assert str(path) in str(err.value)


def test_cli_reports_bad_files_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture,
                                           train_script):
    path = tmp_path / "bad.yml"
    path.write_text("td3-lstm: {gamma: 2.0}\n")
    with pytest.raises(SystemExit) as exit_:
        train_script.main(["--config", str(path), "--no-progress"])
    assert exit_.value.code == 2
    assert "td3-lstm.gamma=2.0 must be a number in (0.0, 1.0]" in capsys.readouterr().err
    path.write_text("td3-lstm: [unclosed\n")
    with pytest.raises(HyperparameterError, match="not valid YAML"):
        load_hyperparams(path, "td3-lstm")
    with pytest.raises(HyperparameterError, match="no section 'td3'"):
        load_hyperparams(_write(tmp_path, "td3-lstm: {}"), "td3")
    with pytest.raises(SystemExit):
        train_script.main(["--resume", str(tmp_path / "missing.zip"), "--no-progress"])


def _write(folder: Path, text: str) -> Path:
    path = folder / "other.yml"
    path.write_text(text)
    return path


def test_shipped_config_is_valid():
    for algo in ("td3-lstm", "td3"):
        hp = load_hyperparams(ROOT / "configs" / "aoass.yml", algo)
        assert hp["n_timesteps"] > 0 and np.isfinite(hp["learning_rate"])


def test_integer_keys_reach_the_algorithm_as_integers(tmp_path: Path):
    path = _write(tmp_path, "td3-lstm: {batch_size: 32.0, learning_rate: 0.001}")
    hp = load_hyperparams(path, "td3-lstm")
    assert hp["batch_size"] == 32 and isinstance(hp["batch_size"], int)
    assert isinstance(hp["learning_rate"], float)


def test_seeds_train_one_run_each_in_its_own_folders(tiny: Path, tmp_path: Path,
                                                     capsys: pytest.CaptureFixture, train_script):
    out, tb = tmp_path / "runs", tmp_path / "tb"
    train_script.main(["--config", str(tiny), "--timesteps", "20", "--seeds", "3,5",
                       "--out", str(out), "--log-dir", str(tb), "--no-progress"])
    for seed in (3, 5):
        assert RecurrentTD3.load(out / f"seed{seed}" / "final.zip").num_timesteps == 20
        assert yaml.safe_load((out / f"seed{seed}" / "run.yml").read_text())["seed"] == seed
        (run,) = tb.glob(f"td3-lstm_seed{seed}_*")
        assert list(run.glob("events.out.tfevents*"))
    assert sorted(p.name for p in out.iterdir()) == ["seed3", "seed5"]
    assert "seed 5: done" in capsys.readouterr().out


@pytest.mark.parametrize("text, seeds", [
    ("0-4", [0, 1, 2, 3, 4]), ("0,2,5", [0, 2, 5]), ("7", [7]), (" 0-1, 9 ", [0, 1, 9]),
])
def test_parse_seeds(text: str, seeds: list[int]):
    from agents.seeds import parse_seeds
    assert parse_seeds(text) == seeds


def test_runs_of_consecutive_seeds_share_no_training_env():
    from agents.training import _vec_env, env_seeds
    assert env_seeds(7, 1) == [7]                  # a one-env run is seeded as before
    assert len(set(env_seeds(7, 4) + env_seeds(8, 4))) == 8
    kwargs = dict(n_nodes=20)
    run_a, run_b = _vec_env(2, 510150, kwargs), _vec_env(2, 510151, kwargs)
    try:
        assert run_a.seed(510150) == env_seeds(510150, 2)
        run_b.seed(510151)
        first_a, first_b = run_a.reset(), run_b.reset()
        # SB3's seed + i gave run S's env 1 the episodes of run S + 1's env 0
        assert not np.array_equal(first_a[1], first_b[0])
        assert np.array_equal(first_a[0], make_training_env(**kwargs).reset(seed=510150)[0])
    finally:
        run_a.close()
        run_b.close()


@pytest.mark.parametrize("seed", [-1, 2**32, 1.5, True])
def test_a_run_refuses_a_seed_outside_32_bits(seed):
    from agents.training import TrainRun
    with pytest.raises(ValueError, match=r"seed=.* must be an integer in \[0, 4294967295\]"):
        TrainRun(seed=seed)


@pytest.mark.parametrize("argv, message", [
    (["--seeds", "4-1"], "--seeds '4-1': expected non-negative integers as a range A-B"),
    (["--seeds", "0,x"], "--seeds '0,x': expected"),
    (["--seeds", "-1"], "--seeds '-1': expected"),
    (["--seeds", "0-2,1"], "--seeds '0-2,1': seed(s) 1 given twice"),
    # seeds past 32 bits used to fail deep in NumPy after the envs were built
    (["--seed", "4294967296"], "argument --seed: must be an integer in [0, 4294967295], got "
                               "'4294967296'"),
    (["--seeds", "0,4294967296"], "--seeds '0,4294967296': a seed above 4294967295"),
    (["--seeds", "0-1", "--seed", "3"], "--seed: not allowed with argument --seeds"),
    (["--seeds", "0-1", "--resume", "x.zip"], "--resume continues one run"),
    (["--address", "auto"], "--address names a Ray cluster; it needs --backend ray"),
    (["--backend", "cloud"], "argument --backend: invalid choice: 'cloud'"),
])
def test_bad_seed_and_backend_options_are_usage_errors(tiny: Path, tmp_path: Path, argv,
                                                       message, capsys: pytest.CaptureFixture,
                                                       monkeypatch: pytest.MonkeyPatch,
                                                       train_script):
    (tmp_path / "x.zip").write_bytes(b"")                  # a model file for --resume
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exit_:
        train_script.main(["--config", str(tiny), "--out", str(tmp_path / "out"),
                           "--no-progress", *argv])
    assert exit_.value.code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_backend_ray_without_ray_says_how_to_install(tiny: Path, tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch,
                                                     capsys: pytest.CaptureFixture, train_script):
    monkeypatch.setitem(sys.modules, "ray", None)           # `import ray` fails
    with pytest.raises(SystemExit) as exit_:
        train_script.main(["--config", str(tiny), "--seeds", "0-1", "--backend", "ray",
                           "--out", str(tmp_path / "out"), "--no-progress"])
    assert exit_.value.code == 2
    assert "--backend ray needs Ray: pip install -e '.[ray]'" in capsys.readouterr().err


def test_training_and_selection_never_see_the_test_maps(tiny: Path, monkeypatch):
    """The agent fits on maps/train less the validation split and best.zip is chosen on the
    validation split; maps/test is refused."""
    import agents.training as training
    fit = make_training_env(field_size=100, densities=(0.1, 0.4), n_nodes=20)
    held = make_training_env(split="validation", field_size=100, densities=(0.1, 0.4),
                             n_nodes=20, cycle=True)
    fit_names = {m.name for m in fit.maps}
    held_names = {m.name for m in held.maps}
    assert len(fit_names) == 16 and len(held_names) == 4 and not fit_names & held_names
    assert all(n.startswith("d0.") for n in fit_names | held_names)
    test_stems = {n.split("/")[1] for n in list_maps("test")}
    assert not (fit_names | held_names) & test_stems
    with pytest.raises(ValueError, match="split='test'.*reported results only"):
        make_training_env(split="test")

    seen = []

    def record(n_envs, seed, env_kwargs):
        seen.append(env_kwargs)
        if len(seen) == 2:      # the evaluation env: stop before any training
            raise KeyboardInterrupt
    monkeypatch.setattr(training, "_vec_env", record)
    with pytest.raises(KeyboardInterrupt):
        training.train_agent(training.TrainRun(config=tiny, out=tiny.parent / "run",
                                               log_dir=None, progress_bar=False))
    assert seen[0].get("split", "train") == "train"
    assert seen[1]["split"] == "validation" and seen[1]["cycle"] is True


def _scalars(log_dir: Path) -> dict[str, list[int]]:
    """TensorBoard scalar tag -> the steps it was written at, over every event file."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator
    tags: dict[str, list[int]] = {}
    for events in log_dir.rglob("events.out.tfevents*"):
        acc = EventAccumulator(str(events.parent))
        acc.Reload()
        for tag in acc.Tags()["scalars"]:
            tags.setdefault(tag, []).extend(e.step for e in acc.Scalars(tag))
    return tags


def test_overrides_and_frequencies_from_the_command_line(tiny: Path, tmp_path: Path,
                                                         train_script):
    """RL Zoo's habits: --hyperparams and --env-kwargs replace keys (values as YAML), the
    frequencies are flags, and a run shorter than one episode still writes its scalars."""
    out, tb = tmp_path / "run", tmp_path / "tb"
    train_script.main(["--config", str(tiny), "--timesteps", "300", "--out", str(out),
                       "--log-dir", str(tb), "--no-progress",
                       "--hyperparams", "learning_starts:50", "policy_kwargs:{lstm_hidden_size: 4,"
                       " net_arch: [4]}", "--env-kwargs", "n_nodes:10",
                       "--eval-freq", "1000", "--checkpoint-freq", "1000", "--log-interval", "1"])
    hp = yaml.safe_load((out / "run.yml").read_text())["hyperparameters"]
    assert hp["learning_starts"] == 50 and hp["policy_kwargs"]["net_arch"] == [4]
    assert hp["env"]["n_nodes"] == 10 and hp["env"]["densities"] == [0.1, 0.1]   # the rest kept
    assert hp["eval"] == {"freq": 1000, "episodes": 1} and hp["checkpoint_freq"] == 1000
    assert (out / "final.zip").is_file()
    assert not (out / "last.zip").exists() and not (out / "evaluations.npz").exists()
    scalars = _scalars(tb)
    assert scalars["time/total_timesteps"] == [300]


@pytest.mark.parametrize("argv, message", [
    (["--hyperparams", "learning_rat:0.1"],
     "--hyperparams learning_rat: unknown key 'learning_rat'; did you mean 'learning_rate'?"),
    (["--env-kwargs", "n_node:3"], "--env-kwargs n_node: unknown key 'n_node'; did you mean "
                                   "'n_nodes'?"),
    (["--hyperparams", "learning_rate:-1"], "td3-lstm.learning_rate=-1 must be a number"),
    (["--env-kwargs", "obstacle_density:[1"], "the value is not valid YAML"),
    (["--hyperparams", "gamma"], "must be key:value, got 'gamma'"),
    (["--hyperparams", "policy:!!python/object/apply:os.system [echo]"],
     "the value is not valid YAML"),
    (["--eval-freq", "0"], "--eval-freq: must be an integer >= 1"),
    # the last of a key given twice used to win unseen
    (["--hyperparams", "batch_size:4", "batch_size:8"],
     "--hyperparams batch_size: given twice (4, then 8)"),
    (["--env-kwargs", "n_nodes:30", "n_nodes:40"], "--env-kwargs n_nodes: given twice"),
    # ... also across two of the flag (the second flag used to drop the first's pairs unseen)
    (["--hyperparams", "batch_size:4", "--hyperparams", "batch_size:8"],
     "--hyperparams batch_size: given twice (4, then 8)"),
    (["--env-kwargs", "n_nodes:30", "--env-kwargs", "action_repeat:2", "n_nodes:40"],
     "--env-kwargs n_nodes: given twice (30, then 40)"),
    # SB3 asserted this in learn(), a traceback after run.yml was written (a blocked --out)
    (["--n-envs", "2", "--hyperparams", "train_freq:[1, episode]"],
     "train_freq: [1, 'episode'] counts episodes, which SB3 does with one environment only, "
     "not --n-envs 2; give train_freq in steps, or --n-envs 1"),
    # SB3's TD3 policy said "optimizer got an empty parameter list"
    (["--algo", "td3", "--hyperparams", "policy_kwargs:{n_critics: 0}"],
     "td3.policy_kwargs.n_critics=0 must be"),
])
def test_bad_overrides_are_one_line_errors_naming_the_flag(tiny: Path, tmp_path: Path,
                                                           capsys: pytest.CaptureFixture,
                                                           train_script, argv, message):
    with pytest.raises(SystemExit) as exit_:
        train_script.main(["--config", str(tiny), "--out", str(tmp_path / "run"),
                           "--no-progress", *argv])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert message in err
    assert not (tmp_path / "run" / "run.yml").exists()


def _files(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in folder.iterdir()}


def test_a_folder_holds_one_run(tiny: Path, tmp_path: Path, capsys: pytest.CaptureFixture,
                                train_script):
    """A new run into a folder holding another run's files is refused before any work (it
    used to write its run.yml beside the other run's models, which a resume or an evaluation
    then paired); --overwrite removes them first."""
    import agents.training as training
    out = tmp_path / "run"
    train_script.main(["--config", str(tiny), "--timesteps", "120", "--out", str(out),
                       "--no-tensorboard", "--no-progress"])
    before = _files(out)
    assert {"best.zip", "evaluations.npz", "last.zip", "run.yml"} <= set(before)
    with pytest.raises(SystemExit) as exit_:
        train_script.main(["--config", str(tiny), "--timesteps", "60", "--out", str(out),
                           "--no-tensorboard", "--no-progress"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"train.py: error: --out {out}: holds another run's files (best.zip, "
                   f"last.zip, last_replay_buffer.npz, final.zip, evaluations.npz, run.yml); "
                   f"give another --out, --resume {out / 'last.zip'} to continue it, or "
                   f"--overwrite to replace them"]
    assert _files(out) == before
    with pytest.raises(ValueError, match="holds another run's files"):     # the API too
        training.train_agent(training.TrainRun(config=tiny, out=out, log_dir=None,
                                               progress_bar=False))
    assert _files(out) == before
    # a model of another folder resumed into it is another run as well
    (tmp_path / "elsewhere").mkdir()
    moved = tmp_path / "elsewhere" / "model.zip"
    moved.write_bytes(before["last.zip"])
    with pytest.raises(SystemExit):
        train_script.main(["--config", str(tiny), "--timesteps", "60", "--out", str(out),
                           "--resume", str(moved), "--no-tensorboard", "--no-progress"])
    assert _files(out) == before
    # --overwrite with a resume that is refused (an unreadable model) leaves them: they are
    # removed once the model loaded (they used to be gone, and nothing trained)
    (tmp_path / "elsewhere" / "broken.zip").write_bytes(b"not a zip")
    with pytest.raises(SystemExit):
        train_script.main(["--config", str(tiny), "--timesteps", "60", "--out", str(out),
                           "--resume", str(tmp_path / "elsewhere" / "broken.zip"),
                           "--overwrite", "--no-tensorboard", "--no-progress"])
    assert _files(out) == before

    train_script.main(["--config", str(tiny), "--timesteps", "60", "--out", str(out),
                       "--overwrite", "--eval-freq", "1000", "--no-tensorboard",
                       "--no-progress"])
    assert sorted(p.name for p in out.iterdir()) == [
        "final.zip", "last.zip", "last_replay_buffer.npz", "run.yml"]   # nothing of the first
    assert yaml.safe_load((out / "run.yml").read_text())["timesteps"] == 60
    assert "removed another run's files from" in capsys.readouterr().out


def test_seeds_check_every_folder_before_the_first_run(tiny: Path, tmp_path: Path,
                                                       train_script):
    out = tmp_path / "runs"
    (out / "seed1").mkdir(parents=True)
    (out / "seed1" / "run.yml").write_text("algo: td3-lstm\n")
    with pytest.raises(SystemExit) as exit_:
        train_script.main(["--config", str(tiny), "--timesteps", "20", "--seeds", "0-1",
                           "--out", str(out), "--no-tensorboard", "--no-progress"])
    assert exit_.value.code == 2
    assert sorted(p.name for p in out.iterdir()) == ["seed1"]     # seed 0 did not start


@pytest.mark.parametrize("previous, replaced", [(1e9, False), (-1e9, True)])
def test_a_resume_continues_the_runs_evaluations(tiny: Path, tmp_path: Path, train_script,
                                                 previous: float, replaced: bool):
    """A resume in the run's folder keeps the evaluations made before it (SB3's EvalCallback
    started a new evaluations.npz) and saves a new best.zip only for an evaluation better than
    all of them (it saved the resume's first evaluation, however bad)."""
    out = tmp_path / "run"
    train_script.main(["--config", str(tiny), "--timesteps", "120", "--out", str(out),
                       "--no-tensorboard", "--no-progress"])
    with np.load(out / "evaluations.npz") as data:
        assert data["timesteps"].tolist() == [100]
        lengths = data["ep_lengths"]
    # the first evaluation's return, replaced by one no evaluation reaches (or all exceed)
    np.savez(out / "evaluations.npz", timesteps=[100], results=[[previous]], ep_lengths=lengths)
    best = (out / "best.zip").read_bytes()
    train_script.main(["--config", str(tiny), "--timesteps", "100", "--out", str(out),
                       "--resume", str(out / "last.zip"), "--no-tensorboard",
                       "--no-progress"])
    with np.load(out / "evaluations.npz", allow_pickle=False) as data:
        assert data["timesteps"].tolist() == [100, 200]
        assert data["results"][0, 0] == previous and data["results"].shape == (2, 1)
    assert ((out / "best.zip").read_bytes() != best) == replaced
    if replaced:
        assert RecurrentTD3.load(out / "best.zip", device="cpu").num_timesteps == 200


def test_a_resume_drops_the_evaluations_it_replays_and_can_be_resumed_again(
        tiny: Path, tmp_path: Path, train_script):
    """Evaluations made after last.zip (before an interruption) leave the record when a resume
    from last.zip replays their steps: the record's steps keep increasing, so the run can be
    resumed again (a repeated step used to make the next resume refuse the record)."""
    out = tmp_path / "run"
    common = ["--config", str(tiny), "--out", str(out), "--no-tensorboard", "--no-progress",
              "--checkpoint-freq", "100", "--eval-freq", "50"]
    train_script.main([*common, "--timesteps", "160"])
    with np.load(out / "evaluations.npz", allow_pickle=False) as data:
        assert data["timesteps"].tolist() == [50, 100, 150]
    for _ in range(2):
        train_script.main([*common, "--timesteps", "60", "--resume", str(out / "last.zip")])
        with np.load(out / "evaluations.npz", allow_pickle=False) as data:
            assert data["timesteps"].tolist() == [50, 100, 150]


def test_a_resume_keeps_the_runs_seed(tiny: Path, tmp_path: Path, train_script,
                                      capsys: pytest.CaptureFixture):
    """A resume without --seed takes the run's seed from its run.yml (it used to take 0, whose
    validation episodes are other maps than the run's); another --seed is refused."""
    out = tmp_path / "run"
    common = ["--config", str(tiny), "--out", str(out), "--no-tensorboard", "--no-progress",
              "--timesteps", "60"]
    train_script.main([*common, "--seed", "3"])
    with pytest.raises(SystemExit) as exit_:
        train_script.main([*common, "--resume", str(out / "last.zip"), "--seed", "5"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert (f"{out / 'last.zip'}: its run was trained with seed 3 ({out / 'run.yml'}), not "
            f"this run's 5") in err and "give --seed 3, or no --seed" in err
    train_script.main([*common, "--resume", str(out / "last.zip")])
    record = yaml.safe_load((out / "run.yml").read_text())
    assert record["seed"] == 3 and [r["seed"] for r in record["resumes"]] == [3]


@pytest.mark.parametrize("damage, message", [
    (lambda path: path.write_bytes(b"not a zip"), "not a readable evaluation record"),
    (lambda path: np.savez(path, timesteps=[100], results=[[1.0, 2.0]], ep_lengths=[[5, 5]]),
     "the run's evaluations are of 2 episodes each, this resume's of 1; continue them with "
     "--eval-episodes 2, or resume into another --out"),
])
def test_a_resume_refuses_evaluations_it_cannot_continue(tiny: Path, tmp_path: Path,
                                                         capsys: pytest.CaptureFixture,
                                                         train_script, damage, message):
    out = tmp_path / "run"
    train_script.main(["--config", str(tiny), "--timesteps", "60", "--out", str(out),
                       "--no-tensorboard", "--no-progress"])
    damage(out / "evaluations.npz")
    final = (out / "final.zip").read_bytes()
    with pytest.raises(SystemExit) as exit_:
        train_script.main(["--config", str(tiny), "--timesteps", "60", "--out", str(out),
                           "--resume", str(out / "last.zip"), "--no-tensorboard",
                           "--no-progress"])
    assert exit_.value.code == 2
    (err,) = capsys.readouterr().err.strip().splitlines()
    assert err.startswith(f"train.py: error: --resume: {out / 'evaluations.npz'}: ")
    assert message in err
    assert (out / "final.zip").read_bytes() == final        # refused before any step
