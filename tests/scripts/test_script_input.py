"""The scripts refuse bad input in one line naming the flag or argument, before writing."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

SCRIPTS = Path(__file__).resolve().parents[2] / "scripts"


def load(name: str):
    spec = importlib.util.spec_from_file_location(f"aoass_script_{name}", SCRIPTS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def refused(capsys, monkeypatch, name: str, *argv: str) -> str:
    """The one-line error of ``scripts/<name>.py argv`` (argparse's exit status 2)."""
    monkeypatch.setattr(sys, "argv", [f"{name}.py", *argv])
    with pytest.raises(SystemExit) as exit_:
        load(name).main()
    assert exit_.value.code == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines[-1].startswith(f"{name}.py: error: ")
    return lines[-1].removeprefix(f"{name}.py: error: ")


def test_plot_training_names_a_run_folder_without_its_log(capsys, monkeypatch, tmp_path):
    assert refused(capsys, monkeypatch, "plot_training", str(tmp_path)).startswith(
        f"RUN {tmp_path}: holds no evaluations.npz")
    np.savez(tmp_path / "evaluations.npz", other=np.zeros(2))
    assert "not an evaluation record (no 'timesteps')" in refused(
        capsys, monkeypatch, "plot_training", str(tmp_path))
    # arrays of other shapes used to fail deep in numpy or matplotlib: the training's own
    # reader checks them
    for steps, results in ((np.arange(3), np.zeros(3)), (np.arange(3), np.zeros((2, 4)))):
        np.savez(tmp_path / "evaluations.npz", timesteps=steps, results=results,
                 ep_lengths=np.zeros_like(results))
        assert refused(capsys, monkeypatch, "plot_training", str(tmp_path)).startswith(
            f"{tmp_path / 'evaluations.npz'}: not an evaluation record (timesteps int64[3]")
    np.savez(tmp_path / "evaluations.npz", timesteps=np.arange(0), results=np.zeros((0, 4)),
             ep_lengths=np.zeros((0, 4)))
    assert refused(capsys, monkeypatch, "plot_training", str(tmp_path)) == (
        f"{tmp_path / 'evaluations.npz'}: holds no evaluation yet")
    assert refused(capsys, monkeypatch, "plot_training", "--tensorboard",
                   str(tmp_path / "none")) == f"--tensorboard {tmp_path / 'none'}: not a folder"
    # rows of no episode, and steps out of order, used to plot a traceback or a zig-zag
    for steps, results, message in (
            (np.arange(3), np.zeros((3, 0)), "want k steps and k rows of at least one"),
            (np.array([10, 30, 20]), np.zeros((3, 2)), "timesteps must increase: 30 then 20")):
        np.savez(tmp_path / "evaluations.npz", timesteps=steps, results=results,
                 ep_lengths=np.zeros_like(results))
        assert message in refused(capsys, monkeypatch, "plot_training", str(tmp_path))
    # a folder above the run's event files (out/tensorboard) used to drop the panels silently
    np.savez(tmp_path / "evaluations.npz", timesteps=np.array([10, 20]),
             results=np.zeros((2, 2)), ep_lengths=np.zeros((2, 2)))
    (tmp_path / "tb" / "td3-lstm_seed0_1").mkdir(parents=True)
    assert refused(capsys, monkeypatch, "plot_training", str(tmp_path), "--tensorboard",
                   str(tmp_path / "tb")).startswith(
        f"--tensorboard {tmp_path / 'tb'}: holds none of the run's scalars (")


def test_plot_maps_names_an_unknown_map_and_an_unwritable_out(capsys, monkeypatch, tmp_path):
    assert refused(capsys, monkeypatch, "plot_maps", "no-such-map").startswith(
        "unknown map 'no-such-map'")
    blocker = tmp_path / "file"
    blocker.write_text("")
    out = blocker / "maps.png"                  # a folder that is a file: cannot be written
    assert refused(capsys, monkeypatch, "plot_maps", "train/d0.10_f100_s000", "--out",
                   str(out)) == f"--out {out}: {blocker} is a file, not a folder"
    assert blocker.read_text() == ""


def test_plot_maps_says_what_is_wrong_with_a_folder(capsys, monkeypatch, tmp_path):
    """A folder given as a map was "no such file"; a file above --out, "File exists" after the
    drawing; --out naming a folder is refused before it too."""
    assert refused(capsys, monkeypatch, "plot_maps", str(tmp_path), "--out",
                   str(tmp_path / "maps.png")).startswith(
        f"{tmp_path}: a folder, not a map file; give map files or shipped map names")
    assert refused(capsys, monkeypatch, "plot_maps", "train/d0.10_f100_s000", "--out",
                   str(tmp_path)) == f"--out {tmp_path}: is a folder; give the figure's file name"
    (tmp_path / "file").write_text("")
    out = tmp_path / "file" / "figures" / "maps.png"
    assert refused(capsys, monkeypatch, "plot_maps", "train/d0.10_f100_s000", "--out",
                   str(out)) == f"--out {out}: {tmp_path / 'file'} is a file, not a folder"
    assert not list(tmp_path.glob("*.png"))


def test_make_results_refuses_zero_workers_instead_of_running_on_all_cores(capsys, monkeypatch):
    script = load("make_results")
    monkeypatch.setattr(script, "run_presets", lambda *args: pytest.fail("the presets ran"))
    with pytest.raises(SystemExit):
        script.main(["--workers", "0"])
    assert "argument --workers: must be an integer >= 1, got '0'" in capsys.readouterr().err


def test_make_config_doc_takes_no_options(capsys):
    with pytest.raises(SystemExit):
        load("make_config_doc").main(["--out", "x"])
    assert "unrecognized arguments: --out x" in capsys.readouterr().err


def test_make_config_doc_names_a_missing_doc_and_a_doc_without_its_table(capsys, tmp_path):
    """A missing docs/config.md was a FileNotFoundError traceback, one without the table a bare
    StopIteration."""
    script = load("make_config_doc")
    script.DOC = tmp_path / "config.md"
    for text, message in ((None, f"{script.DOC}: cannot read it (No such file or directory)"),
                          ("# Config\n\nno table\n",
                           f"{script.DOC}: holds no parameter table (a line starting "
                           f"'| parameter | default') to rewrite")):
        if text is not None:
            script.DOC.write_text(text)
        with pytest.raises(SystemExit) as exit_:
            script.main([])
        assert exit_.value.code == 2
        assert capsys.readouterr().err.strip().splitlines()[-1].split(": error: ", 1)[1] == \
            message
    assert script.DOC.read_text() == "# Config\n\nno table\n"
