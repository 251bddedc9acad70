"""Issue 21, the audit as a test suite: no code runs from a data file, and every bad input of
the issue ends in a clear error naming it (one parametrized line per input)."""

from __future__ import annotations

import base64
import json
import os
import pathlib
import pickle
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import aoass_env  # noqa: F401  (registers AOASS-v0)
from agents.checkpoints import PolicyFileError, load_replay_buffer
from agents.hyperparams import HyperparameterError, load_hyperparams
from agents.recurrent_td3 import RecurrentTD3
from agents.seeds import parse_seeds
from aoass_env.action import checked_action
from aoass_env.beacon_log import BeaconLog, BeaconLogError
from aoass_env.config import AOASSConfig, ConfigError
from aoass_env.env import AOASSEnv
from aoass_env.evaluation import cli
from aoass_env.evaluation.methods import DEFAULT_POLICY, load_policy
from aoass_env.localization.olstm import DEFAULT_CHECKPOINT, CheckpointError, load_checkpoint
from aoass_env.simulator import Simulator

ROOT = Path(__file__).resolve().parent.parent
CONFIG = ROOT / "configs" / "aoass.yml"


class _Payload:
    """Unpickling this touches ``path``: the code a crafted policy file would run."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def __reduce__(self):
        return (pathlib.Path.touch, (pathlib.Path(str(self.path)),))


def _crafted_policy(folder: Path, marker: Path) -> Path:
    """The shipped policy with its run.yml, its lr_schedule replaced by a pickled payload."""
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copy(DEFAULT_POLICY.with_name("run.yml"), folder / "run.yml")
    path = folder / "crafted.zip"
    with zipfile.ZipFile(DEFAULT_POLICY) as src, zipfile.ZipFile(path, "w") as dst:
        for name in src.namelist():
            content = src.read(name)
            if name == "data":
                data = json.loads(content)
                data["lr_schedule"][":serialized:"] = base64.b64encode(
                    pickle.dumps(_Payload(marker))).decode()
                content = json.dumps(data).encode()
            dst.writestr(name, content)
    return path


def test_the_crafted_policy_would_run_code_through_sb3s_own_load(tmp_path):
    """The payload is live: SB3's unpickling load creates the marker."""
    from stable_baselines3.common.save_util import load_from_zip_file
    marker = tmp_path / "pwned"
    load_from_zip_file(_crafted_policy(tmp_path / "p", marker), device="cpu")
    assert marker.exists()


def test_evaluate_policy_runs_no_code_from_a_crafted_zip(tmp_path, monkeypatch):
    marker = tmp_path / "pwned"
    policy = _crafted_policy(tmp_path / "p", marker)
    loaded = []

    def worker(jobs, store, *, options, **kwargs):   # what a worker does first: load it
        loaded.append(load_policy(options.policy, options.algo, options.policy_run))
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "run_jobs", worker)
    status = cli.main(["--preset", "smoke", "--methods", "aoass", "--localizers", "dvhop",
                       "--policy", str(policy), "--out", str(tmp_path / "out"),
                       "--no-progress"])
    assert status == 130 and isinstance(loaded[0], RecurrentTD3)
    assert loaded[0].num_timesteps == 27500 and not marker.exists()


def test_train_resume_runs_no_code_from_a_crafted_zip(tmp_path, capsys, train_script):
    marker = tmp_path / "pwned"
    policy = _crafted_policy(tmp_path / "p", marker)
    config = tmp_path / "tiny.yml"
    hp = load_hyperparams(CONFIG, "td3-lstm")
    # the model's keywords stay the record's (a resume rebuilds the model from its run.yml)
    config.write_text(yaml.safe_dump({"td3-lstm": {
        **hp, "checkpoint_freq": 10_000,
        "eval": {"freq": 10_000, "episodes": 1},
        "env": {**hp["env"], "n_nodes": 20, "time_limit_factor": 1.0}}}))
    train_script.main(["--resume", str(policy), "--timesteps", "2", "--config", str(config),
                        "--out", str(tmp_path / "out"), "--no-tensorboard", "--no-progress"])
    assert "resumed" in capsys.readouterr().out and not marker.exists()
    record = yaml.safe_load((tmp_path / "out" / "run.yml").read_text())
    assert record["resume"].endswith("crafted.zip")


def test_a_resume_appends_to_run_yml(tmp_path):
    from agents.training import TrainRun, _write_record
    hp = load_hyperparams(CONFIG, "td3-lstm")
    path = tmp_path / "run.yml"
    _write_record(path, TrainRun(config=CONFIG, command="first"), hp, 10)
    model = tmp_path / "last.zip"
    model.write_bytes(b"")
    for n in (1, 2):
        _write_record(path, TrainRun(config=CONFIG, resume=model, command=f"resume {n}"), hp,
                      10)
    record = yaml.safe_load(path.read_text())
    assert record["command"] == "first"
    assert [r["command"] for r in record["resumes"]] == ["resume 1", "resume 2"]


def test_a_pickled_or_unpaired_replay_buffer_is_refused(tmp_path):
    model = RecurrentTD3.load(DEFAULT_POLICY)
    path = tmp_path / "buffer.npz"
    np.savez(path, observations=np.array([object()], dtype=object))
    with pytest.raises(PolicyFileError, match="buffer.npz"):
        load_replay_buffer(model, path)
    model.save_replay_buffer(path)
    model.num_timesteps += 1          # a buffer from another save than the model's
    with pytest.raises(PolicyFileError, match="not saved together"):
        load_replay_buffer(model, path)
    model.num_timesteps -= 1
    load_replay_buffer(model, path)


def test_stale_temporary_files_are_removed(tmp_path):
    from aoass_env.atomic import remove_stale_temporaries
    stale = tmp_path / ".last.zip.0123abcd.tmp"
    stale.write_bytes(b"half")
    (tmp_path / "last.zip").write_bytes(b"whole")
    assert remove_stale_temporaries(tmp_path) == [stale]
    assert not stale.exists() and (tmp_path / "last.zip").exists()


# ---------------------------------------------------------------- the audit, one line per input
def _yaml(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "bad.yml"
    path.write_text(text)
    return path


def _section(**changes) -> str:
    hp = {**load_hyperparams(CONFIG, "td3-lstm"), **changes}
    return yaml.safe_dump({"td3-lstm": hp})


def _env_section(**changes) -> str:
    hp = load_hyperparams(CONFIG, "td3-lstm")
    return _section(env={**hp["env"], **changes})


def _policy_without_record(tmp_path: Path) -> Path:
    shutil.copy(DEFAULT_POLICY, tmp_path / "lonely.zip")
    return tmp_path / "lonely.zip"


def _foreign_zip(tmp_path: Path) -> Path:
    shutil.copy(DEFAULT_POLICY.with_name("run.yml"), tmp_path / "run.yml")
    with zipfile.ZipFile(tmp_path / "foreign.zip", "w") as z:
        z.writestr("data", "{}")
    return tmp_path / "foreign.zip"


def _corrupt_zip(tmp_path: Path) -> Path:
    shutil.copy(DEFAULT_POLICY.with_name("run.yml"), tmp_path / "run.yml")
    (tmp_path / "corrupt.zip").write_bytes(DEFAULT_POLICY.read_bytes()[:5000])
    return tmp_path / "corrupt.zip"


def _log(tmp_path: Path, **changes) -> Path:
    env = AOASSEnv(n_nodes=10, field_size=40.0, obstacle_density=0.1)
    env.reset(seed=0)
    for _ in range(5):
        env.step(np.zeros(2))
    arrays = {**env.unwrapped.beacon_log.arrays(), **changes}
    path = tmp_path / "log.npz"
    np.savez(path, **arrays)
    return path


def _log_key(path: Path) -> object:
    """``aoass_env.evaluation.episode.log_key(path)``, imported when the case runs."""
    from aoass_env.evaluation.episode import log_key
    return log_key(path)


def _extra(**changes) -> np.ndarray:
    """The evaluation record of :func:`_log`'s episode (a valid key of its 10 nodes on a 40 m
    field), with ``changes``."""
    key = {"method": "spiral", "map": "gen", "field_size": 40.0, "n_nodes": 10,
           "obstacle_density": 0.1, "seed": 0, "coverage": 0.5}
    return np.array(json.dumps({**key, **changes}))


def _extra_alone(tmp_path: Path) -> Path:
    """A .npz holding a valid evaluation record and nothing of a beacon log."""
    path = tmp_path / "alone.npz"
    np.savez(path, evaluation_episode=_extra())
    return path


def _foreign_log(tmp_path: Path, **config) -> Path:
    """A log without the evaluation record whose config_json has ``config`` merged in."""
    with np.load(_log(tmp_path), allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    arrays["config_json"] = np.array(json.dumps({**json.loads(str(arrays["config_json"])),
                                                 **config}))
    np.savez(tmp_path / "log.npz", **arrays)
    return tmp_path / "log.npz"


def _nan_checkpoint(tmp_path: Path) -> Path:
    payload = torch.load(DEFAULT_CHECKPOINT, weights_only=True)
    name = next(iter(payload["state_dict"]))
    payload["state_dict"][name] = torch.full_like(payload["state_dict"][name], float("nan"))
    torch.save(payload, tmp_path / "nan.pt")
    return tmp_path / "nan.pt"


def _evaluate(*argv: str):
    return lambda: cli.main([*argv, "--out", "/nonexistent-unused", "--no-progress"])


def _train(script, *argv: str):
    return lambda: script.main(list(argv))


AUDIT = [
    # (input, (tmp_path, train.py module) -> call, error type, text the message names)
    ("policy zip without run.yml", lambda t, s: _evaluate(
        "--methods", "aoass", "--policy", str(_policy_without_record(t))), SystemExit,
     "run.yml"),
    ("foreign policy zip", lambda t, s: lambda: RecurrentTD3.load(_foreign_zip(t)),
     PolicyFileError, "foreign.zip"),
    ("corrupt policy zip", lambda t, s: lambda: RecurrentTD3.load(_corrupt_zip(t)),
     PolicyFileError, "corrupt.zip"),
    ("200 m map with field_size=100", lambda t, s: lambda: AOASSEnv(
        map="test/d0.10_f200_s518", field_size=100), ConfigError, "field_size"),
    ("waypoint_step=1000", lambda t, s: lambda: AOASSEnv(waypoint_step=1000),
     ConfigError, "waypoint_step"),
    ("waypoint_step=1000 in the simulator", lambda t, s: lambda: Simulator(
        AOASSConfig(waypoint_step=1000), np.random.default_rng(0)), ConfigError,
     "waypoint_step"),
    ("node at (1e6, -1e6)", lambda t, s: lambda: BeaconLog.load(
        _log(t, nodes=np.tile([[1e6, -1e6]], (10, 1)))), BeaconLogError, "nodes"),
    ("beacons at 1e9", lambda t, s: lambda: BeaconLog.load(_log(
        t, beacons=np.array([[0.0, 1e9, 1e9]]), receptions=np.zeros((0, 2), np.int64))),
     BeaconLogError, "beacons"),
    ("evaluate.py --methods ''", lambda t, s: _evaluate("--methods", ""), SystemExit, "--methods"),
    ("train.py --threads 0", lambda t, s: _train(s, "--threads", "0"), SystemExit, "--threads"),
    ("train.py --out a file", lambda t, s: _train(s, "--out", str(_yaml(t, ""))), SystemExit,
     "--out"),
    ("train.py --log-dir a file", lambda t, s: _train(s, "--log-dir", str(_yaml(t, ""))),
     SystemExit, "--log-dir"),
    ("train.py --config a folder", lambda t, s: _train(s, "--config", str(t)), SystemExit,
     "--config"),
    ("--seeds 0-999999999", lambda t, s: lambda: parse_seeds("0-999999999"), ValueError,
     "--seeds"),
    ("evaluate.py --seeds 999999999", lambda t, s: _evaluate("--seeds", "999999999"), SystemExit,
     "--seeds"),
    ("eval: {frequency: ...}", lambda t, s: lambda: load_hyperparams(
        _yaml(t, _section(eval={"frequency": 10})), "td3-lstm"), HyperparameterError,
     "eval.frequency"),
    ("eval: {freq: -5, episodes: 0}", lambda t, s: lambda: load_hyperparams(
        _yaml(t, _section(eval={"freq": -5, "episodes": 0})), "td3-lstm"),
     HyperparameterError, "td3-lstm.eval."),
    ("policy_kwargs typo", lambda t, s: lambda: load_hyperparams(
        _yaml(t, _section(policy_kwargs={"lstm_hiden_size": 64})), "td3-lstm"),
     HyperparameterError, "policy_kwargs.lstm_hiden_size"),
    ("duplicate YAML key", lambda t, s: lambda: load_hyperparams(
        _yaml(t, "td3-lstm:\n  batch_size: 8\n  batch_size: 16\n"), "td3-lstm"),
     HyperparameterError, "batch_size"),
    ("env section typo", lambda t, s: lambda: load_hyperparams(
        _yaml(t, _env_section(n_node=10)), "td3-lstm"), HyperparameterError,
     "bad.yml: td3-lstm.env.n_node"),
    ("safety section typo", lambda t, s: lambda: load_hyperparams(
        _yaml(t, _env_section(safety={"heading_scael": 0.2})), "td3-lstm"),
     HyperparameterError, "bad.yml: td3-lstm.env.safety.heading_scael"),
    ("localizer --epochs -1", lambda t, s: _train(s, "localizer", "--epochs", "-1"), SystemExit,
     "--epochs"),
    ("localizer --batch-size 0", lambda t, s: _train(s, "localizer", "--batch-size", "0"),
     SystemExit, "--batch-size"),
    ("localizer --hidden 0", lambda t, s: _train(s, "localizer", "--hidden", "0"), SystemExit,
     "--hidden"),
    ("localizer --n-train-logs 0", lambda t, s: _train(s, "localizer", "--n-train-logs", "0"),
     SystemExit, "--n-train-logs"),
    ("localizer --learning-rate nan", lambda t, s: _train(s, "localizer", "--learning-rate", "nan"),
     SystemExit, "--learning-rate"),
    ("malformed evaluation record", lambda t, s: lambda: _log_key(
        _log(t, evaluation_episode=np.array("{not json"))), BeaconLogError,
     "evaluation_episode"),
    ("evaluation record of objects", lambda t, s: lambda: _log_key(
        _log(t, evaluation_episode=np.array([{}], dtype=object))), BeaconLogError,
     "log.npz: beacon log key 'evaluation_episode': cannot read (ValueError: Object arrays"),
    # the record's episode columns went into episodes.csv unchecked (a coverage of 750 %,
    # a row the next run refused), its key was never compared with the log, and a file
    # holding the record alone passed as a log
    ("evaluation record's coverage 7.5", lambda t, s: lambda: _log_key(
        _log(t, evaluation_episode=_extra(coverage=7.5))), BeaconLogError,
     "key 'evaluation_episode': coverage='7.5' must be a finite number in [0, 1]"),
    ("evaluation record's beacons 'lots'", lambda t, s: lambda: _log_key(
        _log(t, evaluation_episode=_extra(beacons="lots"))), BeaconLogError,
     "key 'evaluation_episode': invalid literal for int()"),
    ("evaluation record of another N", lambda t, s: lambda: _log_key(
        _log(t, evaluation_episode=_extra(n_nodes=500))), BeaconLogError,
     "its key is N = 500 on a 40 m field, but the log holds 10 nodes on a 40 m field"),
    ("evaluation record alone", lambda t, s: lambda: _log_key(_extra_alone(t)),
     BeaconLogError, "alone.npz: beacon log key"),
    ("foreign log's seed 'abc'", lambda t, s: lambda: _log_key(_foreign_log(t, seed="abc")),
     BeaconLogError, "'config_json': its seed must be an integer or null, got 'abc'"),
    ("foreign log's seed 1.5", lambda t, s: lambda: _log_key(_foreign_log(t, seed=1.5)),
     BeaconLogError, "its seed must be an integer or null, got 1.5"),
    ("foreign log's config [1]", lambda t, s: lambda: __import__(
        "aoass_env.evaluation.episode", fromlist=["x"]).localize_log(
        _foreign_log(t, config=[1]), ("dv-hop",)), BeaconLogError,
     "its config must be a JSON object, got [1]"),
    ("NaN localizer checkpoint", lambda t, s: lambda: load_checkpoint(_nan_checkpoint(t)),
     CheckpointError, "nan.pt"),
    ("reset(options={'map': 42})", lambda t, s: lambda: AOASSEnv(n_nodes=5).reset(
        options={"map": 42}), ValueError, "'map'"),
    ("complex action", lambda t, s: lambda: checked_action([1 + 2j, 0]), ValueError, "action"),
]


@pytest.mark.parametrize("make, error, named", [a[1:] for a in AUDIT],
                         ids=[a[0] for a in AUDIT])
def test_every_bad_input_of_the_audit_gets_a_clear_error(tmp_path, capsys, train_script, make,
                                                         error, named):
    call = make(tmp_path, train_script)
    with pytest.raises(error) as err:
        call()
    message = capsys.readouterr().err if error is SystemExit else str(err.value)
    if error is SystemExit:
        assert err.value.code == 2
    assert named in message and "Traceback" not in message
    assert len(message.strip().splitlines()[-1]) > 0


def test_the_map_takes_its_own_size_and_time_limit():
    env = AOASSEnv(map="test/d0.10_f200_s518")
    assert env.config.field_size == 200.0
    small = AOASSEnv(n_nodes=5)
    limit = small.max_episode_steps
    small.reset(seed=0, options={"map": "test/d0.10_f200_s518"})
    assert small.sim.map.width == 200.0 and small.max_episode_steps == env.max_episode_steps
    assert small.max_episode_steps > 3 * limit


def test_numpy_scalars_in_configs_are_numbers():
    cfg = AOASSConfig(n_nodes=np.int64(7), dt=np.float32(0.5), line_of_sight=np.bool_(False))
    assert (cfg.n_nodes, cfg.dt, cfg.line_of_sight) == (7, 0.5, False)


# ---------------------------------------------------------------------------------- fuzzing
@settings(max_examples=60, deadline=None)
@given(st.dictionaries(st.sampled_from(["eval", "policy_kwargs", "batch_size", "freq",
                                        "learning_rate", "lstm_hidden_size"]),
                       st.one_of(st.integers(-5, 5), st.floats(allow_nan=True),
                                 st.text(max_size=3), st.none(),
                                 st.dictionaries(st.text(max_size=4), st.integers(-2, 2),
                                                 max_size=2)),
                       max_size=3))
def test_fuzzed_hyperparameter_sections_load_or_name_the_key(tmp_path_factory, section):
    path = tmp_path_factory.mktemp("hp") / "fuzz.yml"
    path.write_text(yaml.safe_dump({"td3-lstm": section}))
    try:
        load_hyperparams(path, "td3-lstm")
    except HyperparameterError as exc:
        assert "fuzz.yml: td3-lstm" in str(exc)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.one_of(st.floats(), st.complex_numbers(), st.integers(), st.text(max_size=2),
                          st.booleans()), max_size=3))
def test_fuzzed_actions_are_clipped_or_refused(action):
    try:
        dv, dtheta = checked_action(action)
    except ValueError:
        return
    assert -1.0 <= dv <= 1.0 and -1.0 <= dtheta <= 1.0


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(key=st.sampled_from(["nodes", "beacons", "anchor_path", "node_energy", "field"]),
       value=st.floats(allow_nan=True, allow_infinity=True, width=64))
def test_fuzzed_log_values_load_or_name_the_key(tmp_path, key, value):
    path = _log(tmp_path)
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    arrays[key] = np.full_like(arrays[key], value)
    np.savez(path, **arrays)
    try:
        log = BeaconLog.load(path)
    except BeaconLogError as exc:
        # a changed field may instead leave the recorded positions outside it
        named = {key} | ({"nodes", "beacons", "anchor_path", "obstacle_vertices"}
                         if key == "field" else set())
        assert exc.key in named and str(path) in str(exc)
    else:
        width, height = log.field
        assert np.all(np.isfinite(log.nodes)) and np.all(log.nodes <= 1.01 * max(width, height))


# ------------------------------------------------------------------------------ interrupts
def _space_interrupting_itself(steps: list[int]):
    """A pymunk space whose velocity callback sends this process a Ctrl-C at its 3rd call."""
    import os
    import signal

    import pymunk
    space = pymunk.Space()
    body = pymunk.Body(1, 1)
    space.add(body, pymunk.Circle(body, 1))

    def velocity(b, gravity, damping, dt):
        steps.append(1)
        if len(steps) == 3:
            os.kill(os.getpid(), signal.SIGINT)
        pymunk.Body.update_velocity(b, gravity, damping, dt)
    body.velocity_func = velocity
    return space


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
def test_a_ctrl_c_inside_a_pymunk_callback_is_swallowed_without_the_guard():
    """Why the guard exists: cffi reports the KeyboardInterrupt as unraisable and goes on."""
    steps: list[int] = []
    space = _space_interrupting_itself(steps)
    for _ in range(10):
        space.step(0.1)
    assert len(steps) == 10


def test_the_first_ctrl_c_stops_even_inside_a_pymunk_callback():
    import signal
    import time

    from aoass_env.backends import deliver_interrupts
    steps: list[int] = []
    space = _space_interrupting_itself(steps)
    # Python's own Ctrl-C handler, as in a terminal: a test run started in the background by a
    # non-interactive shell inherits SIGINT ignored, where deliver_interrupts does nothing
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    before_alarm = signal.signal(signal.SIGALRM, lambda *_: None)
    try:
        signal.setitimer(signal.ITIMER_REAL, 30.0)   # a timer of the caller's, set aside
        with pytest.raises(KeyboardInterrupt), deliver_interrupts():
            for _ in range(10_000):
                space.step(0.1)
                time.sleep(0.001)
        remaining, _ = signal.getitimer(signal.ITIMER_REAL)
        assert 20.0 < remaining <= 30.0              # and running again after the Ctrl-C
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, before_alarm)
        signal.signal(signal.SIGINT, before)
    assert len(steps) < 10_000


def test_deliver_interrupts_leaves_the_callers_alarm_and_timer_alone():
    """An alarm of the caller's (pytest-timeout's signal method, say) became a
    KeyboardInterrupt within deliver_interrupts, and leaving it cancelled the caller's timer."""
    import signal
    import time

    from aoass_env.backends import deliver_interrupts
    rang: list[int] = []
    before_int = signal.signal(signal.SIGINT, signal.default_int_handler)
    before_alarm = signal.signal(signal.SIGALRM, lambda *_: rang.append(1))
    try:
        signal.setitimer(signal.ITIMER_REAL, 0.05)
        with deliver_interrupts():
            time.sleep(0.2)              # the caller's alarm goes to the caller's handler
        assert rang == [1]
        signal.setitimer(signal.ITIMER_REAL, 0.3)
        with deliver_interrupts():
            time.sleep(0.01)
        remaining, _ = signal.getitimer(signal.ITIMER_REAL)
        assert 0.0 < remaining <= 0.3    # still running after the context
        time.sleep(remaining + 0.1)
        assert rang == [1, 1]
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, before_alarm)
        signal.signal(signal.SIGINT, before_int)


def test_evaluate_refuses_a_nan_localizer_checkpoint_before_any_episode(tmp_path, capsys,
                                                                         monkeypatch):
    monkeypatch.setattr(cli, "DEFAULT_CHECKPOINT", _nan_checkpoint(tmp_path))
    with pytest.raises(SystemExit) as err:
        cli.main(["--preset", "smoke", "--methods", "spiral", "--localizers", "olstm-dvhop",
                  "--out", str(tmp_path / "out"), "--no-progress"])
    message = capsys.readouterr().err
    assert err.value.code == 2 and "nan.pt" in message and "NaN" in message
    assert not (tmp_path / "out" / "episodes.csv").exists()


def test_a_replay_buffer_saved_to_a_path_is_written_whole_and_named_as_numpy_names_it(
        tmp_path, monkeypatch):
    model = RecurrentTD3.load(DEFAULT_POLICY)
    model.save_replay_buffer(tmp_path / "buffer")          # numpy's name: .npz appended
    assert sorted(p.name for p in tmp_path.iterdir()) == ["buffer.npz"]
    load_replay_buffer(model, tmp_path / "buffer.npz")
    old = (tmp_path / "buffer.npz").read_bytes()

    def crash(file, **arrays):          # half a file written, then the disk fills
        if isinstance(file, (str, os.PathLike)):
            Path(file).write_bytes(b"half")
        else:
            file.write(b"half")
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez", crash)
    with pytest.raises(OSError, match="disk full"):
        model.save_replay_buffer(tmp_path / "buffer.npz")
    assert (tmp_path / "buffer.npz").read_bytes() == old      # the old buffer, whole
    assert sorted(p.name for p in tmp_path.iterdir()) == ["buffer.npz"]
