"""benchmarks/vector_envs.py: the per-environment world parts it times are on the step path, and
every setup steps the environments it names."""

from __future__ import annotations

from stable_baselines3.common.vec_env import DummyVecEnv

from tests.benchmarks.conftest import load_benchmark


def test_the_world_parts_are_timed_and_restored():
    """A part the step no longer calls would count as mergeable work: each one of
    :data:`_OWN_WORLD` must exist and take time in a few steps, and the originals return."""
    bench = load_benchmark("vector_envs")
    originals = {(owner, name): vars(owner).get(name) for owner, name in bench._OWN_WORLD}
    assert all(method is not None for method in originals.values())
    seen = []
    for owner, name in bench._OWN_WORLD:
        method = originals[owner, name]

        def spy(*args, _method=method, _name=name, **kwargs):
            seen.append(_name)
            return _method(*args, **kwargs)
        setattr(owner, name, spy)
    try:
        total, world, rest = bench.mergeable_share("AOASS-v0", 30, seed=0)
    finally:
        for (owner, name), method in originals.items():
            setattr(owner, name, method)
    assert {name for _, name in bench._OWN_WORLD} <= set(seen)
    assert 0 < world < total and abs(world + rest - total) < 1e-6 * total
    assert all(vars(owner)[name] is method for (owner, name), method in originals.items())


def test_vector_setups_step_every_environment():
    bench = load_benchmark("vector_envs")
    for make, step in ((bench.gym_vector("AOASS-v0", 2, "sync", 0), bench.gym_vector_step),
                       (bench.sb3_vector("AOASS-v0", 2, DummyVecEnv, 0), bench.sb3_vector_step),
                       (bench.single("AOASS-v0", 0), bench.single_step)):
        wall, cpu, done = bench._timed(make, step, steps=4, warm_up=2)
        assert done >= 4 and wall > 0 and cpu > 0
