"""benchmarks/orca.py: a --reference that is no ORCA module is refused in one line before the
scenes are built."""

from __future__ import annotations

from tests.benchmarks.conftest import refused


def test_a_missing_reference_is_one_line(monkeypatch, capsys, tmp_path):
    """It used to be a FileNotFoundError traceback."""
    missing = tmp_path / "orca_ref.py"
    assert refused(monkeypatch, capsys, "orca", "--reference", str(missing)) == (
        f"--reference {missing}: no such file; save one with "
        f"`git show REV:aoass_env/safety/orca.py > /tmp/orca_ref.py`")


def test_a_python_file_without_orca_is_one_line(monkeypatch, capsys, tmp_path):
    """It used to be an AttributeError traceback in the first scene."""
    other = tmp_path / "other.py"
    other.write_text("X = 1\n")
    assert refused(monkeypatch, capsys, "orca", "--reference", str(other)) == (
        f"--reference {other}: not a version of aoass_env/safety/orca.py (no orca_velocity, "
        f"StaticObstacles)")
