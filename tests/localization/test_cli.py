"""The folder CLI prints per-log and overall RMSE, localized fraction and coverage."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from aoass_env.localization.cli import main
from aoass_env.localization.olstm import OLSTM, save_checkpoint
from tests.localization.conftest import make_log


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


def _error_line(argv: list[str], capsys) -> str:
    """The last stderr line of a run that must exit with argparse's status 2."""
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 2
    return capsys.readouterr().err.strip().splitlines()[-1]


def test_cli_errors(tmp_path, capsys) -> None:
    assert main([str(tmp_path)]) == 1
    (tmp_path / "x.npz").write_bytes(b"junk")
    assert _error_line([str(tmp_path), "--method", "dvhop"], capsys).endswith(
        f"error: {tmp_path / 'x.npz'}: not an .npz archive (no zip structure): written by "
        f"BeaconLog.save?")
    assert _error_line([str(tmp_path), "--checkpoint", str(tmp_path / "none.pt")],
                       capsys).endswith(f"error: --checkpoint {tmp_path / 'none.pt'}: no "
                                        f"localizer checkpoint there (train one with `python "
                                        f"train.py localizer`)")


def test_a_checkpoint_the_method_does_not_read_is_refused(tmp_path, small_log, capsys) -> None:
    small_log.save(tmp_path / "a.npz")
    for method in ("dvhop", "consensus"):   # the checkpoint was silently ignored
        assert _error_line([str(tmp_path), "--method", method, "--checkpoint", "m.pt"],
                           capsys).endswith(f"error: --checkpoint is read only by --method "
                                            f"olstm-dvhop, not {method}")


def test_logs_only_in_subfolders_are_pointed_at(tmp_path, small_log, capsys) -> None:
    (tmp_path / "train").mkdir()
    small_log.save(tmp_path / "train" / "a.npz")
    assert main([str(tmp_path)]) == 1
    assert capsys.readouterr().err.strip() == (
        f"no .npz logs in {tmp_path} (its subfolders hold some; pass one of them: "
        f"{tmp_path / 'train'})")


def test_a_logdir_that_is_no_folder_is_named_in_one_line(tmp_path, capsys) -> None:
    (tmp_path / "f.npz").write_bytes(b"")
    for logdir, why in ((tmp_path / "none", "no such folder"),
                        (tmp_path / "f.npz", "not a folder")):
        with pytest.raises(SystemExit) as exit_:
            main([str(logdir)])
        assert exit_.value.code == 2
        last = capsys.readouterr().err.strip().splitlines()[-1]
        assert last.endswith(f"LOGDIR {logdir}: {why}")


def test_a_broken_link_and_a_log_without_beacons_are_named_in_one_line(tmp_path, small_log,
                                                                       capsys) -> None:
    """A log whose content prepare() refuses (no beacons) was reported without its file; a
    broken link (or a log removed while the folder was read) ended in a traceback."""
    small_log.save(tmp_path / "a.npz")
    empty = make_log(np.zeros((2, 2)), np.zeros((0, 2)), [], [])
    empty.save(tmp_path / "b.npz")
    assert _error_line([str(tmp_path), "--method", "dvhop"], capsys).endswith(
        f"error: {tmp_path / 'b.npz'}: beacon log key 'beacons': the log holds no beacons: "
        f"nothing to localize from")
    (tmp_path / "b.npz").unlink()
    (tmp_path / "b.npz").symlink_to(tmp_path / "gone.npz")
    assert _error_line([str(tmp_path), "--method", "dvhop"], capsys).endswith(
        f"error: {tmp_path / 'b.npz'}: no such file (a broken link, or removed while the "
        f"folder was read)")
