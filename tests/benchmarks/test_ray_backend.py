"""benchmarks/ray_backend.py: bad flags are refused in one line before any sweep, and before
Ray is imported or started."""

from __future__ import annotations

import pytest

from tests.benchmarks.conftest import load_benchmark, refused


@pytest.mark.parametrize("argv, message", [
    (["--workers", "0"], "argument --workers: must be an integer >= 1, got '0'"),
    (["--seeds", "0"], "argument --seeds: must be an integer >= 1, got '0'"),
    (["--methods", "spiral", "bogus"], "--methods: unknown method(s) 'bogus'; valid: "),
    (["--preset", "robustness", "--seeds", "2000"],
     "--preset robustness with --seeds 2000: preset 'robustness' takes at most 1000 seeds"),
])
def test_bad_flags_are_one_line_before_ray(monkeypatch, capsys, argv, message):
    """--methods bogus used to fail in every episode of the local sweep (a KeyError each);
    --workers 0 in the local backend's constructor, after Ray was imported."""
    def never(*args, **kwargs):
        raise AssertionError("the benchmark went past its argument checks")

    bench = load_benchmark("ray_backend")
    for name in ("require_ray", "RayBackend", "LocalBackend", "run_jobs"):
        monkeypatch.setattr(bench, name, never)
    assert refused(monkeypatch, capsys, "ray_backend", *argv, module=bench).startswith(message)
