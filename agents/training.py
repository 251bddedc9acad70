"""Training the AOASS agent: environments, callbacks and the run record of ``python train.py``.

The agent trains inside the full safety stack (AOASS-v0 -> Kalman tracker -> fuzzy + ORCA
filter) on the shipped training maps less a validation split, one map drawn per episode; an
``EvalCallback`` on the held-out validation maps (taken in turn) keeps the best model. The
shipped test maps are never used in training or selection. A run writes into its folder:

=========================  ===============================================================
``best.zip``               the model with the best mean evaluation return so far
``last.zip``               the latest periodic checkpoint (+ ``last_replay_buffer.npz``)
``final.zip``              the model at the end of the budget
``evaluations.npz``        SB3's evaluation record (timesteps, returns, episode lengths)
``run.yml``                the command, the hyperparameters, the seed and package versions
                           (a resume appends its own record under ``resumes``)
=========================  ===============================================================

and TensorBoard logs (SB3's metrics plus ``aoass/``) under the log folder. Every file is
written atomically (temporary files an interrupted run left behind are removed at the start);
models are read back without unpickling anything (:mod:`agents.checkpoints`).

A folder holds one run: a new run refuses a folder holding another run's files
(:func:`other_run_files`) unless told to overwrite them, which removes them first, so the
folder never pairs one run's models with another's record. A resume from a model of the
folder continues its run there: the record gains the resume, ``evaluations.npz`` keeps the
evaluations made before it, and ``best.zip`` is replaced only by a better evaluation than all.
"""

from __future__ import annotations

import dataclasses
import platform
import shlex
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import stable_baselines3
import torch
import yaml
from stable_baselines3.common.callbacks import CallbackList
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

from agents.callbacks import (
    AOASSMetricsCallback,
    AtomicCheckpointCallback,
    Evaluations,
    RunEvalCallback,
    SaveBestAtomically,
    read_evaluations,
    replay_buffer_paths,
    save_atomic,
)
from agents.checkpoints import PolicyFileError, read_record, record_path, saved_step
from agents.envs import POLICY_STACK_KEYS, TRAINING_SPLITS, make_training_env
from agents.hyperparams import ALGORITHMS, action_noise, load_hyperparams, read_run_record
from agents.sections import HyperparameterError, model_kwargs, override_section, policy_name
from aoass_env.atomic import remove_stale_temporaries, write_text_atomic
from aoass_env.data import shipped_dir
from aoass_env.validators import first_difference, integer

__all__ = ["MAX_SEED", "RUN_FILES", "TRAINING_SPLITS", "TrainRun", "make_training_env",
           "occupied_message", "other_run_files", "resume_seed", "run_hyperparams", "train_agent"]

DEFAULT_CONFIG = shipped_dir("configs") / "aoass.yml"
#: The largest run seed: SB3's ``set_random_seed`` seeds NumPy's legacy generator (32 bits).
MAX_SEED = 2**32 - 1
#: The validation env's seed is the run's plus this (reseeded before every evaluation).
EVAL_SEED_OFFSET = 1_000_000
#: The files a run writes into its folder (the table above).
RUN_FILES = ("best.zip", "last.zip", *(p.name for p in replay_buffer_paths("last.zip")),
             "final.zip", "evaluations.npz", "run.yml")


@dataclasses.dataclass
class TrainRun:
    """One training run of ``python train.py``.

    Args:
        algo: "td3-lstm" (RecurrentTD3) or "td3" (feedforward ablation).
        timesteps: env steps (None: the file's ``n_timesteps``).
        seed: seed of the model, the environments and the map draws, in [0, MAX_SEED].
        n_envs: parallel training environments (subprocesses when > 1).
        config: hyperparameter YAML file.
        resume: a saved model (.zip) to continue from (its replay buffer too, if saved beside).
        out: folder of the run's models and records (one run per folder: see ``overwrite``).
        log_dir: TensorBoard folder (None: no TensorBoard).
        progress_bar: show SB3's progress bar.
        command: the command line, recorded in run.yml.
        hyperparams: section keys replacing the file's (``--hyperparams key:value``).
        env_kwargs: keys of the section's ``env`` replacing the file's (``--env-kwargs``).
        eval_freq, eval_episodes, checkpoint_freq: env steps between evaluations, episodes
            per evaluation, env steps between checkpoints (None: the file's).
        log_interval: episodes between SB3's log rows (a last row is written at the end).
        overwrite: remove another run's files from ``out`` (:func:`other_run_files`) before
            starting; without it such a folder is refused (ValueError).
    """

    algo: str = "td3-lstm"
    timesteps: int | None = None
    seed: int = 0
    n_envs: int = 1
    config: Path = DEFAULT_CONFIG
    resume: Path | None = None
    out: Path = Path("out/train/aoass_td3_lstm")
    log_dir: Path | None = Path("out/tensorboard")
    progress_bar: bool = True
    command: str = ""
    hyperparams: dict[str, Any] = dataclasses.field(default_factory=dict)
    env_kwargs: dict[str, Any] = dataclasses.field(default_factory=dict)
    eval_freq: int | None = None
    eval_episodes: int | None = None
    checkpoint_freq: int | None = None
    log_interval: int = 4
    overwrite: bool = False

    def __post_init__(self) -> None:
        self.seed = integer("seed", self.seed, low=0, high=MAX_SEED)
        if self.algo not in ALGORITHMS:
            raise ValueError(f"algo={self.algo!r} must be one of {sorted(ALGORITHMS)}")
        if not isinstance(self.overwrite, bool):
            raise TypeError(f"overwrite must be a bool, got {self.overwrite!r}")
        self.log_interval = integer("log_interval", self.log_interval, "episodes", low=1)
        for name in ("timesteps", "n_envs", "eval_freq", "eval_episodes", "checkpoint_freq"):
            value = getattr(self, name)
            if value is not None:
                setattr(self, name, integer(name, value, low=1))
        if self.resume is not None and not Path(self.resume).is_file():
            raise ValueError(f"resume={str(self.resume)!r}: no such model file")


def env_seeds(seed: int, n_envs: int) -> list[int]:
    """Seeds of a run's ``n_envs`` training envs: ``seed`` for env 0 (a one-env run is seeded
    as SB3 seeds it) and draws of ``SeedSequence([seed, i])`` for env i > 0. SB3's ``seed + i``
    gave run S's env 1 the seed of run S + 1's env 0: runs of consecutive seeds (``--seeds``)
    played the same episodes there."""
    return [seed] + [int(np.random.SeedSequence([seed, i]).generate_state(1)[0])
                     for i in range(1, n_envs)]


class _RunSeeds:
    """A VecEnv whose ``seed(s)`` seeds its envs with :func:`env_seeds` (s, n)."""

    num_envs: int

    def seed(self, seed: int | None = None) -> list[int | None]:
        if seed is None:                      # SB3's own: a random base for every env
            return super().seed(None)  # type: ignore[misc]
        self._seeds = env_seeds(int(seed), self.num_envs)
        return list(self._seeds)


class _RunDummyVecEnv(_RunSeeds, DummyVecEnv):
    pass


class _RunSubprocVecEnv(_RunSeeds, SubprocVecEnv):
    pass


def _vec_env(n_envs: int, seed: int, env_kwargs: dict[str, Any]) -> Any:
    return make_vec_env(make_training_env, n_envs=n_envs, seed=seed, env_kwargs=env_kwargs,
                        vec_env_cls=_RunDummyVecEnv if n_envs == 1 else _RunSubprocVecEnv)


def _continues(run: TrainRun) -> bool:
    """Does ``run`` resume a model of its own folder (continuing that folder's run)?"""
    return run.resume is not None and Path(run.resume).resolve().parent == Path(run.out).resolve()


def other_run_files(run: TrainRun) -> list[str]:
    """The files of :data:`RUN_FILES` that another run left in ``run.out`` (none when ``run``
    resumes a model of that folder: its files are the run's own)."""
    out = Path(run.out)
    if _continues(run) or not out.is_dir():
        return []
    return [name for name in RUN_FILES if (out / name).exists()]


def occupied_message(run: TrainRun, files: list[str]) -> str:
    """Why ``run`` may not write into its folder, which holds ``files`` of another run."""
    resume = (f", --resume {Path(run.out) / 'last.zip'} to continue it"
              if "last.zip" in files and run.resume is None else "")
    return (f"{run.out}: holds another run's files ({', '.join(files)}); give another --out"
            f"{resume}, or --overwrite to replace them")


def _previous_evaluations(run: TrainRun, episodes: int) -> Evaluations | None:
    """The evaluations ``run`` continues (its folder's, when it resumes a model of the
    folder); PolicyFileError when they cannot be read or hold another number of episodes
    per evaluation than ``episodes``."""
    path = Path(run.out) / "evaluations.npz"
    if not (_continues(run) and path.is_file()):
        return None
    try:
        found = read_evaluations(path)
    except ValueError as exc:
        raise PolicyFileError(f"{exc}; the resume continues it: move it aside, or resume into "
                              f"another --out") from None
    held = found.results.shape[1]
    if len(found.timesteps) and held != episodes:
        raise PolicyFileError(
            f"{path}: the run's evaluations are of {held} episode{'s' * (held != 1)} each, "
            f"this resume's of {episodes}; continue them with --eval-episodes {held}, or "
            f"resume into another --out")
    return found


def run_hyperparams(run: TrainRun) -> dict[str, Any]:
    """The hyperparameters of ``run``: its file's section with the command line's overrides,
    validated (:class:`~agents.sections.HyperparameterError` naming the flag or the key)."""
    hp = load_hyperparams(run.config, run.algo)
    hyperparams = dict(run.hyperparams)
    if run.checkpoint_freq is not None:
        hyperparams["checkpoint_freq"] = run.checkpoint_freq
    evaluation = {key: value for key, value in (("freq", run.eval_freq),
                                                ("episodes", run.eval_episodes))
                  if value is not None}
    if evaluation:
        hyperparams["eval"] = {**hp.get("eval", {}), **hyperparams.get("eval", {}),
                               **evaluation}
    if hyperparams or run.env_kwargs:
        hp = override_section(hp, ALGORITHMS[run.algo],
                              f"the command line's overrides over {run.config}: {run.algo}",
                              hyperparams=hyperparams, env=run.env_kwargs)
    train_freq = hp.get("train_freq")
    if run.n_envs > 1 and isinstance(train_freq, list) and train_freq[1] == "episode":
        # SB3 asserts this deep inside learn(), after run.yml is written
        raise HyperparameterError(f"train_freq: {train_freq} counts episodes, which SB3 does "
                                  f"with one environment only, not --n-envs {run.n_envs}; give "
                                  f"train_freq in steps, or --n-envs 1")
    return hp


def train_agent(run: TrainRun, report: Any = print) -> Path:
    """Train (or resume) the agent of ``run``; returns the path of the final model."""
    hp = run_hyperparams(run)
    cls = ALGORITHMS[run.algo]
    others = other_run_files(run)
    if others and not run.overwrite:
        raise ValueError(occupied_message(run, others))
    if run.resume is not None:      # the record the model is rebuilt from, read once
        record = _resume_record(Path(run.resume), hp, cls)
        recorded = _record_seed(record, record_path(run.resume))
        if recorded is not None and recorded != run.seed:
            raise PolicyFileError(
                f"{run.resume}: its run was trained with seed {recorded} "
                f"({record_path(run.resume)}), not this run's {run.seed}: a resume continues "
                f"the run's seed (its validation episodes and the seeds drawn from it); give "
                f"--seed {recorded}, or no --seed")
    timesteps = run.timesteps or int(hp.get("n_timesteps", 100_000))
    env_kwargs = dict(hp.get("env", {}))
    evaluation = dict(hp.get("eval", {}))
    eval_episodes = int(evaluation.get("episodes", 4))
    previous = _previous_evaluations(run, eval_episodes)
    env = _vec_env(run.n_envs, run.seed, env_kwargs)
    eval_seed = run.seed + EVAL_SEED_OFFSET
    eval_env = _vec_env(1, eval_seed,
                        {**env_kwargs, "split": "validation", "cycle": True})
    noise = action_noise(hp.get("action_noise"), env.action_space.shape[0])
    tb = str(run.log_dir) if run.log_dir is not None else None
    out = Path(run.out)
    out.mkdir(parents=True, exist_ok=True)
    for stale in remove_stale_temporaries(out):
        report(f"removed {stale}, left by an interrupted write")

    if run.resume is not None:
        # rebuilt from its run.yml (else this run's hyperparameters), nothing unpickled
        model = cls.load(run.resume, env=env, tensorboard_log=tb, device="cpu", record=record)
        model.action_noise = noise
        # the random state of the run at the saved step is not in the model: seed everything
        # (Python, NumPy, torch, the action space, the training envs' next maps) from the run's
        # seed and that step, so that the same resume gives the same run, and the envs do not
        # draw the run's first maps again
        model.set_random_seed(resume_seed(run.seed, model.num_timesteps))
        buffer = _load_buffer(model, run.resume)
        kept = 0 if previous is None else len(previous.timesteps)
        continued = f", continuing the run's evaluations ({kept} so far)" if kept else ""
        report(f"resumed {run.resume} at {model.num_timesteps} steps"
               f"{' with its replay buffer' if buffer is not None else ''}{continued}")
    else:
        model = cls(policy_name(hp, cls), env, action_noise=noise, tensorboard_log=tb,
                    seed=run.seed, device="cpu", verbose=0, **model_kwargs(hp))
    if others:    # run.overwrite: another run's files, removed once the model (and the
        # resumed one's replay buffer) loaded, so that a refused resume leaves them
        for name in others:
            (out / name).unlink()
        report(f"removed another run's files from {out} (overwrite): {', '.join(others)}")

    n = run.n_envs
    checkpoint_every = max(int(hp.get("checkpoint_freq", 10_000)) // n, 1)
    callbacks = [AOASSMetricsCallback(),
                 AtomicCheckpointCallback(checkpoint_every, out / "last.zip"),
                 RunEvalCallback(eval_env, out / "evaluations.npz", previous,
                                 best_step=(saved_step(out / "best.zip") if previous is not None
                                            and (out / "best.zip").is_file() else None),
                                 until=model.num_timesteps if previous is not None else None,
                                 eval_seed=eval_seed, n_eval_episodes=eval_episodes,
                                 eval_freq=max(int(evaluation.get("freq", 10_000)) // n, 1),
                                 deterministic=True, verbose=0,
                                 callback_on_new_best=SaveBestAtomically(out / "best.zip"))]
    _write_record(out / "run.yml", run, hp, timesteps)
    report(f"training {timesteps} steps; the run's models go to {out}")
    model.learn(timesteps, callback=CallbackList(callbacks), progress_bar=run.progress_bar,
                tb_log_name=f"{run.algo}_seed{run.seed}", log_interval=run.log_interval,
                reset_num_timesteps=run.resume is None)
    # a last row, so that a run shorter than log_interval episodes still logs its scalars
    model.logger.record("time/total_timesteps", model.num_timesteps)
    model.logger.dump(model.num_timesteps)
    final = out / "final.zip"
    save_atomic(model, final)
    env.close()
    eval_env.close()
    report(f"trained {model.num_timesteps} steps; models in {out}")
    return final


def run_seed(resume: Path | None, seed: int | None) -> int:
    """The seed of a run: ``seed``; for a resume without one, the seed of the run it resumes
    (the ``run.yml`` beside ``resume``; 0 without a record). A differing ``seed`` is refused by
    :func:`train_agent`."""
    if seed is not None:
        return seed
    if resume is None or not record_path(resume).is_file():
        return 0
    path = record_path(resume)
    recorded = _record_seed(read_run_record(path), path)
    return 0 if recorded is None else recorded


def _record_seed(record: dict[str, Any], path: Path) -> int | None:
    """The ``seed`` of a run record (None for a record without one); a value that is not a
    seed is a :class:`PolicyFileError` naming the file."""
    seed = record.get("seed")
    if seed is None:
        return None
    try:
        return integer("seed", seed, low=0, high=MAX_SEED)
    except (TypeError, ValueError) as exc:
        raise PolicyFileError(f"{path}: {exc}") from None


def resume_seed(seed: int, step: int) -> int:
    """The seed of a run of ``seed`` resumed at ``step`` (a 32-bit integer)."""
    return int(np.random.SeedSequence([seed, step]).generate_state(1)[0])


def _load_buffer(model: Any, path: Path) -> Path | None:
    """Fill ``model``'s replay buffer from the buffer saved with it at ``path`` (its pair's,
    else one a killed save left pending, :func:`~agents.callbacks.replay_buffer_paths`);
    the buffer loaded, or None without one. A buffer of another save is a
    :class:`PolicyFileError` (the pair's refusal, when no pending one fits either)."""
    refusal = None
    for buffer in replay_buffer_paths(path):
        if buffer.is_file():
            try:
                model.load_replay_buffer(buffer)
                return buffer
            except PolicyFileError as exc:
                refusal = refusal or exc
    if refusal is not None:
        raise refusal
    return None


def _resume_record(model: Path, hp: dict[str, Any], cls: type) -> dict[str, Any]:
    """The validated run record ``model`` is rebuilt from: the run.yml beside it, else this
    run's hyperparameters ``hp``. The model's keywords come from that record, so this run's
    (``--config``, ``--hyperparams``) would be ignored while its record listed them: those that
    differ from the record's are a :class:`PolicyFileError` naming the first."""
    record = record_path(model)
    if not record.is_file():
        return {"algo": cls.algo_name, "hyperparameters": hp}
    found = read_record(record, cls)
    recorded = found["hyperparameters"]
    mine, theirs = model_kwargs(hp), model_kwargs(recorded)
    mine["policy"], theirs["policy"] = policy_name(hp, cls), policy_name(recorded, cls)
    # the stack the policy acts in too: its record is what evaluate.py plays the policy in
    mine.update({f"env.{k}": v for k, v in hp.get("env", {}).items() if k in POLICY_STACK_KEYS})
    theirs.update({f"env.{k}": v for k, v in recorded.get("env", {}).items()
                   if k in POLICY_STACK_KEYS})
    differ = first_difference(theirs, mine)
    if differ is not None:
        key, was, this, others = differ
        more = f" (and {len(others)} more: {', '.join(others)})" if others else ""
        raise PolicyFileError(
            f"{model}: a resume rebuilds the model and its stack from {record}, where {key} is "
            f"{was}, not this run's {this}{more}; give the --config, --hyperparams and "
            f"--env-kwargs it was trained with (its command: {found.get('command', '?')}), or "
            f"start a new run")
    return found


def _relative(path: Path) -> str:
    """``path`` relative to the working folder when it lies inside it."""
    path = Path(path).resolve()
    return str(path.relative_to(Path.cwd())) if path.is_relative_to(Path.cwd()) else str(path)


def _write_record(path: Path, run: TrainRun, hp: dict[str, Any], timesteps: int) -> None:
    """Write the run record; a resume appends its own record to the ``resumes`` list of the
    run.yml already in the folder (the first run's record stays as it was)."""
    record = {
        "command": run.command or " ".join(shlex.quote(a) for a in sys.argv),
        "algo": run.algo, "timesteps": timesteps, "seed": run.seed, "n_envs": run.n_envs,
        "config_file": _relative(run.config),
        "resume": _relative(run.resume) if run.resume else None,
        "hyperparameters": hp,
        "versions": {"python": platform.python_version(), "torch": str(torch.__version__),
                     "stable_baselines3": stable_baselines3.__version__,
                     "gymnasium": gym.__version__},
    }
    if run.resume is not None and path.is_file():
        first = read_run_record(path)
        record = {**first, "resumes": [*first.get("resumes", []), record]}
    write_text_atomic(path, yaml.safe_dump(record, sort_keys=False))
