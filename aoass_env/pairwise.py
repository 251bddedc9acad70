"""NumPy's summation order, compiled: :func:`pairwise_sum` adds a run of a float64 array as
``np.add.reduce`` adds a contiguous run (``arr.sum()``, ``arr.sum(axis=-1)`` row by row), so
that compiled code reproduces NumPy's sums bit for bit (tests/test_pairwise.py checks it against
NumPy for every length up to thousands).
"""

from __future__ import annotations

import numpy as np

from aoass_env.jit import njit

__all__ = ["pairwise_sum"]


@njit
def _block_sum(a: np.ndarray, start: int, n: int) -> float:
    """NumPy's sum of a run of at most 128 (:func:`pairwise_sum`): fewer than 8 in turn from
    0, else 8 interleaved accumulators added pairwise, then the rest in turn."""
    if n < 8:
        total = 0.0
        for i in range(start, start + n):
            total += a[i]
        return total
    acc = a[start:start + 8].copy()
    i = 8
    while i < n - n % 8:
        for j in range(8):
            acc[j] += a[start + i + j]
        i += 8
    total = ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]))
    while i < n:
        total += a[start + i]
        i += 1
    return total


@njit
def pairwise_sum(a: np.ndarray, start: int, n: int) -> float:
    """The sum of ``a[start:start + n]`` in NumPy's order for a contiguous float64 array
    (``np.add.reduce``'s pairwise summation): a run longer than 128 is cut in two at a multiple
    of 8 near its middle and the halves' sums added, left + right; :func:`_block_sum` sums the
    runs. The recursion runs on an explicit stack (numba's cache does not load recursive
    functions safely). ValueError when the run leaves ``a``."""
    if start < 0 or n < 0 or start + n > len(a):
        raise ValueError("pairwise_sum: the run a[start:start + n] must lie inside a")
    starts = np.empty(64, dtype=np.int64)
    lengths = np.empty(64, dtype=np.int64)
    lefts = np.empty(64)
    right_next = np.zeros(64, dtype=np.bool_)    # the left half's sum is in lefts
    top = 0
    starts[0], lengths[0] = start, n
    while True:
        s, m = starts[top], lengths[top]
        if m > 128:                                  # descend into the left half
            half = m // 2 - (m // 2) % 8
            top += 1
            starts[top], lengths[top], right_next[top] = s, half, False
            continue
        value = _block_sum(a, s, m)
        top -= 1
        while top >= 0 and right_next[top]:         # a right half: its parent is summed
            value = lefts[top] + value
            top -= 1
        if top < 0:
            return value
        lefts[top], right_next[top] = value, True    # a left half: on to the right one
        half = lengths[top] // 2 - (lengths[top] // 2) % 8
        starts[top + 1], lengths[top + 1], right_next[top + 1] = \
            starts[top] + half, lengths[top] - half, False
        top += 1
