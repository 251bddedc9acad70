"""SB3 callbacks of ``python train.py``: AOASS episode metrics in TensorBoard, atomic checkpoints.

* :class:`AOASSMetricsCallback` logs, per finished episode, the coverage (Eq. 18), the online
  localization RMSE, the anchor's contacts, η_traj (Eq. 19) and the mean safety intervention
  (|v* - v_des|, m/s) under ``aoass/`` (means over the episodes of each log interval).
* :func:`save_atomic` writes a model (and :class:`AtomicCheckpointCallback` periodically a model
  and its replay buffer, an ``.npz``, as a pair) to temporary files that are renamed over the
  targets: a crash mid-training leaves the previous checkpoint intact and loadable.
* :class:`SaveBestAtomically` is the ``callback_on_new_best`` of an ``EvalCallback``.
* :class:`RunEvalCallback` is SB3's ``EvalCallback`` writing ``evaluations.npz`` atomically and
  continuing the :class:`Evaluations` a run made before a resume (:func:`read_evaluations`).
"""

from __future__ import annotations

import io
import os
import zipfile
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback, EvalCallback

from aoass_env.atomic import atomic_open
from aoass_env.validators import integer, one_line

__all__ = ["AOASSMetricsCallback", "AtomicCheckpointCallback", "Evaluations", "RunEvalCallback",
           "SaveBestAtomically", "pending_buffer_path", "read_evaluations", "replay_buffer_paths",
           "save_atomic"]


def save_atomic(model: BaseAlgorithm, path: str | Path, *, replay_buffer: bool = False) -> None:
    """Save ``model`` to ``path`` (a .zip) atomically; with ``replay_buffer``, also its replay
    buffer to ``<path stem>_replay_buffer.npz`` as a pair, so that a kill at any moment leaves
    a model and a buffer of one save: the buffer is written whole beside the pair
    (:func:`pending_buffer_path`), then the model replaces the old one, then the buffer. Between
    the last two renames the pending buffer is the model's (:func:`replay_buffer_paths`). The
    buffer carries the model's step count, so that one from another save is refused at
    resume."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not (replay_buffer and getattr(model, "replay_buffer", None) is not None):
        with atomic_open(path, "wb") as f:
            model.save(f)
        return
    pending = pending_buffer_path(path)
    with atomic_open(pending, "wb") as f:
        model.save_replay_buffer(f)
    with atomic_open(path, "wb") as f:
        model.save(f)
    os.replace(pending, replay_buffer_path(path))


def replay_buffer_path(model_path: str | Path) -> Path:
    """Where :func:`save_atomic` puts the replay buffer of the model saved at ``model_path``."""
    model_path = Path(model_path)
    return model_path.with_name(f"{model_path.stem}_replay_buffer.npz")


def pending_buffer_path(model_path: str | Path) -> Path:
    """Where :func:`save_atomic` writes the next buffer of ``model_path`` before the model."""
    model_path = Path(model_path)
    return model_path.with_name(f"{model_path.stem}_replay_buffer.next.npz")


def replay_buffer_paths(model_path: str | Path) -> tuple[Path, Path]:
    """The buffers that may be the one of the model at ``model_path``, in the order to try:
    its pair's, then a pending one (a save killed between the model's rename and the
    buffer's)."""
    return replay_buffer_path(model_path), pending_buffer_path(model_path)


class AOASSMetricsCallback(BaseCallback):
    """Per-episode AOASS metrics to the logger (TensorBoard): coverage, online RMSE (m),
    contacts, η_traj and the mean safety intervention (m/s) of each finished episode."""

    def _init_callback(self) -> None:
        n = self.training_env.num_envs
        self._intervention = np.zeros(n)
        self._steps = np.zeros(n, dtype=np.int64)

    def _on_step(self) -> bool:
        infos, dones = self.locals["infos"], self.locals["dones"]
        for i, (info, done) in enumerate(zip(infos, dones, strict=True)):
            safety = info.get("safety")
            if safety is not None:
                self._intervention[i] += safety["intervention"]
                self._steps[i] += 1
            if not done:
                continue
            metrics = info.get("episode_metrics")
            if metrics is not None:
                self.logger.record_mean("aoass/coverage", metrics["coverage"])
                self.logger.record_mean("aoass/rmse_online", metrics["rmse_online"])
                self.logger.record_mean("aoass/collisions", metrics["collisions"])
                self.logger.record_mean("aoass/eta_traj", metrics["eta_traj"])
                self.logger.record_mean("aoass/path_complete", float(metrics["path_complete"]))
            if self._steps[i]:
                self.logger.record_mean("aoass/intervention",
                                        self._intervention[i] / self._steps[i])
            self._intervention[i], self._steps[i] = 0.0, 0
        return True


class AtomicCheckpointCallback(BaseCallback):
    """Every ``save_freq`` calls (env steps / n_envs), save the model to ``path`` atomically
    (and its replay buffer with ``replay_buffer``).

    The save is due at the step but written when that step is complete: at the start of the
    next rollout (or the end of training), after SB3 has stored the step's transition and run
    the round's gradient steps. Written from ``on_step`` itself, a checkpoint tagged N held
    N - 1 transitions and the updates of N - 1 steps, and each resume lost one of each."""

    def __init__(self, save_freq: int, path: str | Path, *, replay_buffer: bool = True,
                 verbose: int = 0) -> None:
        super().__init__(verbose)
        save_freq = integer("save_freq", save_freq, "steps", low=1)
        self.save_freq, self.path, self.replay_buffer = save_freq, Path(path), replay_buffer
        self._due = False

    def _on_step(self) -> bool:
        self._due = self._due or self.n_calls % self.save_freq == 0
        return True

    def _save_if_due(self) -> None:
        if self._due:
            self._due = False
            save_atomic(self.model, self.path, replay_buffer=self.replay_buffer)
            if self.verbose:
                print(f"checkpoint: {self.path} at {self.num_timesteps} steps")

    def _on_rollout_start(self) -> None:
        self._save_if_due()

    def _on_training_end(self) -> None:
        self._save_if_due()


class SaveBestAtomically(BaseCallback):
    """``callback_on_new_best`` of an ``EvalCallback``: save the new best model atomically."""

    def __init__(self, path: str | Path, verbose: int = 0) -> None:
        super().__init__(verbose)
        self.path = Path(path)

    def _on_step(self) -> bool:
        save_atomic(self.model, self.path)
        if self.verbose:
            print(f"new best model: {self.path} at {self.num_timesteps} steps")
        return True


class Evaluations(NamedTuple):
    """A run's evaluation record (``evaluations.npz``): one row per evaluation."""

    timesteps: np.ndarray   # (k,) env steps of the model evaluated
    results: np.ndarray     # (k, episodes) returns
    ep_lengths: np.ndarray  # (k, episodes) episode lengths (steps)


def read_evaluations(path: str | Path) -> Evaluations:
    """The evaluation record at ``path``, read without unpickling; ValueError naming the file
    when it is not one (unreadable, a key missing, arrays of other shapes or non-finite
    returns)."""
    try:
        data = np.load(path, allow_pickle=False)
        if not isinstance(data, np.lib.npyio.NpzFile):
            raise ValueError("an array, not an .npz archive")
        with data:
            arrays = {key: data[key] for key in Evaluations._fields if key in data.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise ValueError(f"{path}: not a readable evaluation record ({one_line(exc)})") from None
    missing = [key for key in Evaluations._fields if key not in arrays]
    if missing:
        raise ValueError(f"{path}: not an evaluation record (no {missing[0]!r})")
    found = Evaluations(**arrays)
    k = len(found.timesteps) if found.timesteps.ndim == 1 else -1
    if (k < 0 or found.results.ndim != 2 or found.results.shape[0] != k
            or (k > 0 and found.results.shape[1] == 0)
            or found.ep_lengths.shape != found.results.shape
            or not np.issubdtype(found.timesteps.dtype, np.integer)
            or not np.issubdtype(found.results.dtype, np.floating)
            or not np.isfinite(found.results).all() or (found.timesteps < 0).any()):
        raise ValueError(f"{path}: not an evaluation record (timesteps {found.timesteps.dtype}"
                         f"{list(found.timesteps.shape)}, results {found.results.dtype}"
                         f"{list(found.results.shape)}, ep_lengths "
                         f"{list(found.ep_lengths.shape)}; want k steps and k rows of at least "
                         f"one finite return)")
    if (np.diff(found.timesteps) <= 0).any():
        at = int(np.flatnonzero(np.diff(found.timesteps) <= 0)[0])
        raise ValueError(f"{path}: not an evaluation record (timesteps must increase: "
                         f"{int(found.timesteps[at])} then {int(found.timesteps[at + 1])} at "
                         f"rows {at} and {at + 1})")
    return found


class RunEvalCallback(EvalCallback):
    """SB3's ``EvalCallback`` with the run's record at ``path`` (``evaluations.npz``), written
    atomically after each evaluation, that may continue the record ``previous`` of the same
    run (a resume): its rows stay first, and a new best is an evaluation better than the best
    model's (the best model saved then stays the best of the whole run). The new best model
    (``callback_on_new_best``) is saved after the record that holds its evaluation, so a kill
    between the two leaves a record whose rows name every saved model's step. ``best_step``:
    the step the run's best model so far was saved at (a resume), whose evaluation in
    ``previous`` is the one to beat (the best of the record when it is not there). ``until``:
    the step the resumed model was saved at; the rows of ``previous`` after it, evaluations of
    steps the resume replays, leave the record (the replay evaluates them again, and the record
    stays one of increasing steps, which a later resume reads), though the best model's
    evaluation among them still is the one to beat. Other arguments as ``EvalCallback``'s
    (``log_path`` and ``best_model_save_path`` are not taken: use ``path`` and
    ``callback_on_new_best``). ``eval_seed``: the seed ``eval_env`` is reseeded with before
    every evaluation, so that every evaluation plays the same episodes
    (None: SB3's way, each evaluation going on from the last one's episodes, so that models
    were compared on different maps and nodes)."""

    def __init__(self, eval_env: Any, path: str | Path, previous: Evaluations | None = None,
                 *, best_step: int | None = None, until: int | None = None,
                 eval_seed: int | None = None, **kwargs: Any) -> None:
        super().__init__(eval_env, log_path=None, best_model_save_path=None, **kwargs)
        self.path = Path(path)
        self.eval_seed = None if eval_seed is None else integer("eval_seed", eval_seed, low=0)
        if previous is not None and len(previous.timesteps):
            means = previous.results.mean(axis=1)
            saved = previous.timesteps == best_step
            # a kill after a better evaluation's row, before its model: the saved one's counts
            self.best_mean_reward = float(means[saved].max() if saved.any() else means.max())
            kept = slice(None) if until is None else previous.timesteps <= until
            self.evaluations_timesteps = previous.timesteps[kept].tolist()
            self.evaluations_results = previous.results[kept].tolist()
            self.evaluations_length = previous.ep_lengths[kept].tolist()

    def _on_step(self) -> bool:
        # SB3 keeps its record only with a log path, and writes it there with np.savez: the
        # path is a buffer for the length of the step, whose bytes then replace the file whole;
        # it would save a new best model before that: the callback runs here, after the record
        if self.eval_seed is not None and self.eval_freq > 0 \
                and self.n_calls % self.eval_freq == 0:
            self.eval_env.seed(self.eval_seed)    # taken by evaluate_policy's reset
        on_new_best, self.callback_on_new_best = self.callback_on_new_best, None
        best = self.best_mean_reward
        self.log_path = io.BytesIO()  # type: ignore[assignment]
        try:
            go_on = super()._on_step()
            record = self.log_path.getvalue()
        finally:
            self.log_path = None
            self.callback_on_new_best = on_new_best
        if record:
            with atomic_open(self.path, "wb") as f:
                f.write(record)
        if on_new_best is not None and self.best_mean_reward > best:
            go_on = on_new_best.on_step() and go_on
        return go_on
