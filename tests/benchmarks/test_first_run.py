"""benchmarks/first_run.py: the cold warm-up is printed as a ratio to the warm one, from the
probes' unrounded seconds (the probes themselves take minutes: replaced here)."""

from __future__ import annotations

from types import SimpleNamespace

from tests.benchmarks.conftest import load_benchmark


def test_the_ratio_is_cold_over_warm_from_unrounded_seconds(monkeypatch, capsys):
    bench = load_benchmark("first_run")
    outputs = iter(["3.2104 17.6500 0.2600\n", "2.9876 0.4400 0.3100\n"])
    calls = []

    def probe(args, **kwargs):
        calls.append(kwargs["env"]["PYTHONPATH"])
        return SimpleNamespace(stdout=next(outputs))

    monkeypatch.setattr(bench.subprocess, "run", probe)
    bench.main([])
    assert len(calls) == 2 and calls[0] == calls[1]       # the same copy, cold then warm
    imports, warm_ups, again = capsys.readouterr().out.splitlines()
    assert imports == "import aoass_env and gymnasium: 3.2 s, 3.0 s"
    assert "17.6 s with an empty numba cache" in warm_ups and "0.4 s with the cache" in warm_ups
    assert warm_ups.endswith("ratio cold / warm 40.1")     # 17.65 / 0.44, not 17.6 / 0.4
    # each process's repeat is the stepping alone: compiling 17.39 s, loading 0.13 s
    assert again.endswith("0.3 s, 0.3 s; so compiling took 17.4 s and loading the cache 0.1 s")

