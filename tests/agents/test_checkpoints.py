"""agents.checkpoints: a model .zip that cannot be used is refused in one line naming the file
and the member (weights torch refuses, weights or optimizer states of another architecture)."""

from __future__ import annotations

import io
import os
import re
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch as th
from stable_baselines3.common.env_util import make_vec_env

from agents import RecurrentTD3
from agents.checkpoints import TD3, PolicyFileError

TINY = dict(batch_size=8, burn_in=2, train_length=4, buffer_size=200,
            policy_kwargs=dict(lstm_hidden_size=4, net_arch=[4]))
RECORD = {"algo": "td3-lstm", "hyperparameters": TINY}


def _env():
    return make_vec_env("Pendulum-v1", n_envs=1, seed=0, env_kwargs=dict(max_episode_steps=20))


@pytest.fixture(scope="module")
def saved(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("model") / "model.zip"
    model = RecurrentTD3("MlpLstmPolicy", _env(), seed=0, device="cpu", learning_starts=5,
                         **TINY)
    model.learn(12)                                 # the optimizers hold Adam's moments
    model.save(path)
    return path


def _members(path: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(path) as archive:
        return {name: archive.read(name) for name in archive.namelist()}


def _torch_bytes(obj: Any) -> bytes:
    buffer = io.BytesIO()
    th.save(obj, buffer)
    return buffer.getvalue()


def _write(path: Path, members: dict[str, bytes]) -> Path:
    with zipfile.ZipFile(path, "w") as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return path


def _refusal(path: Path) -> str:
    with pytest.raises(PolicyFileError) as err:
        RecurrentTD3.load(path, env=_env(), record=RECORD)
    message = str(err.value)
    assert len(message.splitlines()) == 1, message
    assert message.startswith(f"{path}: ")
    return message


class _RunsCode:
    def __reduce__(self) -> tuple[Any, ...]:
        return (os.system, ("echo should never run",))


def test_the_saved_model_loads(saved: Path) -> None:
    assert RecurrentTD3.load(saved, env=_env(), record=RECORD).num_timesteps == 12


def test_weights_torch_refuses_are_one_line_without_torch_advice(saved: Path,
                                                                 tmp_path: Path) -> None:
    members = _members(saved)
    code = _write(tmp_path / "code.zip", {**members,
                                          "policy.pth": _torch_bytes({"x": _RunsCode()})})
    message = _refusal(code)
    assert "policy.pth: not readable weights (weights-only load refused: " in message
    assert "GLOBAL" in message and "weights_only" not in message
    garbage = _write(tmp_path / "garbage.zip", {**members, "actor.optimizer.pth": b"garbage"})
    assert _refusal(garbage).endswith(
        "actor.optimizer.pth: not readable weights (weights-only load refused: "
        "Unsupported operand 103)")
    empty = _write(tmp_path / "empty.zip", {**members, "policy.pth": b""})
    assert _refusal(empty).endswith("policy.pth: not readable weights (EOFError)")


def test_weights_of_another_architecture_name_the_first_misfit(saved: Path,
                                                               tmp_path: Path) -> None:
    members = _members(saved)
    state = th.load(io.BytesIO(members["policy.pth"]), weights_only=True)
    wider = dict(state, **{"actor.lstm.weight_ih_l0": th.zeros(16, 9)})
    message = _refusal(_write(tmp_path / "wide.zip",
                              {**members, "policy.pth": _torch_bytes(wider)}))
    assert message.endswith(
        "policy.pth: weights do not fit the recorded architecture (policy_kwargs "
        "{'lstm_hidden_size': 4, 'net_arch': [4]} and the observation and action sizes of the "
        "given env): 1 of another shape or type, first actor.lstm.weight_ih_l0: [16, 9] float32 "
        f"in the file, [16, 4] float32 in the model (of {len(state)} tensors)")
    fewer = {k: v for k, v in state.items() if not k.startswith("critic_target.")}
    fewer["extra"] = th.zeros(1)
    message = _refusal(_write(tmp_path / "fewer.zip",
                              {**members, "policy.pth": _torch_bytes(fewer)}))
    assert message.endswith(f"missing, first critic_target.lstms.0.weight_ih_l0, 1 unexpected, "
                            f"first extra (of {len(state)} tensors)")
    integers = dict(state, **{"actor.mu.0.bias": state["actor.mu.0.bias"].long()})
    message = _refusal(_write(tmp_path / "int.zip",
                              {**members, "policy.pth": _torch_bytes(integers)}))
    assert "first actor.mu.0.bias: [4] int64 in the file, [4] float32 in the model" in message


def test_optimizer_states_that_do_not_fit_are_named(saved: Path, tmp_path: Path) -> None:
    members = _members(saved)
    adam = th.load(io.BytesIO(members["actor.optimizer.pth"]), weights_only=True)
    cases = {
        "not_state": ({"foo": 1}, "actor.optimizer.pth: not an optimizer state (it must hold "
                                  "'state' and 'param_groups')"),
        "groups": ({"state": {}, "param_groups": []},
                   "actor.optimizer.pth: not the optimizer state of this model (loaded state "
                   "dict has a different number of parameter groups)"),
        "shape": ({**adam, "state": {**adam["state"], 0: {
            **adam["state"][0], "exp_avg": th.zeros(3)}}},
            "actor.optimizer.pth: exp_avg: shape [3], its parameter has [16, 4]"),
        "nan": ({**adam, "state": {**adam["state"], 0: {
            **adam["state"][0], "exp_avg_sq": adam["state"][0]["exp_avg_sq"] * float("nan")}}},
            "actor.optimizer.pth: exp_avg_sq holds NaN or infinite values"),
    }
    for name, (optimizer, end) in cases.items():
        path = _write(tmp_path / f"{name}.zip",
                      {**members, "actor.optimizer.pth": _torch_bytes(optimizer)})
        assert _refusal(path).endswith(end), name


def test_a_replay_buffer_that_is_not_an_npz_is_named(saved: Path, tmp_path: Path) -> None:
    model = RecurrentTD3.load(saved, env=_env(), record=RECORD)
    garbage = tmp_path / "buffer.npz"
    garbage.write_bytes(b"garbage")
    for path in (garbage, tmp_path / "missing.npz"):
        with pytest.raises(PolicyFileError) as err:
            model.load_replay_buffer(path)
        assert str(err.value) == (f"{path}: not a replay buffer .npz (no such file, or no zip "
                                  f"structure)")


def test_a_damaged_deflated_data_member_is_named(saved: Path, tmp_path: Path) -> None:
    """A corrupt deflate stream in ``data`` used to escape as a raw zlib.error."""
    path = tmp_path / "deflated.zip"
    with zipfile.ZipFile(path, "w") as archive:
        for name, data in _members(saved).items():
            archive.writestr(name, data, compress_type=zipfile.ZIP_DEFLATED)
    with zipfile.ZipFile(path) as archive:
        info = archive.getinfo("data")
        start = info.header_offset + 30 + len(info.filename) + len(info.extra)
    raw = bytearray(path.read_bytes())
    raw[start:start + 8] = b"\xff" * 8                # the stream, not the headers
    path.write_bytes(bytes(raw))
    assert "data: missing or not JSON (Error -3 while decompressing data" in _refusal(path)


def test_a_replay_buffer_with_bad_tags_or_values_is_named(saved: Path, tmp_path: Path) -> None:
    """Tags of another shape or type used to fail deep in numpy; NaN transitions and a
    fractional step count were taken as they were."""
    import numpy as np
    model = RecurrentTD3.load(saved, env=_env(), record=RECORD)
    good = tmp_path / "good.npz"
    model.save_replay_buffer(good)
    with np.load(good, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    steps = int(arrays["num_timesteps"])
    nan_obs = arrays["observations"].copy()
    nan_obs[0, 0, 0] = np.nan
    cases = {
        "pos": (np.array([0, 1]), r"pos: must be an integer \(a 0-d array\), got shape \(2,\) "
                                  r"int64"),
        "num_timesteps": (np.array(steps + 0.7), r"num_timesteps: must be an integer \(a 0-d "
                                                 r"array\), got shape \(\) float64"),
        "full": (np.array([True, False]), r"full: must be a bool \(a 0-d array\)"),
        "observations": (nan_obs, r"observations: holds NaN or infinite values"),
    }
    for key, (value, message) in cases.items():
        path = tmp_path / f"{key}.npz"
        np.savez(path, **{**arrays, key: value})
        with pytest.raises(PolicyFileError, match=rf"^{path}: {message}") as err:
            model.load_replay_buffer(path)
        assert len(str(err.value).splitlines()) == 1
    model.load_replay_buffer(good)
    assert model.replay_buffer.pos == int(arrays["pos"])


def test_a_replay_buffer_with_an_unknown_or_oversized_member_is_refused_unread(
        saved: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Every member was inflated before any check: a 1 MB file with 1 GB of zeros in an extra
    member took 1 GB, and the member was then ignored."""
    import numpy as np
    model = RecurrentTD3.load(saved, env=_env(), record=RECORD)
    good = tmp_path / "good.npz"
    model.save_replay_buffer(good)
    with np.load(good, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    read: list[str] = []
    getitem = np.lib.npyio.NpzFile.__getitem__
    monkeypatch.setattr(np.lib.npyio.NpzFile, "__getitem__",
                        lambda self, key: read.append(key) or getitem(self, key))
    obs = arrays["observations"]
    cases = {
        "junk": ({**arrays, "junk": np.zeros(10_000)},
                 r"junk: not an array of the model's replay buffer \(it holds "),
        "observations": ({**arrays, "observations": np.zeros((20 * len(obs), *obs.shape[1:]),
                                                              obs.dtype)},
                         rf"observations: {20 * obs.nbytes + 128} bytes, more than the model's "
                         rf"buffer holds \({obs.nbytes + 4096} with the header\)"),
    }
    for name, (members, message) in cases.items():
        path = tmp_path / f"{name}.npz"
        np.savez_compressed(path, **members)
        with pytest.raises(PolicyFileError, match=rf"^{path}: {message}"):
            model.load_replay_buffer(path)
        assert read == [], name
    model.load_replay_buffer(good)


def test_a_member_that_inflates_past_the_limit_is_refused_unread(saved: Path, tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch
                                                                ) -> None:
    from agents import checkpoints
    monkeypatch.setattr(checkpoints, "MAX_MEMBER_BYTES", 64)       # data alone is ~10 kB
    assert re.search(r": data: \d+ bytes once inflated, more than MAX_MEMBER_BYTES=64$",
                     _refusal(saved))
    with zipfile.ZipFile(saved) as archive:
        data_size = archive.getinfo("data").file_size
    monkeypatch.setattr(checkpoints, "MAX_MEMBER_BYTES", data_size)  # now the policy's turn
    assert "policy.pth: " in _refusal(saved)
    assert f"bytes once inflated, more than MAX_MEMBER_BYTES={data_size}" in _refusal(saved)


def test_a_resumed_td3_run_ends_the_stored_episodes_before_the_new_ones(tmp_path):
    """A resume resets the env: the last stored step of the saved run did not end its episode,
    and the next stored step starts another. Its n-step return (n_steps = 3) summed on into
    the new episode and bootstrapped from its observation; the step is now a time-limit cut."""
    hp = dict(n_steps=3, buffer_size=1000, learning_starts=10, batch_size=8,
              policy_kwargs=dict(net_arch=[8]))
    model = TD3("MlpPolicy", _env(), seed=0, device="cpu", **hp)
    model.learn(30)                         # the second episode is 10 steps in
    model.save(tmp_path / "td3.zip")
    model.save_replay_buffer(tmp_path / "td3_buffer.npz")
    resumed = TD3.load(tmp_path / "td3.zip", env=_env(),
                       record={"algo": "td3", "hyperparameters": hp})
    resumed.load_replay_buffer(tmp_path / "td3_buffer.npz")
    resumed.learn(10, reset_num_timesteps=False)
    buffer = resumed.replay_buffer
    assert buffer.dones[29, 0] == 0 and buffer.timeouts[29, 0] == 1
    assert not np.allclose(buffer.observations[30, 0], buffer.next_observations[29, 0])
    sample = buffer._get_samples(np.array([28]), env=None)
    np.testing.assert_allclose(sample.next_observations[0].numpy(),
                               buffer.next_observations[29, 0])
    np.testing.assert_allclose(float(sample.rewards[0]),
                               buffer.rewards[28, 0] + resumed.gamma * buffer.rewards[29, 0],
                               rtol=1e-6)


def test_load_applies_custom_objects_and_refuses_what_it_cannot_honour(saved):
    """SB3's ``custom_objects`` replace saved values (they were set as an attribute named
    custom_objects and the recorded learning rate kept); ``force_reset=False`` cannot be
    honoured (no last observation is saved) and was ignored."""
    model = RecurrentTD3.load(saved, env=_env(), record=RECORD,
                              custom_objects={"learning_rate": 0.0})
    assert model.learning_rate == 0.0 and not hasattr(model, "custom_objects")
    with pytest.raises(ValueError, match="force_reset=False is not supported"):
        RecurrentTD3.load(saved, env=_env(), record=RECORD, force_reset=False)
    with pytest.raises(ValueError, match="learning_rate given both"):
        RecurrentTD3.load(saved, env=_env(), record=RECORD, learning_rate=0.1,
                          custom_objects={"learning_rate": 0.0})
