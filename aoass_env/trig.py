"""Whether Python's ``math.cos``/``math.sin`` give NumPy's float64 ``cos``/``sin`` bit for bit,
and whether numba's compiled ``cos``/``sin`` give them too.

NumPy may dispatch its ``cos``/``sin`` to its own SIMD code, whose last bit can differ from the
C library's, which ``math`` calls. The hot paths that replace small NumPy arrays by Python
floats (the world's rays, the look-ahead's one-path rollout, the unicycle step) take their
float path only when a probe at import finds the two equal, and their array code otherwise.
Compiled code calls the C library through LLVM (or a vector library, if numba finds one), so
the paths that run trigonometry compiled (the unicycle's arc, the look-ahead's rollouts) are
taken only when the same probe finds numba's equal as well (:func:`compiled_trig`, probed on
first use: loading numba's compiled code costs a fraction of a second).
"""

from __future__ import annotations

import functools
import math

import numba
import numpy as np

__all__ = ["SCALAR_TRIG", "compiled_trig"]


def _probe() -> np.ndarray:
    """4 096 random angles in [-20, 20] rad and the unicycle's arc points."""
    return np.concatenate([np.random.default_rng(0).uniform(-20.0, 20.0, 4096),
                           np.linspace(-7.0, 7.0, 9)])


def _maths(cos: np.ndarray, sin: np.ndarray, probe: np.ndarray) -> bool:
    """Whether ``cos`` and ``sin`` of the ``probe`` are ``math``'s, bit for bit."""
    return (np.array_equal(cos, [math.cos(x) for x in probe])
            and np.array_equal(sin, [math.sin(x) for x in probe]))


def _scalar_trig_is_numpys() -> bool:
    """The probe (:func:`_probe`) through ``math`` and NumPy."""
    probe = _probe()
    return _maths(np.cos(probe), np.sin(probe), probe)


#: see :func:`_scalar_trig_is_numpys`
SCALAR_TRIG = _scalar_trig_is_numpys()


@numba.njit(cache=True)
def _compiled_cos_sin(angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Compiled ``math.cos`` and ``math.sin`` of each angle (rad), one call at a time."""
    cos, sin = np.empty_like(angles), np.empty_like(angles)
    for i in range(len(angles)):
        cos[i] = math.cos(angles[i])
        sin[i] = math.sin(angles[i])
    return cos, sin


@functools.cache
def compiled_trig() -> bool:
    """Whether compiled ``cos``/``sin`` are ``math``'s, which are NumPy's (:data:`SCALAR_TRIG`):
    the probe (:func:`_probe`) through numba and ``math``, once per process."""
    if not SCALAR_TRIG:
        return False
    probe = _probe()
    return _maths(*_compiled_cos_sin(probe), probe)
