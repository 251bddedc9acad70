"""The scalar-trig probe (aoass_env.trig) shared by the float paths."""

from __future__ import annotations

import math
import sys

import numba
import numpy as np
import pytest

from aoass_env import trig, world
from aoass_env.safety import lookahead, unicycle


def test_every_float_path_reads_the_one_probe():
    assert isinstance(trig.SCALAR_TRIG, bool)
    assert lookahead.SCALAR_TRIG is unicycle.SCALAR_TRIG is world.SCALAR_TRIG is trig.SCALAR_TRIG


@pytest.mark.skipif(not trig.SCALAR_TRIG, reason="math's cos/sin differ from NumPy's here")
def test_a_passed_probe_holds_on_other_angles():
    """Angles the probe did not see (the rays' and arcs' ranges, huge ones): equal bits."""
    angles = np.concatenate([np.random.default_rng(1).uniform(-50.0, 50.0, 20000),
                             np.random.default_rng(2).uniform(-1e6, 1e6, 2000),
                             2.0 * math.pi * np.arange(64) / 64])
    assert np.cos(angles).tolist() == [math.cos(a) for a in angles.tolist()]
    assert np.sin(angles).tolist() == [math.sin(a) for a in angles.tolist()]


def test_a_passed_compiled_probe_holds_on_other_angles():
    """compiled_trig() is a bool, probed once; when it holds, numba's cos and sin give math's
    floats on angles the probe did not see."""
    assert isinstance(trig.compiled_trig(), bool)
    if not trig.compiled_trig():
        pytest.skip("numba's cos/sin differ from math's here")
    angles = np.concatenate([np.random.default_rng(3).uniform(-50.0, 50.0, 20000),
                             np.random.default_rng(4).uniform(-1e6, 1e6, 2000)])
    cos, sin = trig._compiled_cos_sin(angles)
    assert cos.tolist() == [math.cos(a) for a in angles.tolist()]
    assert sin.tolist() == [math.sin(a) for a in angles.tolist()]


@numba.njit
def _hypots(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    out = np.empty(len(x))
    for i in range(len(x)):
        out[i] = trig.hypot(x[i], y[i])
    return out


@pytest.mark.skipif(sys.version_info < (3, 11),
                    reason="math.hypot is correctly rounded since Python 3.11 only")
def test_the_compiled_hypot_is_pythons():
    """Random pairs over 24 decades, exact sides, zeros, subnormals, huge and infinite sides."""
    rng = np.random.default_rng(11)
    scale = 10.0 ** rng.uniform(-12.0, 12.0, (300_000, 1))
    pairs = rng.normal(0.0, 1.0, (300_000, 2)) * scale
    pairs[:, 1] *= rng.uniform(0.0, 1.0, 300_000) ** 4
    special = [[3.0, 4.0], [0.0, 0.0], [-0.0, 5.0], [5e-324, 5e-324], [1e-310, 3e-310],
               [1e308, 1e308], [math.inf, math.nan], [math.nan, 1.0], [-math.inf, 2.0],
               [1.0, 1e-9], [1.0, 2.0 ** -30], [1.0, 2.0 ** -31], [0.1, 0.2]]
    pairs = np.concatenate([np.array(special), pairs])
    got = _hypots(pairs[:, 0], pairs[:, 1]).tolist()
    want = [math.hypot(x, y) for x, y in pairs.tolist()]
    assert [g if g == g else "nan" for g in got] == [w if w == w else "nan" for w in want]


def test_a_passed_polar_probe_holds_on_other_pairs():
    """compiled_polar() is a bool, probed once; when it holds, numba's atan2 and the compiled
    hypot give math's floats, signed zeros included, on pairs the probe did not see."""
    assert isinstance(trig.compiled_polar(), bool)
    if not trig.compiled_polar():
        pytest.skip("numba's atan2 or the compiled hypot differ from math's here")
    rng = np.random.default_rng(5)
    y, x = (rng.normal(0.0, 1.0, (2, 20000)) * 10.0 ** rng.uniform(-8.0, 8.0, 20000))
    y[:50], x[50:100] = 0.0, -0.0
    angle, norm = trig._compiled_polar(y.copy(), x.copy())
    pairs = list(zip(y.tolist(), x.tolist(), strict=True))
    assert np.array_equal(angle.view(np.int64),
                          np.array([math.atan2(a, b) for a, b in pairs]).view(np.int64))
    assert norm.tolist() == [math.hypot(b, a) for a, b in pairs]


def test_the_polar_probe_fails_on_one_unit_in_the_last_place(monkeypatch):
    """One angle of the probe's 8 202 off by one unit in the last place, or one norm: the probe
    says no (asked only where it says yes unperturbed: elsewhere this could not fail)."""
    if not trig.compiled_polar():
        pytest.skip("numba's atan2 or the compiled hypot differ from math's here")
    compiled = trig._compiled_polar
    for column in (0, 1):
        def off(y, x, column=column):
            out = compiled(y, x)
            out[column][1234] = np.nextafter(out[column][1234], np.inf)
            return out
        monkeypatch.setattr(trig, "_compiled_polar", off)
        assert trig.compiled_polar.__wrapped__() is False
    monkeypatch.setattr(trig, "_compiled_polar", compiled)
    assert trig.compiled_polar.__wrapped__() is True
