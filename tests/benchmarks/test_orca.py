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


def test_a_reference_that_answers_otherwise_ends_the_run(capsys, tmp_path, monkeypatch):
    """A mismatch was printed, and the run went on to time the two and exit 0."""
    import sys
    from pathlib import Path

    from tests.benchmarks.conftest import load_benchmark
    source = (Path(__file__).resolve().parents[2] / "aoass_env" / "safety" / "orca.py"
              ).read_text()
    wrong = tmp_path / "orca_wrong.py"
    wrong.write_text(source + "\n_orca_velocity = orca_velocity\n\n\n"
                     "def orca_velocity(*args, **kwargs):\n"
                     "    return 1.5 * _orca_velocity(*args, **kwargs)\n")
    bench = load_benchmark("orca")
    monkeypatch.setattr(sys, "argv", ["orca.py", "--reference", str(wrong), "--calls", "20",
                                      "--repeats", "1"])
    try:
        bench.main()
    except SystemExit as exit_:
        assert "velocities differ from the reference" in str(exit_.code)
    else:
        raise AssertionError("the run went on against a reference with other answers")
