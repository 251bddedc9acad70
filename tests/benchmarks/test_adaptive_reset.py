"""benchmarks/adaptive_reset.py: one timed reset per fresh map, bad flags refused."""

from __future__ import annotations

import pytest

from tests.benchmarks.conftest import load_benchmark, refused


def test_one_reset_per_fresh_map_is_timed(capsys):
    bench = load_benchmark("adaptive_reset")
    bench.main(["--maps", "1", "--densities", "0.3", "--field", "30"])
    out = capsys.readouterr().out
    assert out.startswith("AOASS-Adaptive-v0 reset") and "(sum " in out


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
