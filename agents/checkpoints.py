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
import zlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import torch as th
from gymnasium import spaces as gym_spaces
from stable_baselines3 import TD3 as _SB3TD3

from agents.envs import make_training_env
from agents.errors import PolicyFileError
from agents.sections import (
    HyperparameterError,
    action_noise,
    check_section,
    model_kwargs,
    policy_name,
    read_yaml,
)
from aoass_env.atomic import atomic_open
from aoass_env.validators import integer, keyword_names, one_line, torch_load_problem

__all__ = ["MAX_MEMBER_BYTES", "RECORD_NAME", "STATE_FIELDS", "PolicyFileError", "SafeLoading",
           "TD3", "load_model", "read_record", "record_path", "saved_step", "validate_record"]

#: The run record that ``train.py`` writes beside its models.
RECORD_NAME = "run.yml"
#: The only entries of a model's ``data`` that are read: training counters (integers >= 0).
STATE_FIELDS = ("num_timesteps", "_n_updates", "_episode_num")
#: The largest member of a model .zip read (inflated size, bytes): far above any model here.
MAX_MEMBER_BYTES = 1 << 30
#: Weight files of a model .zip: the policy (required) and the optimizers (read to resume).
_OPTIMIZERS = ("actor.optimizer", "critic.optimizer")
#: The scalar tags of a saved replay buffer besides the buffer's own arrays: key -> (dtype
#: kinds accepted, what it must be).
_BUFFER_META = {"pos": ("iu", "an integer"), "full": ("b", "a bool"),
                "num_timesteps": ("iu", "an integer")}

#: What reading a damaged model .zip raises (zipfile, zlib and torch's many types).
_UNREADABLE_ZIP = (zipfile.BadZipFile, OSError, RuntimeError, NotImplementedError, zlib.error)

SelfSafe = TypeVar("SelfSafe", bound="SafeLoading")


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


def read_record(path: str | os.PathLike[str], cls: type) -> dict[str, Any]:
    """The run record at ``path`` of a model of class ``cls``, read safely and validated
    (:func:`validate_record`); :class:`PolicyFileError` naming the file otherwise."""
    try:
        return validate_record(read_yaml(path, "run record"), cls, path)
    except HyperparameterError as exc:
        raise PolicyFileError(str(exc)) from None


def _member(path: Path, archive: zipfile.ZipFile, name: str) -> bytes:
    """The bytes of member ``name``, refused above :data:`MAX_MEMBER_BYTES` before a byte is
    inflated (a small crafted .zip can inflate to any size)."""
    size = archive.getinfo(name).file_size
    if size > MAX_MEMBER_BYTES:
        raise PolicyFileError(f"{path}: {name}: {size} bytes once inflated, more than "
                              f"MAX_MEMBER_BYTES={MAX_MEMBER_BYTES}")
    return archive.read(name)


def _read_weights(path: Path, archive: zipfile.ZipFile, name: str, device: str) -> Any:
    member = _member(path, archive, f"{name}.pth")
    try:
        payload = th.load(io.BytesIO(member), map_location=device, weights_only=True)
    except Exception as exc:  # torch raises many types for a damaged or foreign file
        raise PolicyFileError(f"{path}: {name}.pth: not readable weights "
                              f"({torch_load_problem(exc)})") from None
    if not isinstance(payload, Mapping):
        raise PolicyFileError(f"{path}: {name}.pth: not a state dict")
    return payload


def _check_finite(path: Path, name: str, state: Mapping[str, Any]) -> None:
    for key, value in state.items():
        if isinstance(value, th.Tensor) and value.is_floating_point() \
                and not bool(th.isfinite(value).all()):
            raise PolicyFileError(f"{path}: {name}.pth: {key} holds NaN or infinite weights")


def _describe(value: Any) -> str:
    if isinstance(value, th.Tensor):
        return f"{list(value.shape)} {str(value.dtype).removeprefix('torch.')}"
    return type(value).__name__


def _fit_problem(model_state: Mapping[str, th.Tensor], file_state: Mapping[str, Any]
                 ) -> str | None:
    """Why the weights ``file_state`` do not fit ``model_state`` (tensors missing, unexpected,
    of another shape, or not floating point where the model's are), on one line; None when
    they fit."""
    def fits(key: str) -> bool:
        mine, theirs = model_state[key], file_state[key]
        return (isinstance(theirs, th.Tensor) and theirs.shape == mine.shape
                and theirs.is_floating_point() == mine.is_floating_point())

    wrong = [key for key in model_state if key in file_state and not fits(key)]
    missing = [key for key in model_state if key not in file_state]
    unexpected = [key for key in file_state if key not in model_state]
    parts = []
    if wrong:
        parts.append(f"{len(wrong)} of another shape or type, first {wrong[0]}: "
                     f"{_describe(file_state[wrong[0]])} in the file, "
                     f"{_describe(model_state[wrong[0]])} in the model")
    if missing:
        parts.append(f"{len(missing)} missing, first {missing[0]}")
    if unexpected:
        parts.append(f"{len(unexpected)} unexpected, first {unexpected[0]}")
    return f"{', '.join(parts)} (of {len(model_state)} tensors)" if parts else None


def _load_optimizer(path: Path, name: str, optimizer: th.optim.Optimizer,
                    state: Mapping[str, Any]) -> None:
    """Load the optimizer state ``state`` (from ``name``.pth) into ``optimizer``; every
    per-parameter tensor must have its parameter's shape and be finite."""
    where = f"{path}: {name}.pth"
    if not {"state", "param_groups"} <= set(state):
        raise PolicyFileError(f"{where}: not an optimizer state (it must hold 'state' and "
                              f"'param_groups')")
    try:
        optimizer.load_state_dict(state)
    except Exception as exc:  # torch raises many types for a foreign state
        raise PolicyFileError(f"{where}: not the optimizer state of this model "
                              f"({one_line(exc)})") from None
    for group in optimizer.param_groups:
        for param in group["params"]:
            for key, value in optimizer.state.get(param, {}).items():
                if not isinstance(value, th.Tensor):
                    continue
                if value.dim() > 0 and value.shape != param.shape:
                    raise PolicyFileError(f"{where}: {key}: shape {list(value.shape)}, its "
                                          f"parameter has {list(param.shape)}")
                if value.is_floating_point() and not bool(th.isfinite(value).all()):
                    raise PolicyFileError(f"{where}: {key} holds NaN or infinite values")


def _read_data(path: Path, archive: zipfile.ZipFile) -> dict[str, Any]:
    """The model's ``data`` member as JSON (its pickled entries stay unread strings)."""
    try:
        data = json.loads(_member(path, archive, "data"))
    except (KeyError, UnicodeDecodeError, json.JSONDecodeError, zlib.error) as exc:
        raise PolicyFileError(f"{path}: data: missing or not JSON ({one_line(exc)})"
                              ) from None
    if not isinstance(data, dict):
        raise PolicyFileError(f"{path}: data: must be a JSON object")
    return data


def _read_state(path: Path, data: Mapping[str, Any]) -> dict[str, int]:
    return {key: integer(f"{path}: data: {key}", data.get(key, 0), low=0, error=PolicyFileError)
            for key in STATE_FIELDS}


def _printed_array(text: Any, size: int) -> np.ndarray | None:
    """The flat array numpy printed as ``text`` ("[-2. 2.]", nested brackets for more
    dimensions), None when it does not read as ``size`` numbers (e.g. summarised by "...")."""
    try:
        values = np.array([float(t) for t in str(text).replace("[", " ").replace("]", " ")
                           .split()])
    except ValueError:
        return None
    return values if values.size == size else None


def _check_saved_spaces(path: Path, data: Mapping[str, Any], env: Any) -> None:
    """PolicyFileError unless ``env``'s Box spaces have the shapes and bounds the model was
    saved with (SB3 writes them as plain JSON beside the pickled space: ``_shape``, and
    ``low``/``high`` printed by numpy, to 8 significant digits); other spaces, and bounds that
    were printed summarised, are left to the weights' fit check."""
    for key in ("observation_space", "action_space"):
        saved, space = data.get(key), getattr(env, key)
        if not (isinstance(saved, dict) and "Box" in str(saved.get(":type:"))
                and isinstance(space, gym_spaces.Box)):
            continue
        shape = saved.get("_shape")
        if isinstance(shape, list) and tuple(shape) != space.shape:
            raise PolicyFileError(f"{path}: {key}: saved with shape {tuple(shape)}, the given "
                                  f"env's is {space}")
        for side in ("low", "high"):
            bound = _printed_array(saved.get(side), int(np.prod(space.shape)))
            own = np.asarray(getattr(space, side), dtype=np.float64).reshape(-1)
            if bound is not None and not np.allclose(bound, own, rtol=1e-6, atol=0.0):
                raise PolicyFileError(f"{path}: {key}: saved with {side} {saved[side]}, the "
                                      f"given env's is {space}: the model acts in the spaces "
                                      f"it was trained in")


def saved_step(path: str | os.PathLike[str]) -> int:
    """The step count (``num_timesteps``) a model .zip was saved at, read from its ``data``
    member alone (no weights loaded); :class:`PolicyFileError` naming the file."""
    path = Path(path)
    try:
        with zipfile.ZipFile(path) as archive:
            return _read_state(path, _read_data(path, archive))["num_timesteps"]
    except _UNREADABLE_ZIP as exc:
        raise PolicyFileError(f"{path}: not a readable model .zip ({one_line(exc)})"
                              ) from None


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
        kwargs: changes to the model, as SB3's ``load`` takes them: constructor keywords (e.g.
            ``tensorboard_log``, ``learning_rate``) go to the constructor, before the model is
            set up; other names are set as attributes. With ``env``, the record's
            ``action_noise`` is rebuilt unless one is given, as SB3's ``load`` keeps it.

    Raises:
        PolicyFileError: no such file, no record, a file that is not a model, an env whose
            spaces differ from those the model was saved with, weights that do not fit the
            record's architecture or are not finite; each names the file.
    """
    path = Path(path)
    if not path.is_file():
        raise PolicyFileError(f"{path}: no such model file")
    if record is None:
        record = record_path(path)
        if not record.is_file():
            raise PolicyFileError(f"{path}: no {RECORD_NAME} beside it: the model is rebuilt "
                                  f"from the run record that train.py writes next to it; give "
                                  f"one explicitly")
    if not isinstance(record, Mapping):
        record = read_record(record, cls)
    if record.get("algo") != cls.algo_name:
        raise PolicyFileError(f"{path}: its run record says algo {record.get('algo')!r}, not "
                              f"{cls.algo_name!r}")
    hp = record["hyperparameters"]
    if not zipfile.is_zipfile(path):
        raise PolicyFileError(f"{path}: not a model .zip (no zip structure)")
    try:
        with zipfile.ZipFile(path) as archive:
            data = _read_data(path, archive)
            state = _read_state(path, data)
            names = set(archive.namelist())
            if "policy.pth" not in names:
                raise PolicyFileError(f"{path}: policy.pth: missing (not a saved model)")
            weights = {"policy": _read_weights(path, archive, "policy", device)}
            if env is not None:
                weights.update({n: _read_weights(path, archive, n, device)
                                for n in _OPTIMIZERS if f"{n}.pth" in names})
    except _UNREADABLE_ZIP as exc:
        raise PolicyFileError(f"{path}: not a readable model .zip ({one_line(exc)})"
                              ) from None
    _check_finite(path, "policy", weights["policy"])
    if env is not None:
        _check_saved_spaces(path, data, env)
    overrides = {} if env is not None else {"buffer_size": 1}
    constructor = set(keyword_names(cls.__init__)) - {"policy", "env", "device",
                                                       "_init_setup_model"}
    changes = {k: v for k, v in kwargs.items() if k in constructor}
    if env is not None and "action_noise" not in kwargs:    # as SB3's load keeps it
        changes["action_noise"] = action_noise(hp.get("action_noise"), env.action_space.shape[0])
    model = cls(policy_name(hp, cls), None if env is None else env, device=device,
                _init_setup_model=False, **{**model_kwargs(hp), **overrides, **changes})
    if env is None:
        model.observation_space, model.action_space = _spaces(None, hp)
        model.n_envs = 1
    model._setup_model()
    policy = weights.pop("policy")
    problem = _fit_problem(model.policy.state_dict(), policy)
    if problem is not None:
        raise PolicyFileError(f"{path}: policy.pth: weights do not fit the recorded "
                              f"architecture (policy_kwargs {hp.get('policy_kwargs', {})} "
                              f"and the observation and action sizes of "
                              f"{'the given' if env is not None else 'its'} env): {problem}")
    model.policy.load_state_dict(policy, strict=True)
    for name, optimizer_state in weights.items():
        _load_optimizer(path, name, getattr(model, name.split(".")[0]).optimizer,
                        optimizer_state)
    for key, value in {**state, **{k: v for k, v in kwargs.items() if k not in changes}}.items():
        setattr(model, key, value)
    return model


#: The most bytes a member's ``.npy`` header takes (numpy pads headers to 64 or 4096 bytes).
_NPY_HEADER_BYTES = 4096


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
    if not path.is_file() and path.suffix != ".npz":
        path = path.with_name(f"{path.name}.npz")   # as save_replay_buffer named it
    buffer = model.replay_buffer
    own = {k: v for k, v in vars(buffer).items() if isinstance(v, np.ndarray)}
    if not zipfile.is_zipfile(path):    # else numpy takes it for a pickle and advises loading it
        raise PolicyFileError(f"{path}: not a replay buffer .npz (no such file, or no zip "
                              f"structure)")
    try:
        with np.load(path, allow_pickle=False) as data:
            # names and sizes before any member is read: an unknown member, or one larger than
            # the model's array it stands for, was inflated whole first (a 1 MB file holding
            # 1 GB of zeros)
            for key in data.files:
                if key not in own and key not in _BUFFER_META:
                    raise PolicyFileError(f"{path}: {key}: not an array of the model's replay "
                                          f"buffer (it holds {', '.join(own)} and "
                                          f"{', '.join(_BUFFER_META)})")
                size = data.zip.getinfo(f"{key}.npy").file_size
                most = (own[key].nbytes if key in own else 0) + _NPY_HEADER_BYTES
                if size > most:
                    raise PolicyFileError(f"{path}: {key}: {size} bytes, more than the model's "
                                          f"buffer holds ({most} with the header)")
            arrays = {k: data[k] for k in data.files}
    except PolicyFileError:
        raise
    except Exception as exc:  # zipfile, zlib and numpy raise many types for a damaged file
        raise PolicyFileError(f"{path}: not a replay buffer .npz of arrays "
                              f"({one_line(exc)})") from None
    for key in (*own, *_BUFFER_META):
        if key not in arrays:
            raise PolicyFileError(f"{path}: {key}: missing (not a replay buffer of this model)")
    for key, value in own.items():
        if arrays[key].shape != value.shape or arrays[key].dtype != value.dtype:
            raise PolicyFileError(f"{path}: {key}: shape {arrays[key].shape} {arrays[key].dtype}"
                                  f", the model's buffer holds {value.shape} {value.dtype}")
        if arrays[key].dtype.kind == "f" and not np.isfinite(arrays[key]).all():
            raise PolicyFileError(f"{path}: {key}: holds NaN or infinite values (the model's "
                                  f"transitions are finite)")
    for key, (kinds, what) in _BUFFER_META.items():
        if arrays[key].shape != () or arrays[key].dtype.kind not in kinds:
            raise PolicyFileError(f"{path}: {key}: must be {what} (a 0-d array), got shape "
                                  f"{arrays[key].shape} {arrays[key].dtype}")
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
             custom_objects: Mapping[str, Any] | None = None, force_reset: bool = True,
             **kwargs: Any) -> SelfSafe:
        """The model saved at ``path`` (see :func:`load_model`). SB3's ``custom_objects``
        (values that replace the saved ones, e.g. ``learning_rate``) are changes as ``kwargs``
        are (a keyword given both ways is refused); ``force_reset=False`` is refused: the last
        observation is not saved, so a loaded model always starts with a reset."""
        if not force_reset:
            raise ValueError("force_reset=False is not supported: the model file keeps no last "
                             "observation, so learning always starts by resetting the env")
        custom = dict(custom_objects or {})
        twice = sorted(set(custom) & set(kwargs))
        if twice:
            raise ValueError(f"{', '.join(twice)} given both in custom_objects and as a keyword: "
                             f"give each change once")
        return load_model(cls, path, env=env, record=record,
                          device="cpu" if device == "auto" else device, **custom, **kwargs)

    def save_replay_buffer(self, path: str | os.PathLike[str] | io.IOBase) -> None:
        """Write the replay buffer as an ``.npz`` (see :func:`save_replay_buffer`)."""
        save_replay_buffer(self, path)

    def load_replay_buffer(self, path: str | os.PathLike[str],
                           truncate_last_traj: bool = True) -> None:
        """Read a replay buffer ``.npz`` (see :func:`load_replay_buffer`)."""
        load_replay_buffer(self, path)


class TD3(SafeLoading, _SB3TD3):
    """SB3's feedforward TD3 (the ``--algo td3`` ablation) with :class:`SafeLoading`. A
    ``learn`` that resets the env (a resumed run, or ``reset_num_timesteps``) ends the episodes
    the replay buffer holds as truncated, so that no n-step return joins them to the new ones
    (as :class:`~agents.recurrent_td3.RecurrentTD3` starts new episodes in its buffer)."""

    algo_name = "td3"
    default_policy = "MlpPolicy"

    def _setup_learn(self, total_timesteps: int, callback: Any = None,
                     reset_num_timesteps: bool = True, tb_log_name: str = "run",
                     progress_bar: bool = False) -> tuple[int, Any]:
        resets_env = reset_num_timesteps or self._last_obs is None
        out = super()._setup_learn(total_timesteps, callback, reset_num_timesteps, tb_log_name,
                                   progress_bar)
        buffer = self.replay_buffer
        if resets_env and buffer is not None and (buffer.full or buffer.pos > 0):
            # the last stored step of each env did not end its episode, and its successor in
            # the buffer will be another episode's first: a time-limit cut (the step keeps its
            # own next observation to bootstrap from; an n-step sum stops there)
            last = (buffer.pos - 1) % buffer.buffer_size
            buffer.timeouts[last] = np.where(buffer.dones[last] > 0, buffer.timeouts[last], 1.0)
        return out
