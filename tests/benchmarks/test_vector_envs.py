"""benchmarks/vector_envs.py: the per-environment world parts it times are on the step path, the
lock-step bound, and every setup steps the environments it names."""

from __future__ import annotations

import numpy as np
from stable_baselines3.common.vec_env import DummyVecEnv

from tests.benchmarks.conftest import load_benchmark


def test_the_world_parts_are_timed_and_restored():
    """A part the step no longer calls would count as mergeable work: each part of
    :data:`OWN_WORLD` must exist on its class and take time in a few steps, and the timers
    must leave the original methods in place."""
    bench = load_benchmark("vector_envs")
    originals = {(owner, name): vars(owner).get(name) for _, owner, name in bench.OWN_WORLD}
    assert all(method is not None for method in originals.values())
    with bench.part_timers(bench.OWN_WORLD) as totals:
        env = bench.single("AOASS-v0", 0)()
        for _ in range(30):
            bench.single_step(env, None)
        env.close()
    assert {label for label, _, _ in bench.OWN_WORLD} == {
        label for label, (seconds, calls) in totals.items() if seconds > 0 and calls > 0}
    assert all(vars(owner)[name] is method for (owner, name), method in originals.items())
    times, world = bench.single_profile("AOASS-v0", 30, seed=0)
    assert times.shape == (30,) and (times > 0).all() and 0 < world < times.sum()


def test_lockstep_bound():
    bench = load_benchmark("vector_envs")
    assert abs(bench.lockstep_bound(np.full(50, 2e-3), 3) - 3.0) < 1e-12   # equal steps: n x
    # one step in two lasts 3 times the other: E[max of 2] = 2.5, mean = 2: 2 x 2 / 2.5
    assert abs(bench.lockstep_bound(np.array([1.0, 3.0] * 50), 2) - 1.6) < 0.02


def test_vector_setups_step_every_environment():
    bench = load_benchmark("vector_envs")
    for make, step in ((bench.gym_vector("AOASS-v0", 2, "sync", 0), bench.gym_vector_step),
                       (bench.sb3_vector("AOASS-v0", 2, DummyVecEnv, 0), bench.sb3_vector_step),
                       (bench.single("AOASS-v0", 0), bench.single_step)):
        wall, cpu, done = bench._timed(make, step, steps=4, warm_up=2)
        assert done >= 4 and wall > 0 and cpu > 0
