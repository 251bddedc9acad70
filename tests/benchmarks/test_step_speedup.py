"""benchmarks/step_speedup.py: each tree's run imports that tree and times AOASS-v0 and its
reference Pendulum-v1 in turn in its one process, and a bad commit is refused in one line (its
counts: tests/benchmarks/test_count_flags.py)."""

from __future__ import annotations

import subprocess

import pytest

from tests.benchmarks.conftest import ROOT, load_benchmark


def test_a_run_in_this_tree_times_both_envs_in_its_process():
    bench = load_benchmark("step_speedup")
    timed = bench.in_tree(ROOT, 20, 1, warm_up=1)
    assert sorted(timed) == ["AOASS-v0", "Pendulum-v1"]
    assert all(sampled > 0.0 and alone > 0.0 for sampled, alone in timed.values())


def test_the_two_envs_take_turns_seed_by_seed_after_both_warm_ups(monkeypatch):
    """Pendulum-v1 used to be timed in an interpreter of its own, after the trees' AOASS-v0."""
    bench = load_benchmark("step_speedup")
    log = []

    def seed_cpu_s(env, seed, steps, swap=False):
        log.append((env.spec.id, seed, steps, swap))
        return 1e-6 * steps, 0.5e-6 * steps

    monkeypatch.setattr(bench, "seed_cpu_s", seed_cpu_s)
    timed = bench.cpu_us_per_step(10, 3, 1)
    warm = [("AOASS-v0", bench.WARM_UP_SEED, bench.WARM_UP_STEPS, False),
            ("Pendulum-v1", bench.WARM_UP_SEED, bench.WARM_UP_STEPS, False)]
    # round 1: seeds 0 and 2 time the drawn-before pass first, seed 1 the in-the-loop one
    assert log == warm + [("Pendulum-v1", 0, 30, True), ("AOASS-v0", 0, 10, True),
                          ("AOASS-v0", 1, 10, False), ("Pendulum-v1", 1, 30, False),
                          ("Pendulum-v1", 2, 30, True), ("AOASS-v0", 2, 10, True)]
    assert timed == {"AOASS-v0": pytest.approx((1.0, 0.5)),
                     "Pendulum-v1": pytest.approx((1.0, 0.5))}


@pytest.mark.parametrize("swap", [False, True])
def test_each_pass_lands_in_its_slot_whichever_runs_first(monkeypatch, swap):
    """A clock that counts the actions drawn: only the in-the-loop pass draws while timed, so
    it takes all the time, in the first slot, in either order of the passes (their order once
    was fixed: a drift of the machine landed on the draw's cost, once negative)."""
    bench = load_benchmark("step_speedup")
    drawn = [0]

    class Space:
        def seed(self, seed):
            pass

        def sample(self):
            drawn[0] += 1
            return 0

    class Env:
        action_space = Space()

        def reset(self, seed=None):
            return None, {}

        def step(self, action):
            return None, 0.0, False, False, {}

    monkeypatch.setattr(bench.time, "process_time", lambda: float(drawn[0]))
    assert bench.seed_cpu_s(Env(), 0, 7, swap=swap) == (7.0, 0.0)


def test_a_tree_whose_aoass_env_is_not_the_one_imported_is_refused(tmp_path):
    """A folder without the package: the interpreter finds the installed one instead, and the
    run must not be reported as the folder's."""
    bench = load_benchmark("step_speedup")
    with pytest.raises(SystemExit) as refused:
        bench.in_tree(tmp_path, 1, 1, warm_up=1)
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
    timed = bench.in_tree(tmp_path, 5, 1, warm_up=1)
    assert all(sampled > 0.0 and alone > 0.0 for sampled, alone in timed.values())
