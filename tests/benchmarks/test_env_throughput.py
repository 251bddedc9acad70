"""benchmarks/env_throughput.py: every row of the per-part profile times a part a step runs."""

from __future__ import annotations

import gymnasium as gym

from tests.benchmarks.conftest import load_benchmark


def test_every_part_of_both_profiles_is_on_the_step_path_and_restored_after():
    """A part the code no longer calls (a renamed or bypassed function) would print a row of
    zeros: each part of :data:`PARTS` and :data:`SAFE_PARTS` must exist in this tree and be
    timed at least once in 2000 random steps of AOASS-Safe-v0 (whose inner env is AOASS-v0),
    and the timers must leave the original methods in place."""
    bench = load_benchmark("env_throughput")
    parts = bench.PARTS + bench.SAFE_PARTS
    originals = {(owner, name): vars(owner).get(name) for _, owner, name in parts}
    assert all(method is not None for method in originals.values()), \
        [name for (_, name), method in originals.items() if method is None]
    env = gym.make("AOASS-Safe-v0")
    with bench.part_timers(bench.PARTS) as bare, bench.part_timers(bench.SAFE_PARTS) as safe:
        bench.throughput(env, 2_000, seed=0)
    idle = [label for table, totals in ((bench.PARTS, bare), (bench.SAFE_PARTS, safe))
            for label, _, _ in table if totals.get(label, [0.0, 0])[1] == 0]
    assert idle == []
    assert all(vars(owner)[name] is method for (owner, name), method in originals.items())
