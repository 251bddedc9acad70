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

The norms and angles of the compiled code that must equal Python's: :func:`hypot`, correctly
rounded as ``math.hypot`` is since Python 3.11 (the C library's hypot, which numba would call,
is not), and :func:`compiled_polar`, the probe that finds numba's ``atan2`` and :func:`hypot`
equal to ``math``'s before a compiled path relies on them.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from aoass_env.jit import njit

__all__ = ["SCALAR_TRIG", "compiled_polar", "compiled_trig", "hypot"]


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


@njit
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


#: Veltkamp's splitter for doubles, 2^27 + 1: splits a float into two halves of 26 bits.
_SPLITTER = 134217729.0


@njit
def _exact_square(a: float) -> tuple[float, float]:
    """(p, e) with p = fl(a * a) and p + e = a * a exactly (Dekker's product, no FMA), for
    |a| < 1 and not tiny enough to underflow."""
    p = a * a
    t = _SPLITTER * a
    hi = t - (t - a)
    lo = a - hi
    return p, ((hi * hi - p) + 2.0 * hi * lo) + lo * lo


@njit
def hypot(x: float, y: float) -> float:
    """sqrt(x^2 + y^2), correctly rounded but in cases within about 2^-100 of a tie: compiled,
    ``math.hypot``'s float since Python 3.11.

    Both are scaled by the power of two that brings the larger into [0.5, 1); the sum of the
    squares is kept exactly as two floats (Dekker's products, then a two-sum); the square
    root of its leading float is corrected by one Newton step on the residual, which is
    computed exactly. A ratio below 2^-30 leaves the larger unchanged after rounding.
    """
    x, y = abs(x), abs(y)
    if x == math.inf or y == math.inf:
        return math.inf
    if x != x or y != y:
        return math.nan
    big, small = (x, y) if x >= y else (y, x)
    if small == 0.0 or small < big * 9.313225746154785e-10:        # 2^-30
        return big
    _, e = math.frexp(big)
    a, b = math.ldexp(big, -e), math.ldexp(small, -e)
    a2, a2e = _exact_square(a)
    b2, b2e = _exact_square(b)
    s = a2 + b2
    lo = ((a2 - s) + b2) + (a2e + b2e)        # a2 >= b2: the two-sum's error is exact
    h = math.sqrt(s)
    h2, h2e = _exact_square(h)
    h += (((s - h2) - h2e) + lo) / (2.0 * h)
    return math.ldexp(h, e)


@njit
def _compiled_polar(y: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Compiled ``math.atan2(y, x)`` and :func:`hypot` ``(x, y)`` of each pair."""
    angle, norm = np.empty_like(y), np.empty_like(y)
    for i in range(len(y)):
        angle[i] = math.atan2(y[i], x[i])
        norm[i] = hypot(x[i], y[i])
    return angle, norm


@functools.cache
def compiled_polar() -> bool:
    """Whether compiled ``math.atan2`` and :func:`hypot` give ``math.atan2`` and ``math.hypot``
    bit for bit: 8 192 random pairs over twelve decades, signed zeros and axis pairs, through
    numba and ``math``, once per process."""
    rng = np.random.default_rng(0)
    pairs = rng.normal(0.0, 1.0, (8192, 2)) * 10.0 ** rng.uniform(-6.0, 6.0, (8192, 1))
    axes = np.array([[0.0, 0.0], [-0.0, 0.0], [0.0, -0.0], [-0.0, -0.0], [1.0, 0.0],
                     [-1.0, 0.0], [1.0, -0.0], [-1.0, -0.0], [0.0, 2.5], [-0.0, -2.5]])
    y, x = np.concatenate([pairs, axes]).T.copy()
    angle, norm = _compiled_polar(y, x)
    yx = list(zip(y.tolist(), x.tolist(), strict=True))
    # the bits compared, signed zeros included
    return (np.array_equal(angle.view(np.int64),
                           np.array([math.atan2(a, b) for a, b in yx]).view(np.int64))
            and np.array_equal(norm.view(np.int64),
                               np.array([math.hypot(b, a) for a, b in yx]).view(np.int64)))
