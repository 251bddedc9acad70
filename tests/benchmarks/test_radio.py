"""benchmarks/radio.py: a density the map generator refuses is refused in one line, and the
speed-up times both sides on the same beacons, best of the same passes, in turn."""

from __future__ import annotations

import numpy as np
import pytest

from aoass_env.maps import generate_map
from aoass_env.radio import Radio
from tests.benchmarks.conftest import load_benchmark, refused


@pytest.mark.parametrize("value", ["0.9", "-0.1", "nan"])
def test_a_density_out_of_range_is_one_line_before_the_map(monkeypatch, capsys, value):
    """It used to reach generate_map: a MapError traceback."""
    assert refused(monkeypatch, capsys, "radio", "--density", value) == (
        f"argument --density: must be a finite number in [0, 0.6], got {value!r}")


def test_both_sides_take_the_same_beacons_in_turn_and_agree(monkeypatch):
    """The reference used to run once on the first 20 beacons and the radio best of three
    on all 1000."""
    bench = load_benchmark("radio")
    rng = np.random.default_rng(545000)
    obstacle_map = generate_map(40.0, 0.3, rng)
    radio = Radio(obstacle_map.sample_free_points(60, rng), obstacle_map, 15.0)
    beacons = obstacle_map.sample_free_points(4, rng)
    log = []
    reference, receivers = bench.reference_receivers, radio.receivers
    monkeypatch.setattr(bench, "reference_receivers",
                        lambda *a: log.append(("reference", a[2])) or reference(*a))
    monkeypatch.setattr(radio, "receivers",
                        lambda p: log.append(("radio", tuple(p))) or receivers(p))
    fast, slow, got, expected = bench.compared(radio, beacons)
    points = [tuple(float(v) for v in p) for p in beacons]
    passes = [log[k * 8:(k + 1) * 8] for k in range(bench.PASSES)]
    assert len(log) == 8 * bench.PASSES == 24
    for k, one in enumerate(passes):
        first, second = ("reference", "radio") if k % 2 == 0 else ("radio", "reference")
        assert one == [(first, p) for p in points] + [(second, p) for p in points]
    assert got == expected and any(got)
    assert 0.0 < fast and 0.0 < slow
