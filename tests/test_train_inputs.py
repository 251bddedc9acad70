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
