"""benchmarks/radio.py: a density the map generator refuses is refused in one line."""

from __future__ import annotations

import pytest

from tests.benchmarks.conftest import refused


@pytest.mark.parametrize("value", ["0.9", "-0.1", "nan"])
def test_a_density_out_of_range_is_one_line_before_the_map(monkeypatch, capsys, value):
    """It used to reach generate_map: a MapError traceback."""
    assert refused(monkeypatch, capsys, "radio", "--density", value) == (
        f"argument --density: must be a finite number in [0, 0.6], got {value!r}")
