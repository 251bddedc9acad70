"""The folder CLI prints per-log and overall RMSE, localized fraction and coverage."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from aoass_env.localization.cli import main
from aoass_env.localization.olstm import OLSTM, save_checkpoint


def test_cli_on_a_folder(tmp_path, small_log, capsys) -> None:
    small_log.save(tmp_path / "a.npz")
    small_log.save(tmp_path / "b.npz")
    assert main([str(tmp_path), "--method", "dvhop"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].split()[:2] == ["log", "nodes"] and len(lines) == 4
    assert lines[1].split()[1:] == lines[2].split()[1:]  # same log twice
    assert lines[3].split()[0] == "overall"
    torch.manual_seed(0)
    save_checkpoint(OLSTM(hidden=8), tmp_path / "m.pt", {})
    assert main([str(tmp_path), "--checkpoint", str(tmp_path / "m.pt")]) == 0
    rmse = float(capsys.readouterr().out.splitlines()[-1].split()[2])
    assert np.isfinite(rmse)


def test_cli_errors(tmp_path, capsys) -> None:
    assert main([str(tmp_path)]) == 1
    (tmp_path / "x.npz").write_bytes(b"junk")
    assert main([str(tmp_path), "--method", "dvhop"]) == 2
    assert "x.npz" in capsys.readouterr().err
    assert main([str(tmp_path), "--checkpoint", str(tmp_path / "none.pt")]) == 2


def test_a_logdir_that_is_no_folder_is_named_in_one_line(tmp_path, capsys) -> None:
    (tmp_path / "f.npz").write_bytes(b"")
    for logdir, why in ((tmp_path / "none", "no such folder"),
                        (tmp_path / "f.npz", "not a folder")):
        with pytest.raises(SystemExit) as exit_:
            main([str(logdir)])
        assert exit_.value.code == 2
        last = capsys.readouterr().err.strip().splitlines()[-1]
        assert last.endswith(f"LOGDIR {logdir}: {why}")
