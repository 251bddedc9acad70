"""aoass_env.pairwise: NumPy's summation order, compiled."""

from __future__ import annotations

import numpy as np
import pytest

from aoass_env.pairwise import pairwise_sum


def test_every_length_sums_as_numpy():
    """np.add.reduce of contiguous runs (whole arrays and runs inside them) of every length up
    to 1100 and of random lengths up to 20 000, values over many magnitudes and signs, bit for
    bit."""
    rng = np.random.default_rng(30)
    lengths = [*range(0, 1100), *rng.integers(1100, 20000, 40).tolist()]
    for n in lengths:
        a = rng.normal(0.0, 1.0, n + 7) * 10.0 ** rng.uniform(-6, 6, n + 7)
        start = int(rng.integers(0, 8))
        want = np.add.reduce(a[start:start + n])
        got = pairwise_sum(a, start, n)
        assert got == want or (got == 0.0 == want), n
        assert pairwise_sum(a[:n].copy(), 0, n) == a[:n].sum(), n


def test_rows_sum_as_numpy_row_sums():
    """arr.sum(axis=1) of C-contiguous 2-D arrays and of column slices (strided rows), row by
    row (NumPy could order a reduction over a short axis otherwise): what the look-ahead's
    summed shortfalls are, 52 candidates of 18 steps among them."""
    rng = np.random.default_rng(31)
    for i in range(300):
        k = int(rng.choice([1, 2, 17, 52, 200])) if i % 2 else int(rng.integers(1, 40))
        s = 18 if i % 5 == 0 else int(rng.integers(1, 300))
        arr = np.maximum(rng.normal(0.0, 1.0, (k, s)), 0.0)
        cut = int(rng.integers(1, s + 1))
        for block in (arr, arr[:, :cut]):
            want = block.sum(axis=1)
            got = [pairwise_sum(np.ascontiguousarray(row), 0, len(row)) for row in block]
            assert np.array_equal(got, want)


def test_a_run_outside_the_array_is_an_error():
    a = np.ones(10)
    assert pairwise_sum(a, 2, 8) == 8.0
    for start, n in ((3, 8), (-1, 2), (0, -1), (11, 0)):
        with pytest.raises(ValueError, match="must lie inside a"):
            pairwise_sum(a, start, n)
