"""benchmarks/adaptive_reset.py: one timed reset per fresh map, beside AOASS-v0's on its own copy,
and the ratio; bad flags refused."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

from tests.benchmarks.conftest import load_benchmark, refused


def test_one_reset_per_fresh_map_is_timed_with_the_reference_and_the_ratio(capsys):
    bench = load_benchmark("adaptive_reset")
    bench.main(["--maps", "1", "--densities", "0.3", "--field", "30"])
    adaptive, plain, ratio = capsys.readouterr().out.splitlines()
    assert adaptive.startswith("AOASS-Adaptive-v0 reset") and "(sum " in adaptive
    assert plain.startswith("AOASS-v0 reset") and "(sum " in plain
    sums = [float(line.split("(sum ")[1].rstrip(")")) for line in (adaptive, plain)]
    assert ratio.startswith("ratio AOASS-Adaptive-v0 / AOASS-v0 (sums): ")
    assert float(ratio.split(": ")[1]) == pytest.approx(sums[0] / sums[1], rel=0.1, abs=0.1)


def test_each_env_resets_on_its_own_copy_of_each_map_in_turn_first(monkeypatch):
    """A map keeps what it derives: an env given the other's map would find its work done;
    and neither env always goes first."""
    bench = load_benchmark("adaptive_reset")
    maps = bench.fresh_maps(2, [0.2], 30.0)
    seen: list[tuple[str, object]] = []
    make = gymnasium.make

    def spied(env_id, **kwargs):
        env = make(env_id, **kwargs)
        reset = env.reset

        def spy(*, seed=None, options=None):
            if seed == 2:
                seen.append((env_id, options["map"]))
            return reset(seed=seed, options=options)

        env.reset = spy
        return env

    monkeypatch.setattr(bench.gym, "make", spied)
    times = bench.resets(maps, 30.0)
    assert [len(t) for t in times] == [2, 2]
    ids = [env_id for env_id, _ in seen]
    assert ids == ["AOASS-Adaptive-v0", "AOASS-v0", "AOASS-v0", "AOASS-Adaptive-v0"]
    given = [m for _, m in seen]
    assert len({id(m) for m in given}) == 4 and not any(m in maps for m in given)
    for k, fresh in enumerate(maps):
        for m in given[2 * k:2 * k + 2]:
            assert all(np.array_equal(a, b) for a, b in zip(m.polygons, fresh.polygons,
                                                            strict=True))


@pytest.mark.parametrize("argv, message", [
    (["--maps", "0"], "--maps must be an integer >= 1"),
    (["--densities", "0.9"], "--densities must lie in [0, 0.6]"),
    (["--field", "5"], "--field must lie in [20, 400] m"),
])
def test_bad_flags_are_refused_in_one_line(capsys, argv, message):
    with pytest.raises(SystemExit):
        load_benchmark("adaptive_reset").main(argv)
    assert message in capsys.readouterr().err


def test_a_field_and_density_its_episodes_cannot_start_on_is_one_line(monkeypatch, capsys):
    """No room for the moving obstacles on the fresh map: a ValueError traceback from the
    reset (after the resets timed before it)."""
    assert refused(monkeypatch, capsys, "adaptive_reset", "--maps", "2", "--densities", "0.2",
                   "0.4", "--field", "25").startswith(
        "--field 25 with --densities 0.2 0.4: could not place moving obstacle")
