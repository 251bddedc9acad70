"""agents.sections: the safe YAML reader's errors are one line naming the file."""

from __future__ import annotations

from pathlib import Path

import pytest

from agents.checkpoints import PolicyFileError
from agents.hyperparams import read_run_record
from agents.sections import HyperparameterError, key_value, read_yaml


@pytest.mark.parametrize("text, message", [
    ("a: [1,2\n", "not valid YAML (line 2, column 1: expected ',' or ']', but got "
                  "'<stream end>')"),
    ("a: 1\na: 2\n", "not valid YAML (line 2, column 1: key 'a' is given twice)"),
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
