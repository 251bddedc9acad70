"""agents.sections: the safe YAML reader's errors are one line naming the file."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from agents.checkpoints import PolicyFileError
from agents.hyperparams import load_hyperparams, read_run_record
from agents.sections import HyperparameterError, key_value, read_yaml


@pytest.mark.parametrize("text, message", [
    ("a: [1,2\n", "not valid YAML (line 2, column 1: expected ',' or ']', but got "
                  "'<stream end>')"),
    ("a: 1\na: 2\n", "not valid YAML (line 2, column 1: key 'a' is given twice)"),
    ("b: &b {x: 1}\nc:\n  <<: *b\n  y: 1\n  y: 2\n",
     "not valid YAML (line 5, column 3: key 'y' is given twice)"),
    # an unhashable key used to escape as a raw TypeError
    ("{[1, 2]: 3}\n", "not valid YAML (line 1, column 2: a key must be a scalar, not a list or "
                     "a mapping)"),
    ("? {a: 1}\n: 3\n", "not valid YAML (line 1, column 3: a key must be a scalar, not a list "
                       "or a mapping)"),
    ("a: b: c\n", "not valid YAML (line 1, column 5: mapping values are not allowed here)"),
    ("x: !!python/object/apply:os.system [echo]\n",
     "not valid YAML (line 1, column 4: could not determine a constructor for the tag "
     "'tag:yaml.org,2002:python/object/apply:os.system')"),
    ("a: \x00\n", "not valid YAML (character 4: unacceptable character #x0000: special "
                  "characters are not allowed)"),
])
def test_invalid_yaml_is_one_line_naming_the_file_and_the_place(tmp_path: Path, text: str,
                                                                  message: str) -> None:
    path = tmp_path / "bad.yml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(HyperparameterError) as err:
        read_yaml(path)
    assert str(err.value) == f"{path}: {message}"


def test_merge_keys_share_a_block_and_the_mapping_s_own_keys_win(tmp_path: Path) -> None:
    """``<<: *base`` used to be refused as "not valid YAML", though YAML's safe loader reads
    it; a key of the mapping itself overrides the merged one, as there."""
    path = tmp_path / "merged.yml"
    text = "base: &b {x: 1, y: [1, 2]}\nc:\n  <<: *b\n  x: 2\nd: {<<: [*b, {z: 3}]}\n"
    path.write_text(text, encoding="utf-8")
    assert read_yaml(path) == yaml.safe_load(text) == {
        "base": {"x": 1, "y": [1, 2]}, "c": {"x": 2, "y": [1, 2]},
        "d": {"x": 1, "y": [1, 2], "z": 3}}


def test_invalid_run_record_is_one_line(tmp_path: Path) -> None:
    path = tmp_path / "run.yml"
    path.write_text("algo: td3-lstm\nhyperparameters: {gamma: 0.9\n", encoding="utf-8")
    with pytest.raises(PolicyFileError) as err:
        read_run_record(path)
    assert len(str(err.value).splitlines()) == 1
    assert str(err.value).startswith(f"{path}: not valid YAML (line 3, column 1: ")


def test_key_value_yaml_error_is_one_line() -> None:
    with pytest.raises(HyperparameterError) as err:
        key_value("net_arch:[1", "--hyperparams")
    assert str(err.value) == ("--hyperparams 'net_arch:[1': the value is not valid YAML "
                              "(line 1, column 3: expected ',' or ']', but got '<stream end>')")


_TINY = {"batch_size": 4, "buffer_size": 100, "burn_in": 2, "train_length": 4,
         "policy_kwargs": {"lstm_hidden_size": 4, "net_arch": [4]},
         "env": {"field_size": 100, "densities": [0.1, 0.1], "n_nodes": 20}}


@pytest.mark.parametrize("algo, keys, message", [
    ("td3-lstm", {"gradient_steps": 0}, "td3-lstm.gradient_steps=0 would never train: must be an "
                                        "integer >= 1, or -1 (as many as the env steps "
                                        "collected)"),
    ("td3-lstm", {"policy": [1]}, "td3-lstm.policy: [1] is not one of ['MlpLstmPolicy']"),
    ("td3-lstm", {"stats_window_size": 0},
     "td3-lstm.stats_window_size=0 must be an integer in [1, inf)"),
    ("td3-lstm", {"optimize_memory_usage": 3},
     "td3-lstm.optimize_memory_usage=3 must be true or false"),
    ("td3", {"optimize_memory_usage": True}, "td3.optimize_memory_usage: true needs "
                                             "replay_buffer_kwargs.handle_timeout_termination: "
                                             "false"),
    ("td3-lstm", {"optimize_memory_usage": True,
                  "replay_buffer_kwargs": {"handle_timeout_termination": False}},
     "td3-lstm: optimize_memory_usage=True is not supported by RecurrentTD3"),
    ("td3-lstm", {"replay_buffer_kwargs": 5}, "td3-lstm.replay_buffer_kwargs: must be a "
                                              "mapping, got int"),
    ("td3-lstm", {"replay_buffer_kwargs": {"foo": 1}},
     "td3-lstm.replay_buffer_kwargs.foo: unknown key 'foo' (valid: handle_timeout_termination)"),
    ("td3-lstm", {"replay_buffer_kwargs": {"handle_timeout_termination": 3}},
     "td3-lstm.replay_buffer_kwargs.handle_timeout_termination=3 must be true or false"),
    ("td3-lstm", {"policy_kwargs": {"net_arch": 5}},
     "td3-lstm.policy_kwargs.net_arch must be a list of layer widths (integers >= 1), got 5"),
    ("td3", {"policy_kwargs": {"net_arch": {"pi": [4], "foo": [3]}}},
     "td3.policy_kwargs.net_arch must be a list of layer widths or {pi: [...], qf: [...]}, got "
     "the keys ['foo', 'pi']"),
    ("td3-lstm", {"policy_kwargs": {"net_arch": [4, 0]}},
     "td3-lstm.policy_kwargs.net_arch[1]=0 must be an integer in [1, inf) units"),
    ("td3-lstm", {"policy_kwargs": {"current_features": "no"}},
     "td3-lstm.policy_kwargs.current_features='no' must be true or false"),
    ("td3", {"policy_kwargs": {"share_features_extractor": 3}},
     "td3.policy_kwargs.share_features_extractor=3 must be true or false"),
    ("td3-lstm", {"policy_kwargs": {"activation_fn": "relu"}},
     "td3-lstm.policy_kwargs.activation_fn: must be a Python class, which a YAML file cannot "
     "name (got 'relu'); leave it out for the default"),
])
def test_bad_keys_name_the_file_and_the_key(tmp_path: Path, algo: str, keys: dict,
                                            message: str) -> None:
    section = {k: v for k, v in _TINY.items() if algo == "td3-lstm" or k not in (
        "burn_in", "train_length", "policy_kwargs")}
    path = tmp_path / "config.yml"
    path.write_text(yaml.safe_dump({algo: {**section, **keys}}), encoding="utf-8")
    with pytest.raises(HyperparameterError) as err:
        load_hyperparams(path, algo)
    assert str(err.value) == f"{path}: {message}"


def test_the_split_is_not_a_key_of_env(tmp_path: Path) -> None:
    path = tmp_path / "config.yml"
    path.write_text(yaml.safe_dump({"td3-lstm": {**_TINY, "env": {"split": "validation"}}}),
                    encoding="utf-8")
    with pytest.raises(HyperparameterError, match=r"td3-lstm\.env\.split: unknown key 'split'"):
        load_hyperparams(path, "td3-lstm")


def test_good_sections_are_unchanged(tmp_path: Path) -> None:
    keys = {"gradient_steps": -1, "replay_buffer_kwargs": {"handle_timeout_termination": False},
            "policy_kwargs": {"lstm_hidden_size": 4, "net_arch": {"pi": [4], "qf": []},
                              "current_features": False}}
    path = tmp_path / "config.yml"
    path.write_text(yaml.safe_dump({"td3-lstm": {**_TINY, **keys}}), encoding="utf-8")
    hp = load_hyperparams(path, "td3-lstm")
    assert hp == {**_TINY, **keys}


@pytest.mark.parametrize("text, value", [("1e-4", 1e-4), ("3E5", 3e5), ("-2e+3", -2e3),
                                         ("1.5e-3", 1.5e-3), ("1e3x", "1e3x"), ("e5", "e5")])
def test_exponent_floats_without_a_point_read_as_numbers(tmp_path: Path, text: str,
                                                         value: object) -> None:
    """YAML 1.1 (PyYAML) read 1e-4 as a string: learning_rate:1e-4 was refused as
    "'1e-4' must be a number"; the command line and the files read it alike now."""
    assert key_value(f"learning_rate:{text}", "--hyperparams") == ("learning_rate", value)
    path = tmp_path / "c.yml"
    path.write_text(f"learning_rate: {text}\n", encoding="utf-8")
    assert read_yaml(path) == {"learning_rate": value}
    assert yaml.safe_load("1e-4") == "1e-4"     # PyYAML's own loader is left as it was


def test_a_key_given_twice_in_a_command_line_mapping_is_refused() -> None:
    with pytest.raises(HyperparameterError, match=r"key 'a' is given twice"):
        key_value("policy_kwargs:{a: 1, a: 2}", "--hyperparams")
