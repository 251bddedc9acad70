"""The scalar-trig probe (aoass_env.trig) shared by the float paths."""

from __future__ import annotations

import math

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
