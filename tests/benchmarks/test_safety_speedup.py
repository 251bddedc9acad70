"""benchmarks/safety_speedup.py: a tree's run times both envs with that tree's aoass_env (its
counts: tests/benchmarks/test_count_flags.py; the tree checks: test_step_speedup.py)."""

from __future__ import annotations

from tests.benchmarks.conftest import load_benchmark


def test_a_run_times_the_bare_env_and_the_stack(monkeypatch):
    bench = load_benchmark("safety_speedup")
    import env_throughput  # the scripts' folder is on the path (load_benchmark)

    warmed = []
    monkeypatch.setattr(env_throughput, "warm_up_env", lambda env: warmed.append(env.spec.id))
    bare, safe = bench.paired_us(20, 0)
    assert warmed == ["AOASS-Safe-v0", "AOASS-v0"]
    assert 0.0 < bare and 0.0 < safe



def test_the_gate_measure_steps_three_envs_and_forces_numpys_association_in_one(monkeypatch):
    """--gate's stack without the compiled gate must really associate by NumPy's path."""
    from aoass_env.safety.kalman import MultiTargetTracker

    bench = load_benchmark("safety_speedup")
    calls = {"compiled": 0}
    nearest = MultiTargetTracker._nearest

    def counted(self, *args):
        calls["compiled"] += 1
        return nearest(self, *args)

    monkeypatch.setattr(MultiTargetTracker, "_nearest", counted)
    bare, compiled, numpy_gate, assoc, assoc_numpy = bench.gate_us(1200, 0, chunk=200)
    assert min(bare, compiled, numpy_gate) > 0.0
    assert calls["compiled"] > 0          # the first stack's tracker took the compiled gate
    assert assoc > 0.0 and assoc_numpy > 0.0  # both stacks' associations timed
