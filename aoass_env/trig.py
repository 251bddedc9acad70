"""Whether Python's ``math.cos``/``math.sin`` give NumPy's float64 ``cos``/``sin`` bit for bit.

NumPy may dispatch its ``cos``/``sin`` to its own SIMD code, whose last bit can differ from the
C library's, which ``math`` calls. The hot paths that replace small NumPy arrays by Python
floats (the world's rays, the look-ahead's one-path rollout, the unicycle step) take their
float path only when a probe at import finds the two equal, and their array code otherwise.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["SCALAR_TRIG"]


def _scalar_trig_is_numpys() -> bool:
    """The probe: 4 096 random angles in [-20, 20] rad and the unicycle's arc points."""
    probe = np.concatenate([np.random.default_rng(0).uniform(-20.0, 20.0, 4096),
                            np.linspace(-7.0, 7.0, 9)])
    return (np.array_equal(np.cos(probe), [math.cos(x) for x in probe])
            and np.array_equal(np.sin(probe), [math.sin(x) for x in probe]))


#: see :func:`_scalar_trig_is_numpys`
SCALAR_TRIG = _scalar_trig_is_numpys()
