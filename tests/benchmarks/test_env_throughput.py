"""benchmarks/env_throughput.py: every row of the per-part profile times a part a step runs."""

from __future__ import annotations

import gymnasium as gym
import pytest

from tests.benchmarks.conftest import load_benchmark, refused


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


@pytest.mark.parametrize("argv, message", [
    (["--nodes", "100", "0"], "argument --nodes: must be an integer in [1, 100000], got '0'"),
    (["--field", "5"], "argument --field: must be a finite number in [10, 2000], got '5'"),
])
def test_bad_nodes_and_field_are_one_line_before_the_warm_up(monkeypatch, capsys, argv,
                                                             message):
    """They used to reach the config: a ConfigError traceback, --nodes only after the 27 s
    warm-up."""
    assert refused(monkeypatch, capsys, "env_throughput", *argv) == message


def test_a_field_too_small_for_its_episodes_is_one_line_before_the_warm_up(monkeypatch, capsys):
    """No room for the moving obstacles: a ValueError traceback from the warm-up's reset."""
    bench = load_benchmark("env_throughput")
    monkeypatch.setattr(bench, "warm_up_env", lambda *a, **k: pytest.fail("the warm-up ran"))
    assert refused(monkeypatch, capsys, "env_throughput", "--field", "10",
                   module=bench).startswith(
        f"--field 10 (density 0.2, seed {bench.WARM_UP_SEED}): could not place moving obstacle")


def test_the_repeated_seeds_resets_reuse_their_maps(monkeypatch):
    """The 'same seeds again and again' figure timed fresh maps once the generator's cache
    shrank to 4 draws (the warm-up's seed and the first passes evicted each other): every
    timed reset with given seeds must now draw no map, and more seeds than the cache holds
    are refused."""
    bench = load_benchmark("env_throughput")
    generator = bench.generator
    generator.clear_cache()
    drawn = []
    draw = generator._generate
    monkeypatch.setattr(generator, "_generate", lambda *a, **k: drawn.append(1) or draw(*a, **k))
    seeds = list(range(generator._GENERATED_MAX))
    try:
        bench.reset_ms(2 * len(seeds) + 1, seeds, obstacle_density=0.4, field_size=40.0)
    finally:
        generator.clear_cache()             # no maps of this test left to later ones
    assert len(drawn) == 1 + len(seeds)     # the warm-up's and the priming pass's, no more
    with pytest.raises(ValueError, match="cannot all reuse their maps"):
        bench.reset_ms(1, list(range(generator._GENERATED_MAX + 1)))
