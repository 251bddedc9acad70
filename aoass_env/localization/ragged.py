"""Ragged lists (one variable-length list per row) packed into padded rectangular arrays."""

from __future__ import annotations

import numpy as np

__all__ = ["pad_rows"]


def pad_rows(rows: np.ndarray, values: np.ndarray, n_rows: int,
             max_len: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Pack ``values`` grouped by ``rows`` into an (n_rows, L) array, padding with -1.

    Args:
        rows: (K,) row of each value, non-decreasing (entries keep their order within a row).
        values: (K,) non-negative integers (indices) to place.
        n_rows: number of rows of the result.
        max_len: width L; default the longest row.

    Returns:
        ``(padded, lengths)``: (n_rows, L) int64 with -1 after each row's entries, and (n_rows,)
        the number of entries per row.
    """
    rows = np.asarray(rows, dtype=np.int64)
    lengths = np.bincount(rows, minlength=n_rows)
    width = int(lengths.max(initial=0)) if max_len is None else int(max_len)
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    col = np.arange(len(rows)) - starts[rows]
    padded = np.full((n_rows, width), -1, dtype=np.int64)
    padded[rows, col] = values
    return padded, lengths
