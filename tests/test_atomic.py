import os
import stat

import pytest

from aoass_env import atomic
from aoass_env.atomic import atomic_open, save_figure_atomic, write_text_atomic


def test_write_creates_parents_and_replaces(tmp_path):
    target = tmp_path / "a" / "b.txt"
    write_text_atomic(target, "one")
    write_text_atomic(target, "two")
    assert target.read_text() == "two"
    assert [p.name for p in target.parent.iterdir()] == ["b.txt"]


def test_crash_mid_write_keeps_old_file_and_leaves_no_temp(tmp_path):
    target = tmp_path / "log.bin"
    target.write_bytes(b"old")
    with pytest.raises(RuntimeError), atomic_open(target, "wb") as f:
        f.write(b"new, half")
        raise RuntimeError("crash")
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["log.bin"]


def test_the_file_then_its_folder_are_synced_after_the_rename(tmp_path, monkeypatch):
    events = []
    fsync, replace = os.fsync, os.replace

    def spy_fsync(fd):
        events.append("fsync folder" if stat.S_ISDIR(os.fstat(fd).st_mode) else "fsync file")
        fsync(fd)

    def spy_replace(src, dst):
        events.append("replace")
        replace(src, dst)

    monkeypatch.setattr(atomic.os, "fsync", spy_fsync)
    monkeypatch.setattr(atomic.os, "replace", spy_replace)
    write_text_atomic(tmp_path / "a.txt", "x")
    assert events == ["fsync file", "replace", "fsync folder"]
    assert (tmp_path / "a.txt").read_text() == "x"


def test_bad_mode():
    with pytest.raises(ValueError, match="mode"), atomic_open("x", "a"):
        pass


def test_a_figure_is_saved_whole_in_its_suffix_format_or_not_at_all(tmp_path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    png, pdf = tmp_path / "f" / "a.png", tmp_path / "f" / "a.pdf"
    save_figure_atomic(fig, png, dpi=20)
    save_figure_atomic(fig, pdf)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and pdf.read_bytes()[:5] == b"%PDF-"
    with pytest.raises(ValueError, match="suffix"):
        save_figure_atomic(fig, tmp_path / "f" / "noformat")

    class Failing:              # a figure whose drawing fails half-way
        def savefig(self, f, **kwargs):
            f.write(b"half")
            raise RuntimeError("draw failed")

    with pytest.raises(RuntimeError):
        save_figure_atomic(Failing(), png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"      # the old figure, whole
    assert sorted(p.name for p in png.parent.iterdir()) == ["a.pdf", "a.png"]
    plt.close(fig)


def test_folder_problem_names_what_keeps_files_out(tmp_path):
    from aoass_env.atomic import folder_problem
    assert folder_problem(tmp_path / "new" / "deeper") is None
    assert (tmp_path / "new" / "deeper").is_dir() and not list((tmp_path / "new").rglob("*.*"))
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert folder_problem(blocker / "sub") == f"{blocker} is a file, not a folder"
    assert folder_problem(blocker) == f"{blocker} is a file, not a folder"
