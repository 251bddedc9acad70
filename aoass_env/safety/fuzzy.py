"""Mamdani fuzzy logic controller of Eq. 7: f_FLC(d, dtheta) = [omega, v].

Inputs: ``d``, the gap to the nearest obstacle (m, clipped to the distance universe, so +inf
reads as "far"), and ``dtheta`` = desired heading - current heading (rad, wrapped to
[-pi, pi], then clipped to the heading universe). Outputs: ``omega``, a fraction in [-1, 1] of
the maximum turn rate (positive = counter-clockwise, the sign of ``dtheta``), and ``v``, a
fraction in [0, 1] of the desired speed.

Everything the controller knows is data: four :class:`FuzzyVariable` (universe and named
triangle/trapezoid terms) and a rule table ``(distance term, heading term) -> (turn term,
speed term)`` in a frozen :class:`FuzzyController`. Inference:

* fuzzification: exact membership of the crisp inputs (piecewise-linear interpolation between
  the term corners, no input discretisation);
* AND = min; rule strength = min(mu_distance, mu_heading);
* implication = min (clipping); aggregation = max over rules;
* defuzzification = centroid of the aggregated set on the discretised output universe
  (``n`` points; integrals exact for a set linear between grid points, so the centroid of a
  term whose corners are grid points is exact to round-off, and O(h^2) off otherwise).

Membership grids of the output terms and the interpolation tables of the input terms are
computed once at construction. A scalar call runs fuzzification, rules and aggregation compiled
(numba, :func:`_aggregate`) and the centroid's two products in NumPy (about 5 us;
scikit-fuzzy's control system takes about 12 ms on the same sets); arrays go through the same
steps vectorised, in blocks of 1024 points (about 5 us per point). ``benchmarks/fuzzy.py``
prints the figures.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from aoass_env.jit import njit
from aoass_env.validators import number_array

__all__ = ["FULL_TURN", "FuzzyController", "FuzzyVariable", "membership"]

#: Heading change (rad) per control period that the controller's full turn (1) stands for: its
#: heading terms make the turn grow about linearly to a full turn at an error of pi/4, so a turn
#: of u closes about u pi/4 (the default limits, pi/2 rad/s over 0.5 s, turn exactly this far).
#: A faster anchor still turns at most this far on the controller's word, else a turn sized for
#: pi/4 overshoots the error and the heading zig-zags from period to period.
FULL_TURN = math.pi / 4

_TWO_PI = 2.0 * math.pi
#: the scalar inputs of the controller's fast path (booleans excepted)
_REALS = (float, int, np.floating, np.integer)
#: Inputs evaluated together at most (bounds the memory of one vectorised call).
_BLOCK = 1024


def membership(x: ArrayLike, params: tuple[float, ...]) -> np.ndarray:
    """Membership of ``x`` in a triangle ``(a, b, c)`` or trapezoid ``(a, b, c, d)`` term.

    0 outside [a, d], 1 on [b, c], linear in between; a vertical edge (``a == b`` or
    ``c == d``) gives 1 at the corner. A plain reference implementation (plots, tests); the
    controller itself interpolates precomputed tables.
    """
    a, b, c, d = (params[0], params[1], params[1], params[2]) if len(params) == 3 else params
    x = np.asarray(x, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        rise = np.where(x >= b, 1.0, (x - a) / (b - a)) if b > a else (x >= a).astype(float)
        fall = np.where(x <= c, 1.0, (d - x) / (d - c)) if d > c else (x <= d).astype(float)
    return np.clip(np.minimum(rise, fall), 0.0, 1.0)


@njit
def _memberships(x: float, inner: np.ndarray, rows: np.ndarray, lo: float,
                 hi: float) -> np.ndarray:
    """Memberships of one crisp value by exact piecewise-linear interpolation (the vectorised
    :meth:`FuzzyController._fuzzify`'s arithmetic; Python's ``min(max(x, lo), hi)`` clip)."""
    if lo > x:
        x = lo
    if hi < x:
        x = hi
    k = np.searchsorted(inner, x, side="right")
    n = (rows.shape[1] - 1) // 2
    dx = x - rows[k, 2 * n]
    mu = np.empty(n)
    for t in range(n):
        mu[t] = rows[k, t] + rows[k, n + t] * dx
    return mu


@njit
def _aggregate(d: float, h: float, d_inner: np.ndarray, d_rows: np.ndarray, d_lo: float,
               d_hi: float, h_inner: np.ndarray, h_rows: np.ndarray, h_lo: float, h_hi: float,
               table: np.ndarray, grid: np.ndarray, nt: int,
               support: np.ndarray) -> np.ndarray:
    """(2, n) the aggregated turn and speed sets (rows, on the output grid) of one d (m) and
    one wrapped dtheta (rad): AND = min, implication = min, aggregation = max. One array, so
    one allocation and one return to Python.

    Only the rules whose two memberships are both positive are evaluated: any other rule has a
    strength min(mu_d, mu_h) <= 0, which never raises an output term's strength (they start at
    0). Every operation is a comparison, so the sets are those of the array code.

    Only the output terms of positive strength are clipped, on their support ``support[r]``
    (the first and one past the last grid point where the term is positive). The grid holds no
    negative value and no -0.0 (memberships are clipped to [0, 1]), so elsewhere a term's
    clipped value is +0.0, which never raises a set that starts at +0.0: the sets are the floats
    of every term clipped on every point, the first of each output assigned, the others taken
    where larger.
    """
    mu_d = _memberships(d, d_inner, d_rows, d_lo, d_hi)
    mu_h = _memberships(h, h_inner, h_rows, h_lo, h_hi)
    n_out, n = grid.shape
    out = np.zeros(n_out)
    for i in range(len(mu_d)):
        md = mu_d[i]
        if md > 0.0:
            for j in range(len(mu_h)):
                mh = mu_h[j]
                if mh > 0.0:
                    w = mh if mh < md else md
                    t, s = table[i, j, 0], table[i, j, 1]
                    if w > out[t]:
                        out[t] = w
                    if w > out[s]:
                        out[s] = w
    sets = np.zeros((2, n))
    for r in range(n_out):
        strength = out[r]
        if not strength > 0.0:
            continue
        target = sets[0] if r < nt else sets[1]
        for k in range(support[r, 0], support[r, 1]):
            g = grid[r, k]
            clipped = strength if strength < g else g
            if clipped > target[k]:
                target[k] = clipped
    return sets


@dataclass(frozen=True)
class FuzzyVariable:
    """A linguistic variable: a universe and its named terms.

    Attributes:
        name: variable name, used in error messages.
        universe: ``(min, max, n)``: the interval of the variable (its unit) and the number of
            points of its discretisation (output variables are defuzzified on it; input
            variables use it for plots only).
        terms: term name -> corners ``(a, b, c)`` of a triangle or ``(a, b, c, d)`` of a
            trapezoid, non-decreasing, inside the universe. Vertical edges (``a == b`` or
            ``c == d``) are allowed only at the universe bounds, so every membership function
            is continuous on the universe. Stored as a read-only mapping in the given order.
    """

    name: str
    universe: tuple[float, float, int]
    terms: Mapping[str, tuple[float, ...]]

    def __post_init__(self) -> None:
        try:
            lo, hi, n = self.universe
        except (TypeError, ValueError):
            raise ValueError(f"{self.name}: universe={self.universe!r} must be (min, max, "
                             "n points)") from None
        lo, hi = float(lo), float(hi)
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ValueError(f"{self.name}: universe=({lo}, {hi}, ...) needs finite min < max")
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 3:
            raise ValueError(f"{self.name}: universe n={n!r} must be an integer >= 3")
        object.__setattr__(self, "universe", (lo, hi, int(n)))
        if not isinstance(self.terms, Mapping) or not self.terms:
            raise ValueError(f"{self.name}: terms must be a non-empty mapping name -> corners")
        terms: dict[str, tuple[float, ...]] = {}
        for term, params in self.terms.items():
            if not isinstance(term, str) or not term:
                raise ValueError(f"{self.name}: term name {term!r} must be a non-empty string")
            try:
                p = tuple(float(v) for v in params)
            except (TypeError, ValueError):
                raise ValueError(f"{self.name}.{term}: corners {params!r} must be numbers") \
                    from None
            where = f"{self.name}.{term}: corners {p}"
            if len(p) not in (3, 4):
                raise ValueError(f"{where} must be 3 (triangle) or 4 (trapezoid) numbers")
            if not all(math.isfinite(v) for v in p):
                raise ValueError(f"{where} must be finite")
            if any(u > v for u, v in zip(p, p[1:], strict=False)):
                raise ValueError(f"{where} must be sorted (non-decreasing)")
            if p[0] < lo or p[-1] > hi:
                raise ValueError(f"{where} must lie inside the universe [{lo}, {hi}]")
            a, b, c, d = (p[0], p[1], p[1], p[2]) if len(p) == 3 else p
            if (a == b and a != lo) or (c == d and d != hi):
                raise ValueError(f"{where}: a vertical edge (a == b or c == d) is allowed "
                                 f"only at the universe bounds {lo} / {hi}")
            terms[term] = p
        object.__setattr__(self, "terms", MappingProxyType(terms))

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        """Pickle and deepcopy: rebuilt from plain values (a mappingproxy does not pickle)."""
        return type(self), (self.name, self.universe, dict(self.terms))

    def grid(self) -> np.ndarray:
        """The discretised universe, shape (n,)."""
        lo, hi, n = self.universe
        return np.linspace(lo, hi, n)

    def memberships(self, x: ArrayLike) -> np.ndarray:
        """Memberships of ``x`` (shape S) in every term, shape S + (number of terms,)."""
        return np.stack([membership(x, p) for p in self.terms.values()], axis=-1)


def _default_distance() -> FuzzyVariable:
    # ORCA keeps the anchor off the obstacles; the controller only eases off in the last
    # metre (the spiral and the detours routinely pass 0.3-1 m from obstacles).
    return FuzzyVariable("distance", (0.0, 10.0, 201), {
        "near": (0.0, 0.0, 0.2, 0.6),
        "medium": (0.3, 1.0, 2.0),
        "far": (1.2, 2.5, 10.0, 10.0),
    })


def _default_heading() -> FuzzyVariable:
    p = math.pi
    return FuzzyVariable("heading", (-p, p, 181), {
        "NB": (-p, -p, -p / 2, -p / 4),
        "NS": (-p / 2, -p / 4, 0.0),
        "ZE": (-p / 4, 0.0, p / 4),
        "PS": (0.0, p / 4, p / 2),
        "PB": (p / 4, p / 2, p, p),
    })


def _default_turn() -> FuzzyVariable:
    # Symmetric terms centred on -1, 0 and 1 (the universe reaches past +-1 so that full turn
    # is exactly 1): between "ZE" at 0 and "PS" at pi/4 the output grows about linearly, so
    # with the default limits (pi/2 rad/s over a 0.5 s period) the anchor closes a heading
    # error of up to pi/4 within one period.
    return FuzzyVariable("turn", (-1.1, 1.1, 441), {
        "right": (-1.1, -1.0, -0.9),
        "straight": (-0.1, 0.0, 0.1),
        "left": (0.9, 1.0, 1.1),
    })


def _default_speed() -> FuzzyVariable:
    # symmetric terms: "stop" is exactly 0 and "fast" exactly 1 (the universe reaches past both)
    return FuzzyVariable("speed", (-0.1, 1.1, 481), {
        "stop": (-0.1, 0.0, 0.1),
        "slow": (0.1, 0.3, 0.5),
        "medium": (0.4, 0.65, 0.9),
        "fast": (0.9, 1.0, 1.1),
    })


def _default_rules() -> dict[tuple[str, str], tuple[str, str]]:
    # The turn follows the sign of the heading error (the FLC has no bearing to the obstacle,
    # so it steers toward the desired heading and leaves the geometry to ORCA); the speed term
    # drops for heading errors beyond pi/4 (the follower already slows with the cosine of the
    # error) and in the last metre before an obstacle.
    turn = {"NB": "right", "NS": "right", "ZE": "straight", "PS": "left", "PB": "left"}
    speed = {
        "near": {"NB": "stop", "NS": "slow", "ZE": "medium", "PS": "slow", "PB": "stop"},
        "medium": {"NB": "stop", "NS": "fast", "ZE": "fast", "PS": "fast", "PB": "stop"},
        "far": {"NB": "slow", "NS": "fast", "ZE": "fast", "PS": "fast", "PB": "slow"},
    }
    return {(dt, ht): (turn[ht], sp) for dt, row in speed.items() for ht, sp in row.items()}


@dataclass(frozen=True)
class FuzzyController:
    """Mamdani FLC of Eq. 7, ``controller(d, dtheta) -> (omega_fraction, speed_fraction)``.

    Attributes:
        distance: input variable, gap to the nearest obstacle (m).
        heading: input variable, heading error (rad); its universe should be [-pi, pi].
        turn: output variable, fraction of the turn per period, universe inside [-1, 1]: of
            the anchor's largest, but no more than :data:`FULL_TURN`.
        speed: output variable, fraction of the desired speed, universe inside [0, 1].
        rules: complete table ``(distance term, heading term) -> (turn term, speed term)``,
            one entry for every pair of input terms (so every input fires some rule).

    ``FuzzyController()`` (or :meth:`default`) gives the documented defaults
    (docs/safety.md).
    """

    distance: FuzzyVariable = field(default_factory=_default_distance)
    heading: FuzzyVariable = field(default_factory=_default_heading)
    turn: FuzzyVariable = field(default_factory=_default_turn)
    speed: FuzzyVariable = field(default_factory=_default_speed)
    rules: Mapping[tuple[str, str], tuple[str, str]] = field(default_factory=_default_rules)
    _tables: Any = field(init=False, repr=False, compare=False, default=None)

    @classmethod
    def default(cls) -> FuzzyController:
        """The controller with the default sets and rules."""
        return cls()

    def __post_init__(self) -> None:
        for role, var in (("distance", self.distance), ("heading", self.heading),
                          ("turn", self.turn), ("speed", self.speed)):
            if not isinstance(var, FuzzyVariable):
                raise ValueError(f"{role} must be a FuzzyVariable, got {type(var).__name__}")
        # Output universes may reach past [-1, 1] / [0, 1] (so that a symmetric term can
        # centre on an end); the outputs are clipped to those ranges.
        if self.turn.universe[0] >= 0 or self.turn.universe[1] <= 0:
            raise ValueError(f"turn universe {self.turn.universe[:2]} must contain 0")
        if self.speed.universe[0] > 0 or self.speed.universe[1] <= 0:
            raise ValueError(f"speed universe {self.speed.universe[:2]} must contain [0, a] "
                             f"with a > 0")
        rules = self._check_rules()
        object.__setattr__(self, "rules", MappingProxyType(rules))
        object.__setattr__(self, "_tables", self._build_tables(rules))

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        """Pickle and deepcopy: rebuilt from plain values (a mappingproxy does not pickle)."""
        return type(self), (self.distance, self.heading, self.turn, self.speed, dict(self.rules))

    def _check_rules(self) -> dict[tuple[str, str], tuple[str, str]]:
        if not isinstance(self.rules, Mapping):
            raise ValueError("rules must be a mapping (distance term, heading term) -> "
                             "(turn term, speed term)")
        rules: dict[tuple[str, str], tuple[str, str]] = {}
        for key, value in self.rules.items():
            if not all(isinstance(pair, tuple) and len(pair) == 2
                       and all(isinstance(term, str) for term in pair) for pair in (key, value)):
                raise ValueError(f"rule {key!r} -> {value!r} must be (distance term, heading "
                                 "term) -> (turn term, speed term), tuples of names")
            (dterm, hterm), (tterm, sterm) = key, value
            for var, term in ((self.distance, dterm), (self.heading, hterm),
                              (self.turn, tterm), (self.speed, sterm)):
                if term not in var.terms:
                    raise ValueError(f"rule {key!r} -> {value!r}: {term!r} is not a term of "
                                     f"{var.name} (terms: {', '.join(var.terms)})")
            rules[(dterm, hterm)] = (tterm, sterm)
        missing = [(d, h) for d in self.distance.terms for h in self.heading.terms
                   if (d, h) not in rules]
        if missing:
            raise ValueError(f"rules must cover every (distance term, heading term) pair; "
                             f"missing: {missing}")
        return rules

    def _build_tables(self, rules: Mapping[tuple[str, str], tuple[str, str]]) -> dict:
        inputs = []
        for var in (self.distance, self.heading):
            lo, hi, _ = var.universe
            xp = np.unique(np.array([lo, hi] + [v for p in var.terms.values() for v in p]))
            fp = var.memberships(xp)                                    # (K, T), exact
            if (fp.max(axis=1) <= 0).any():                              # piecewise linear:
                x0 = xp[np.argmax(fp.max(axis=1) <= 0)]                  # checking corners
                raise ValueError(f"{var.name}: no term covers {x0} (every point of the "
                                 "universe needs a term of membership > 0)")
            slope = np.diff(fp, axis=0) / np.diff(xp)[:, None]           # (K-1, T)
            inputs.append((xp[1:-1].copy(), np.ascontiguousarray(fp[:-1].T),
                           np.ascontiguousarray(slope.T), xp[:-1].copy(), lo, hi))
        # Output terms of both outputs stacked on one grid length (padded with zeros).
        n = max(self.turn.universe[2], self.speed.universe[2])
        grids, moments = [], []
        for var in (self.turn, self.speed):
            y = var.grid()
            mu = var.memberships(y).T                                      # (T, n_var)
            empty = [t for t, row in zip(var.terms, mu, strict=True) if row.max() <= 0]
            if empty:
                raise ValueError(f"{var.name}: terms {empty} are zero on every point of the "
                                 f"discretised universe; raise n={var.universe[2]}")
            # Weights of the exact integrals of a function linear between grid points:
            # area = sum w_i mu_i (trapezoid rule), moment = sum m_i mu_i, where m_i = h y_i
            # inside and h y / 2 +- h^2 / 6 at the two ends.
            h = y[1] - y[0]
            w = np.full(len(y), h)
            w[[0, -1]] *= 0.5
            m = w * y
            m[0] += h * h / 6
            m[-1] -= h * h / 6
            pad = n - len(y)
            grids.append(np.pad(mu, ((0, 0), (0, pad))))
            moments.append(np.ascontiguousarray(
                np.pad(np.stack([w, m], axis=1), ((0, pad), (0, 0)))))        # (n, 2)
        nt = len(self.turn.terms)
        # Rule r (row-major over distance x heading terms) -> its turn and speed term columns.
        dnames, hnames = list(self.distance.terms), list(self.heading.terms)
        tnames, snames = list(self.turn.terms), list(self.speed.terms)
        consequent = np.zeros((len(dnames) * len(hnames), nt + len(snames), 1))
        for i, dterm in enumerate(dnames):
            for j, hterm in enumerate(hnames):
                tterm, sterm = rules[(dterm, hterm)]
                r = i * len(hnames) + j
                consequent[r, tnames.index(tterm)] = 1.0
                consequent[r, nt + snames.index(sterm)] = 1.0
        # The scalar path's compiled tables (:func:`_aggregate`): per input, the inner corners,
        # rows [fp (T), slope (T), left corner] per interval, and the universe's ends; the rule
        # table [distance term, heading term] -> (turn row, speed row); the output grids.
        compiled = []
        for inner, fp, slope, left, lo, hi in inputs:
            compiled += [inner, np.ascontiguousarray(np.concatenate(
                [fp.T, slope.T, left[:, None]], axis=1)), float(lo), float(hi)]
        table = np.array([[(tnames.index(rules[(dt, ht)][0]),
                            nt + snames.index(rules[(dt, ht)][1])) for ht in hnames]
                          for dt in dnames], dtype=np.int64)
        grid = np.ascontiguousarray(np.concatenate(grids))                # C order: fast
        if np.signbit(grid).any():       # the aggregation's support rests on this
            raise RuntimeError("a membership grid holds a negative value or -0.0")
        positive = grid > 0.0            # each term is positive somewhere (checked above)
        support = np.array([[np.argmax(row), len(row) - np.argmax(row[::-1])]
                            for row in positive], dtype=np.int64)
        compiled += [table, grid, nt, support]
        return {"inputs": inputs, "grid": grid[:, None, :], "moments": moments, "nt": nt,
                "consequent": consequent, "rules": len(dnames) * len(hnames),
                "compiled": tuple(compiled)}

    @staticmethod
    def _fuzzify(x: np.ndarray, table: tuple) -> np.ndarray:
        """Memberships (T, N) of crisp values (N,) by exact piecewise-linear interpolation."""
        inner, fp, slope, left, lo, hi = table
        x = np.clip(x, lo, hi)
        k = np.searchsorted(inner, x, side="right")
        return fp[:, k] + slope[:, k] * (x - left[k])

    def _infer_scalar(self, d: float, h: float) -> tuple[float, float]:
        """[omega fraction, speed fraction] for one d (m) and one wrapped dtheta (rad).

        The memberships, the rules and the aggregation run compiled (:func:`_aggregate`); the
        centroid's areas and moments are NumPy's products of the aggregated sets, whose
        division and clipping round as NumPy's float64 scalars do (NumPy divides a zero area).
        The products are ``ndarray.dot``'s: the same BLAS product as ``@`` and ``np.dot`` (one
        vector times one matrix; tested equal), with less of the ufunc machinery around it
        (the method skips ``np.dot``'s ``__array_function__`` dispatch, about 0.6 us a call).
        """
        tab = self._tables
        sets = _aggregate(d, h, *tab["compiled"])
        moments = tab["moments"]
        ta, tm = sets[0].dot(moments[0]).tolist()
        sa, sm = sets[1].dot(moments[1]).tolist()
        if not (ta and sa):     # an area underflowed to 0: NumPy's inf or nan (and warning)
            ta, sa = np.float64(ta), np.float64(sa)
        return min(max(tm / ta, -1.0), 1.0), min(max(sm / sa, 0.0), 1.0)

    def _infer(self, d: np.ndarray, h: np.ndarray) -> np.ndarray:
        """(N, 4) [turn area, turn moment, speed area, speed moment] for 1-D d (m) and wrapped
        dtheta (rad); terms-first layouts keep every reduction on a leading axis."""
        tab = self._tables
        mu_d = self._fuzzify(d, tab["inputs"][0])                          # (Td, N)
        mu_h = self._fuzzify(h, tab["inputs"][1])                          # (Th, N)
        strength = np.minimum(mu_d[:, None], mu_h[None]).reshape(tab["rules"], 1, -1)
        # Strength of each output term: max over the rules concluding it (AND = min, max agg.).
        out = (strength * tab["consequent"]).max(axis=0)                   # (Tt + Ts, N)
        clipped = np.minimum(out[:, :, None], tab["grid"])                # implication = min
        nt = tab["nt"]
        turn = clipped[:nt].max(axis=0) @ tab["moments"][0]               # (N, 2)
        speed = clipped[nt:].max(axis=0) @ tab["moments"][1]
        return np.concatenate([turn, speed], axis=1)

    def __call__(self, d: ArrayLike, dtheta: ArrayLike) -> tuple[Any, Any]:
        """Evaluate f_FLC(d, dtheta) = [omega, v] (Eq. 7).

        Args:
            d: gap to the nearest obstacle (m); clipped to the distance universe (+inf = far).
            dtheta: heading error = desired - current heading (rad), any real; wrapped to
                [-pi, pi] (an odd wrap: +pi stays +pi), then clipped to the heading universe.

        Returns:
            ``(omega_fraction, speed_fraction)``: fractions of the maximum turn rate in
            [-1, 1] and of the desired speed in [0, 1]; Python floats for scalar inputs,
            else arrays of the common broadcast shape.

        Raises:
            ValueError: NaN in ``d``, non-finite ``dtheta``, entries that are not numbers
                (booleans, strings, objects), or shapes that do not broadcast.
        """
        if isinstance(d, _REALS) and isinstance(dtheta, _REALS) and not (
                isinstance(d, bool) or isinstance(dtheta, bool)):
            d, dtheta = float(d), float(dtheta)
            if math.isnan(d):
                raise ValueError("d must not be NaN (gap to the nearest obstacle, m)")
            if not math.isfinite(dtheta):
                raise ValueError("dtheta must be finite (heading error, rad)")
            return self._infer_scalar(d, dtheta - _TWO_PI * round(dtheta / _TWO_PI))
        # a boolean, a string ("1") or an object is no gap or angle
        d_arr = number_array("d", d, "gap to the nearest obstacle, m")
        h_arr = number_array("dtheta", dtheta, "heading error, rad")
        try:
            d_arr, h_arr = np.broadcast_arrays(d_arr, h_arr)
        except ValueError:
            raise ValueError(f"d of shape {d_arr.shape} and dtheta of shape {h_arr.shape} "
                             "do not broadcast") from None
        shape = d_arr.shape
        if not shape:                                   # 0-d arrays: the scalar path
            return self(float(d_arr), float(h_arr))
        d_flat, h_flat = d_arr.ravel(), h_arr.ravel()
        if np.isnan(d_flat).any():
            raise ValueError("d must not be NaN (gap to the nearest obstacle, m)")
        if not np.isfinite(h_flat).all():
            raise ValueError("dtheta must be finite (heading error, rad)")
        # Odd wrap into [-pi, pi]: np.round rounds half to even, so +-pi stay where they are.
        h_flat = h_flat - _TWO_PI * np.round(h_flat / _TWO_PI)
        # Blocks bound the (terms, block, n) implication array to a few MB.
        res = np.concatenate([self._infer(d_flat[i:i + _BLOCK], h_flat[i:i + _BLOCK])
                              for i in range(0, max(len(d_flat), 1), _BLOCK)])
        omega = np.clip(res[:, 1] / res[:, 0], -1.0, 1.0)                 # centroids
        speed = np.clip(res[:, 3] / res[:, 2], 0.0, 1.0)
        return omega.reshape(shape), speed.reshape(shape)
