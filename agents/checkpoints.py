"""The agent's files, read without running code from them.

SB3's own ``load`` unpickles entries of a model's ``data`` (``":serialized:"`` cloudpickle blobs)
and its replay buffers are plain pickles: a crafted file runs any code when loaded. Here:

* a model ``.zip`` is read by hand: of ``data`` only plain JSON numbers are taken
  (:data:`STATE_FIELDS`, checked), the model is rebuilt from its validated hyperparameters (the
  ``run.yml`` that ``train.py`` writes beside it, :func:`validate_record`) and its weights are
  read with ``torch.load(weights_only=True)`` and checked finite;
* a replay buffer is an ``.npz`` of arrays, read with ``allow_pickle=False`` and checked against
  the model's buffer, and tagged with the model's step count so that a model and a buffer that
  were not saved together are refused.

:class:`SafeLoading` puts these behind SB3's ``load``, ``save_replay_buffer`` and
``load_replay_buffer`` of :class:`~agents.recurrent_td3.RecurrentTD3` and :class:`TD3`.
"""

from __future__ import annotations

import io
import json
import os
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import torch as th
from stable_baselines3 import TD3 as _SB3TD3

from agents.envs import make_training_env
from agents.sections import HyperparameterError, check_section, model_kwargs, policy_name, read_yaml
from aoass_env.atomic import atomic_open
from aoass_env.validators import integer

__all__ = ["RECORD_NAME", "STATE_FIELDS", "PolicyFileError", "SafeLoading", "TD3",
           "load_model", "record_path", "validate_record"]

#: The run record that ``train.py`` writes beside its models.
RECORD_NAME = "run.yml"
#: The only entries of a model's ``data`` that are read: training counters (integers >= 0).
STATE_FIELDS = ("num_timesteps", "_n_updates", "_episode_num")
#: Weight files of a model .zip: the policy (required) and the optimizers (read to resume).
_OPTIMIZERS = ("actor.optimizer", "critic.optimizer")
#: Arrays of a saved replay buffer besides the buffer's own arrays.
_BUFFER_META = ("pos", "full", "num_timesteps")

SelfSafe = TypeVar("SelfSafe", bound="SafeLoading")


class PolicyFileError(ValueError):
    """A model, run record or replay buffer file that cannot be used; the message names it."""


def record_path(model_path: str | os.PathLike[str]) -> Path:
    """The run record beside the model at ``model_path``."""
    return Path(model_path).with_name(RECORD_NAME)


def validate_record(record: Any, cls: type, path: str | os.PathLike[str]) -> dict[str, Any]:
    """The run record ``record`` (read from ``path``) of a model of class ``cls``, validated:
    ``algo`` and its ``hyperparameters`` (every key checked as in a hyperparameter file,
    :func:`agents.sections.check_section`; ``resumes`` lists the records of later resumes).

    Raises:
        PolicyFileError: a malformed record, naming the file and the key.
    """
    if not isinstance(record, Mapping):
        raise PolicyFileError(f"{path}: must be a mapping (a run.yml of train.py)")
    if record.get("algo") != cls.algo_name:
        raise PolicyFileError(f"{path}: algo: {record.get('algo')!r}, but this is a "
                              f"{cls.algo_name!r} model")
    try:
        hp = check_section(record.get("hyperparameters"), cls, f"{path}: hyperparameters")
    except HyperparameterError as exc:
        raise PolicyFileError(str(exc)) from None
    if not isinstance(record.get("resumes", []), list):
        raise PolicyFileError(f"{path}: resumes: must be a list of run records")
    return {**record, "hyperparameters": hp}


def _read_weights(path: Path, archive: zipfile.ZipFile, name: str, device: str) -> Any:
    try:
        payload = th.load(io.BytesIO(archive.read(f"{name}.pth")), map_location=device,
                          weights_only=True)
    except Exception as exc:  # torch raises many types for a damaged or foreign file
        raise PolicyFileError(f"{path}: {name}.pth: not readable weights ({exc})") from None
    if not isinstance(payload, Mapping):
        raise PolicyFileError(f"{path}: {name}.pth: not a state dict")
    return payload


def _check_finite(path: Path, name: str, state: Mapping[str, Any]) -> None:
    for key, value in state.items():
        if isinstance(value, th.Tensor) and value.is_floating_point() \
                and not bool(th.isfinite(value).all()):
            raise PolicyFileError(f"{path}: {name}.pth: {key} holds NaN or infinite weights")


def _read_state(path: Path, archive: zipfile.ZipFile) -> dict[str, int]:
    try:
        data = json.loads(archive.read("data"))
    except (KeyError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise PolicyFileError(f"{path}: data: missing or not JSON ({exc})") from None
    if not isinstance(data, dict):
        raise PolicyFileError(f"{path}: data: must be a JSON object")
    state = {}
    for key in STATE_FIELDS:
        state[key] = integer(f"{path}: data: {key}", data.get(key, 0), low=0,
                             error=PolicyFileError)
    return state


def _spaces(env: Any, hp: Mapping[str, Any]) -> tuple[Any, Any]:
    """Observation and action spaces: the env's, else those of the recorded training env."""
    if env is not None:
        return env.observation_space, env.action_space
    probe = make_training_env(split="validation", **hp.get("env", {}))
    spaces = probe.observation_space, probe.action_space
    probe.close()
    return spaces


def load_model(cls: type[SelfSafe], path: str | os.PathLike[str], *, env: Any = None,
               record: str | os.PathLike[str] | Mapping[str, Any] | None = None,
               device: str = "cpu", **kwargs: Any) -> SelfSafe:
    """The model of class ``cls`` saved at ``path``, read without unpickling anything.

    Args:
        path: a model .zip (SB3's layout).
        env: the environment to train on (None: predict only; the spaces then come from the
            record's training environment and the model gets a one-step replay buffer).
        record: a run record (path or validated mapping) giving the hyperparameters; default
            the run.yml beside ``path``.
        device: torch device.
        kwargs: attributes set on the model (SB3's ``load`` keywords, e.g.
            ``tensorboard_log``).

    Raises:
        PolicyFileError: no record, a file that is not a model, weights that do not fit the
            record's architecture or are not finite; each names the file.
    """
    path = Path(path)
    if record is None:
        record = record_path(path)
        if not record.is_file():
            raise PolicyFileError(f"{path}: no {RECORD_NAME} beside it: the model is rebuilt "
                                  f"from the run record that train.py writes next to it; give "
                                  f"one explicitly")
    if not isinstance(record, Mapping):
        try:
            record = validate_record(read_yaml(record, "run record"), cls, record)
        except HyperparameterError as exc:
            raise PolicyFileError(str(exc)) from None
    if record.get("algo") != cls.algo_name:
        raise PolicyFileError(f"{path}: its run record says algo {record.get('algo')!r}, not "
                              f"{cls.algo_name!r}")
    hp = record["hyperparameters"]
    if not zipfile.is_zipfile(path):
        raise PolicyFileError(f"{path}: not a model .zip (no such file, or no zip structure)")
    try:
        with zipfile.ZipFile(path) as archive:
            state = _read_state(path, archive)
            names = set(archive.namelist())
            if "policy.pth" not in names:
                raise PolicyFileError(f"{path}: policy.pth: missing (not a saved model)")
            weights = {"policy": _read_weights(path, archive, "policy", device)}
            if env is not None:
                weights.update({n: _read_weights(path, archive, n, device)
                                for n in _OPTIMIZERS if f"{n}.pth" in names})
    except (zipfile.BadZipFile, OSError, RuntimeError, NotImplementedError) as exc:
        raise PolicyFileError(f"{path}: not a readable model .zip ({exc})") from None
    _check_finite(path, "policy", weights["policy"])
    overrides = {} if env is not None else {"buffer_size": 1}
    model = cls(policy_name(hp, cls), None if env is None else env, device=device,
                _init_setup_model=False, **{**model_kwargs(hp), **overrides})
    if env is None:
        model.observation_space, model.action_space = _spaces(None, hp)
        model.n_envs = 1
    model._setup_model()
    try:
        model.policy.load_state_dict(weights.pop("policy"), strict=True)
        for name, optimizer_state in weights.items():
            getattr(model, name.split(".")[0]).optimizer.load_state_dict(optimizer_state)
    except (RuntimeError, ValueError, KeyError) as exc:
        raise PolicyFileError(f"{path}: weights do not fit the recorded architecture "
                              f"(policy_kwargs {hp.get('policy_kwargs', {})}): "
                              f"{str(exc).splitlines()[0]}") from None
    for key, value in {**state, **kwargs}.items():
        setattr(model, key, value)
    return model


def save_replay_buffer(model: Any, path: str | os.PathLike[str] | io.IOBase) -> None:
    """Write ``model``'s replay buffer as an ``.npz`` of its arrays (no pickles), tagged with the
    model's step count. A path is written atomically, with ``.npz`` appended where it lacks it
    (as :func:`numpy.savez` names it); a file object is written as it is."""
    buffer = model.replay_buffer
    arrays = {k: v for k, v in vars(buffer).items() if isinstance(v, np.ndarray)}
    tags = {"pos": np.int64(buffer.pos), "full": np.bool_(buffer.full),
            "num_timesteps": np.int64(model.num_timesteps)}
    if not isinstance(path, (str, os.PathLike)):
        np.savez(path, **arrays, **tags)
        return
    path = Path(path)
    with atomic_open(path if path.suffix == ".npz" else path.with_name(f"{path.name}.npz"),
                     "wb") as f:
        np.savez(f, **arrays, **tags)


def load_replay_buffer(model: Any, path: str | os.PathLike[str]) -> None:
    """Fill ``model``'s replay buffer from an ``.npz`` written by :func:`save_replay_buffer`
    (read with ``allow_pickle=False``; every array checked against the model's buffer).

    Raises:
        PolicyFileError: a file that is not such a buffer, one that does not fit the model, or
            one saved at another step than the model (they were not saved together).
    """
    path = Path(path)
    buffer = model.replay_buffer
    own = {k: v for k, v in vars(buffer).items() if isinstance(v, np.ndarray)}
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except Exception as exc:  # zipfile, zlib and numpy raise many types for a damaged file
        raise PolicyFileError(f"{path}: not a replay buffer .npz of arrays ({exc})") from None
    for key in (*own, *_BUFFER_META):
        if key not in arrays:
            raise PolicyFileError(f"{path}: {key}: missing (not a replay buffer of this model)")
    for key, value in own.items():
        if arrays[key].shape != value.shape or arrays[key].dtype != value.dtype:
            raise PolicyFileError(f"{path}: {key}: shape {arrays[key].shape} {arrays[key].dtype}"
                                  f", the model's buffer holds {value.shape} {value.dtype}")
    pos, steps = int(arrays["pos"]), int(arrays["num_timesteps"])
    if not 0 <= pos < buffer.buffer_size:
        raise PolicyFileError(f"{path}: pos: {pos} is outside [0, {buffer.buffer_size})")
    if steps != model.num_timesteps:
        raise PolicyFileError(f"{path}: saved at step {steps}, the model at step "
                              f"{model.num_timesteps}: they were not saved together; delete "
                              f"the buffer to resume without it")
    for key in own:
        setattr(buffer, key, arrays[key])
    buffer.pos, buffer.full = pos, bool(arrays["full"])


class SafeLoading:
    """Mixin for SB3 algorithms: ``load`` is :func:`load_model`, replay buffers are ``.npz``
    (:func:`save_replay_buffer`, :func:`load_replay_buffer`). Nothing is ever unpickled.
    A class names its ``algo_name`` (``train.py --algo``) and ``default_policy``."""

    algo_name: str
    default_policy: str

    @classmethod
    def load(cls: type[SelfSafe], path: str | os.PathLike[str], env: Any = None,
             device: str = "cpu", *, record: str | os.PathLike[str] | None = None,
             **kwargs: Any) -> SelfSafe:
        """The model saved at ``path`` (see :func:`load_model`)."""
        return load_model(cls, path, env=env, record=record,
                          device="cpu" if device == "auto" else device, **kwargs)

    def save_replay_buffer(self, path: str | os.PathLike[str] | io.IOBase) -> None:
        """Write the replay buffer as an ``.npz`` (see :func:`save_replay_buffer`)."""
        save_replay_buffer(self, path)

    def load_replay_buffer(self, path: str | os.PathLike[str],
                           truncate_last_traj: bool = True) -> None:
        """Read a replay buffer ``.npz`` (see :func:`load_replay_buffer`)."""
        load_replay_buffer(self, path)


class TD3(SafeLoading, _SB3TD3):
    """SB3's feedforward TD3 (the ``--algo td3`` ablation) with :class:`SafeLoading`."""

    algo_name = "td3"
    default_policy = "MlpPolicy"
