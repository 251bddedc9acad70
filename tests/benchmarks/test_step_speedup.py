"""benchmarks/step_speedup.py: each tree's run imports that tree, and a bad commit is refused in
one line (its counts: tests/benchmarks/test_count_flags.py)."""

from __future__ import annotations

import subprocess

import pytest

from tests.benchmarks.conftest import ROOT, load_benchmark


def test_a_run_in_this_tree_times_it():
    bench = load_benchmark("step_speedup")
    sampled, alone = bench.in_tree(ROOT, "Pendulum-v1", 20, 1)
    assert sampled > 0.0 and alone > 0.0


def test_a_tree_whose_aoass_env_is_not_the_one_imported_is_refused(tmp_path):
    """A folder without the package: the interpreter finds the installed one instead, and the
    run must not be reported as the folder's."""
    bench = load_benchmark("step_speedup")
    with pytest.raises(SystemExit) as refused:
        bench.in_tree(tmp_path, "Pendulum-v1", 1, 1)
    assert str(refused.value).startswith(f"the run meant for {tmp_path} imported aoass_env from")


def test_an_unknown_commit_is_refused_in_one_line(tmp_path):
    bench = load_benchmark("step_speedup")
    with pytest.raises(SystemExit) as refused:
        bench.unpack("no-such-commit", tmp_path)
    message = str(refused.value)
    assert message.startswith("--against no-such-commit: git archive failed")
    assert "\n" not in message


def test_the_tree_before_issue_20_runs(tmp_path):
    """The earlier tree's interpreter imports this module with that tree's aoass_env: the module
    must not need anything newer (it imported argparse_number at the top, which 94e941b lacks,
    and every comparison failed)."""
    bench = load_benchmark("step_speedup")
    if subprocess.run(["git", "cat-file", "-e", "94e941b^{commit}"], cwd=ROOT,
                      capture_output=True).returncode:
        pytest.skip("needs the repository's history (94e941b)")
    bench.unpack("94e941b", tmp_path)
    sampled, alone = bench.in_tree(tmp_path, "Pendulum-v1", 5, 1)
    assert sampled > 0.0 and alone > 0.0
