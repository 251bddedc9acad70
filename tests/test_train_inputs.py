"""python train.py: path flags that are empty strings are refused (Path('') is the working
folder: an empty --out trained into it)."""

from __future__ import annotations

import pytest


@pytest.mark.parametrize("argv, message", [
    (["--out", ""], "train.py: error: argument --out: must be a path, got ''"),
    (["--log-dir", " "], "train.py: error: argument --log-dir: must be a path, got ' '"),
    (["--config", ""], "train.py: error: argument --config: must be a path, got ''"),
    (["--resume", ""], "train.py: error: argument --resume: must be a path, got ''"),
    (["localizer", "--data-dir", ""],
     "train.py localizer: error: argument --data-dir: must be a path, got ''"),
])
def test_empty_paths_are_usage_errors(train_script, capsys: pytest.CaptureFixture, argv,
                                      message: str) -> None:
    with pytest.raises(SystemExit) as exit_:
        train_script.main(argv)
    assert exit_.value.code == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == message


def test_a_missing_resume_names_the_flag(train_script, capsys: pytest.CaptureFixture,
                                         tmp_path) -> None:
    for path, end in ((tmp_path / "missing.zip", ""), (tmp_path, " (a folder)")):
        with pytest.raises(SystemExit) as exit_:
            train_script.main(["--resume", str(path), "--out", str(tmp_path / "run")])
        assert exit_.value.code == 2
        assert capsys.readouterr().err.strip().splitlines()[-1] == (
            f"train.py: error: --resume {path}: no such model file{end}")
