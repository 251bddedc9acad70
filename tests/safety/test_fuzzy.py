"""Mamdani FLC of Eq. 7 (aoass_env.safety.fuzzy)."""

from __future__ import annotations

import bisect
import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env.safety.fuzzy import FuzzyController, FuzzyVariable, membership

FLC = FuzzyController()
PI = math.pi
distances = st.floats(0.0, 12.0)
headings = st.floats(-PI + 1e-6, PI - 1e-6)       # +-pi itself: turn direction is ambiguous
FAST = settings(max_examples=150, deadline=None)


def centroid(params: tuple[float, ...]) -> float:
    """Centroid of a triangle/trapezoid term, from its geometry (left ramp, top, right ramp)."""
    a, b, c, d = (params[0], params[1], params[1], params[2]) if len(params) == 3 else params
    parts = [((b - a) / 2, a + 2 * (b - a) / 3), (c - b, (b + c) / 2),
             ((d - c) / 2, c + (d - c) / 3)]
    return sum(area * x for area, x in parts) / sum(area for area, _ in parts)


def peak(params: tuple[float, ...]) -> float:
    """A point where the term's membership is 1."""
    return params[1] if len(params) == 3 else 0.5 * (params[1] + params[2])


def test_rule_table_at_the_peaks():
    """Where exactly one rule fires fully, the outputs are the centroids of its two terms."""
    for (dterm, hterm), (tterm, sterm) in FLC.rules.items():
        d, h = peak(FLC.distance.terms[dterm]), peak(FLC.heading.terms[hterm])
        mu_d = FLC.distance.memberships(d)
        mu_h = FLC.heading.memberships(h)
        assert sorted(mu_d)[-2:] == [0.0, 1.0] and sorted(mu_h)[-2:] == [0.0, 1.0]
        omega, v = FLC(d, h)
        assert omega == pytest.approx(centroid(FLC.turn.terms[tterm]), abs=1e-12)
        assert v == pytest.approx(centroid(FLC.speed.terms[sterm]), abs=1e-12)


def test_default_behaviour():
    """The documented intent of the default table, in numbers."""
    free, _ = FLC(8.0, 0.0)
    assert free == pytest.approx(0.0, abs=1e-12)
    assert FLC(8.0, 0.0)[1] > 0.9                  # far and aligned: fast
    assert FLC(0.1, 0.0)[1] == pytest.approx(0.65)  # touching and aligned: medium
    assert FLC(0.1, 0.5)[1] < FLC(0.1, 0.0)[1]     # near and turning: slower
    assert FLC(8.0, 2.5)[1] < 0.35                 # large error: slow even when far
    assert FLC(0.5, 2.5)[1] < 0.05                 # large error and near: stop
    assert FLC(5.0, 2.5)[0] > 0.85                 # turn hard toward the desired heading
    assert FLC(5.0, -2.5)[0] < -0.85
    assert FLC(np.inf, 0.0) == FLC(10.0, 0.0) == FLC(25.0, 0.0)   # clipped to the universe
    assert FLC(-1.0, 0.3) == FLC(0.0, 0.3)


@FAST
@given(distances, headings)
def test_symmetry(d, h):
    o1, v1 = FLC(d, h)
    o2, v2 = FLC(d, -h)
    assert o2 == pytest.approx(-o1, abs=1e-12)
    assert v2 == pytest.approx(v1, abs=1e-12)
    if h > 1e-9:
        assert o1 > 0                              # the sign follows the heading error


@FAST
@given(distances, distances)
def test_speed_non_decreasing_in_distance_when_aligned(d1, d2):
    lo, hi = sorted((d1, d2))
    assert FLC(lo, 0.0)[1] <= FLC(hi, 0.0)[1] + 1e-12


@FAST
@given(distances, st.floats(0.0, PI - 1e-6), st.floats(0.0, PI - 1e-6))
def test_turn_magnitude_non_decreasing_in_heading_error(d, h1, h2):
    lo, hi = sorted((h1, h2))
    assert FLC(d, lo)[0] <= FLC(d, hi)[0] + 1e-12
    assert FLC(d, -lo)[0] >= FLC(d, -hi)[0] - 1e-12


@FAST
@given(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3))
def test_outputs_in_range(d, h):
    omega, v = FLC(d, h)
    assert isinstance(omega, float) and isinstance(v, float)
    assert -1.0 <= omega <= 1.0 and 0.0 <= v <= 1.0


@FAST
@given(distances, st.floats(-PI + 1e-3, PI - 1e-3), st.integers(-3, 3))
def test_heading_error_is_wrapped(d, h, k):
    o1, v1 = FLC(d, h)
    o2, v2 = FLC(d, h + 2 * PI * k)
    assert o2 == pytest.approx(o1, abs=1e-9) and v2 == pytest.approx(v1, abs=1e-9)


def test_vectorised_equals_scalar_loop():
    rng = np.random.default_rng(0)
    d = rng.uniform(-1, 12, (7, 9))
    h = rng.uniform(-7, 7, (7, 9))
    d[0, 0], h[0, 1] = np.inf, PI
    omega, v = FLC(d, h)
    assert omega.shape == v.shape == (7, 9)
    loop = np.array([FLC(float(a), float(b)) for a, b in zip(d.ravel(), h.ravel(),
                                                             strict=True)])
    np.testing.assert_allclose(omega.ravel(), loop[:, 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(v.ravel(), loop[:, 1], rtol=0, atol=1e-12)
    # broadcasting, 0-d arrays, lists and large batches (evaluated in blocks)
    o_b, v_b = FLC(3.0, h[0])
    np.testing.assert_allclose(o_b, [FLC(3.0, float(b))[0] for b in h[0]], atol=1e-12)
    assert FLC(np.float64(3.0), np.array(0.2)) == FLC(3.0, 0.2)
    assert np.shape(FLC([1.0, 2.0], [0.0, 0.1])[0]) == (2,)
    big_d, big_h = rng.uniform(0, 10, 3000), rng.uniform(-3, 3, 3000)
    o_big, _ = FLC(big_d, big_h)
    np.testing.assert_allclose(o_big[[0, 1500, 2999]],
                               [FLC(big_d[i], big_h[i])[0] for i in (0, 1500, 2999)],
                               atol=1e-12)
    empty = FLC(np.zeros(0), np.zeros(0))
    assert empty[0].shape == empty[1].shape == (0,)


@FAST
@given(distances, st.floats(-PI + 0.02, PI - 0.02), st.floats(-0.01, 0.01),
       st.floats(-0.01, 0.01))
def test_continuity(d, h, dd, dh):
    """Lipschitz: a small input change gives a proportionally small output change (the
    default surfaces have slopes below 14 / m and 10.6 / rad, measured on fine grids: the
    speed drops from fast to medium over the 0.3-0.6 m of gap where near and medium cross, and
    turns steepest in the heading error near d = 1.65 m, 45 degrees)."""
    o1, v1 = FLC(d, h)
    o2, v2 = FLC(d + dd, h + dh)
    bound = 15.0 * (abs(dd) + abs(dh)) + 1e-12
    assert abs(o2 - o1) <= bound and abs(v2 - v1) <= bound


def test_membership_reference():
    x = np.array([-1.0, 0.0, 0.5, 1.0, 1.5, 2.0, 3.0])
    np.testing.assert_allclose(membership(x, (0.0, 1.0, 2.0)), [0, 0, 0.5, 1, 0.5, 0, 0])
    np.testing.assert_allclose(membership(x, (0.0, 0.0, 1.0, 2.0)), [0, 1, 1, 1, 0.5, 0, 0])
    np.testing.assert_allclose(membership(x, (1.0, 2.0, 3.0, 3.0)), [0, 0, 0, 0, 0.5, 1, 1])


def test_custom_controller_and_immutability():
    flc = FuzzyController(
        distance=FuzzyVariable("d", (0, 4, 5), {"close": (0, 0, 4), "open": (0, 4, 4)}),
        heading=FuzzyVariable("h", (-PI, PI, 5), {"any": (-PI, -PI, PI, PI)}),
        turn=FuzzyVariable("t", (-1, 1, 201), {"zero": (-0.5, 0.0, 0.5)}),
        speed=FuzzyVariable("s", (0, 1, 101), {"lo": (0.0, 0.2, 0.4), "hi": (0.6, 0.8, 1.0)}),
        rules={("close", "any"): ("zero", "lo"), ("open", "any"): ("zero", "hi")})
    assert flc(0.0, 1.0)[1] == pytest.approx(0.2)
    assert flc(4.0, 1.0)[1] == pytest.approx(0.8)
    assert flc(2.0, 1.0)[1] == pytest.approx(0.5)
    with pytest.raises(dataclasses.FrozenInstanceError):
        flc.rules = {}
    with pytest.raises(TypeError):
        flc.rules[("close", "any")] = ("zero", "hi")
    with pytest.raises(TypeError):
        flc.distance.terms["close"] = (0, 1, 2)
    assert FuzzyController.default() == FuzzyController()


def _var(name="v", universe=(0.0, 1.0, 11), **terms):
    return FuzzyVariable(name, universe, terms or {"a": (0.0, 0.0, 1.0)})


@pytest.mark.parametrize("make, match", [
    (lambda: _var(universe=(1.0, 1.0, 11)), "min < max"),
    (lambda: _var(universe=(0.0, math.nan, 11)), "min < max"),
    (lambda: _var(universe=(0.0, 1.0, 2)), "n="),
    (lambda: _var(universe=(0.0, 1.0)), "universe"),
    (lambda: FuzzyVariable("v", (0.0, 1.0, 11), {}), "non-empty"),
    (lambda: _var(a=(0.0, 0.5)), "3 .triangle. or 4"),
    (lambda: _var(a=(0.5, 0.2, 1.0)), "sorted"),
    (lambda: _var(a=(0.0, 0.5, 1.5)), "inside the universe"),
    (lambda: _var(a=(0.0, 0.5, math.inf)), "finite"),
    (lambda: _var(a=(0.2, 0.2, 0.6)), "vertical edge"),
    (lambda: _var(a=(0.0, 0.5, 0.6, 0.6)), "vertical edge"),
    (lambda: _var(a=("x", 0.5, 1.0)), "numbers"),
])
def test_bad_variables_rejected(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def _rules(**changes):
    rules = dict(FLC.rules)
    rules.update(changes.get("update", {}))
    for key in changes.get("drop", ()):
        del rules[key]
    return rules


@pytest.mark.parametrize("kwargs, match", [
    ({"rules": _rules(update={("near", "ZE"): ("straight", "warp")})},
     "'warp' is not a term of speed"),
    ({"rules": _rules(update={("close", "ZE"): ("ZE", "slow")})}, "'close' is not a term"),
    ({"rules": _rules(drop=[("far", "PB")])}, "missing"),
    ({"rules": _rules(update={("near", "ZE"): "ZE"})}, "must be"),
    ({"turn": _var("turn", (0.5, 2.0, 11), a=(0.5, 0.5, 2.0))}, "must contain 0"),
    ({"speed": _var("speed", (0.5, 2.0, 11), a=(0.5, 0.5, 2.0))}, "must contain"),
    ({"distance": FuzzyVariable("distance", (0, 10, 11), {
        "near": (0, 0, 1, 2), "medium": (1, 2, 3), "far": (5, 6, 10, 10)})}, "no term covers"),
    ({"speed": FuzzyVariable("speed", (0, 1, 11), {
        "stop": (0, 0, 0.1), "slow": (0.01, 0.02, 0.03), "medium": (0.4, 0.5, 0.6),
        "fast": (0.9, 1, 1)})}, "zero on every point"),
    ({"heading": "not a variable"}, "must be a FuzzyVariable"),
])
def test_bad_controllers_rejected(kwargs, match):
    with pytest.raises(ValueError, match=match):
        FuzzyController(**kwargs)


@pytest.mark.parametrize("d, h, match", [
    (math.nan, 0.0, "d must not be NaN"), (1.0, math.nan, "dtheta"), (1.0, math.inf, "dtheta"),
    (np.array([1.0, math.nan]), 0.0, "d must not be NaN"),
    (np.ones(2), np.array([0.0, -math.inf]), "dtheta"),
    (np.ones(3), np.zeros(2), "broadcast"),
    (True, 0.0, "d must be an array of numbers"),
    (1.0, False, "dtheta must be an array of numbers"),
    ("1", 0.0, "d must be an array of numbers"), (["1"], [0.1], "d must be an array of numbers"),
    (np.array([True]), np.array([0.1]), "d must be an array of numbers"),
    (np.bool_(True), 0.1, "d must be an array of numbers"),
    ([1.0, None], 0.1, "d must be an array of numbers"),
    (1.0, [[0.1], [0.2, 0.3]], "dtheta must be an array of numbers"),
])
def test_bad_inputs_rejected(d, h, match):
    with pytest.raises(ValueError, match=match):
        FLC(d, h)


@pytest.mark.filterwarnings("ignore::DeprecationWarning")      # inside scikit-fuzzy 0.5
def test_matches_scikit_fuzzy():
    """Oracle: scikit-fuzzy's Mamdani (min AND, clipping, max aggregation, centroid) on the
    same sets and rules. Its inputs are fuzzified on a grid with the term corners on grid
    points, so both evaluate the same piecewise-linear memberships."""
    fuzz = pytest.importorskip("skfuzzy")
    ctrl = pytest.importorskip("skfuzzy.control")

    def var(cls, v: FuzzyVariable, n: int):
        lo, hi, _ = v.universe
        u = np.linspace(lo, hi, n)
        out = cls(u, v.name)
        for name, p in v.terms.items():
            out[name] = fuzz.trimf(u, list(p)) if len(p) == 3 else fuzz.trapmf(u, list(p))
        return out

    dist = var(ctrl.Antecedent, FLC.distance, 1001)           # 0.01 m: corners on the grid
    head = var(ctrl.Antecedent, FLC.heading, 801)             # pi / 400: corners on the grid
    turn = var(ctrl.Consequent, FLC.turn, FLC.turn.universe[2])
    speed = var(ctrl.Consequent, FLC.speed, FLC.speed.universe[2])
    rules = [ctrl.Rule(dist[d] & head[h], (turn[t], speed[s]))
             for (d, h), (t, s) in FLC.rules.items()]
    sim = ctrl.ControlSystemSimulation(ctrl.ControlSystem(rules))
    for d, h in [(0.3, 0.1), (1.5, 0.5), (2.2, -1.0), (4.2, 0.3), (5.5, -0.2), (7.0, 2.0),
                 (3.0, -2.7), (9.5, 0.05)]:
        sim.input["distance"], sim.input["heading"] = d, h
        sim.compute()
        omega, v = FLC(d, h)
        assert omega == pytest.approx(sim.output["turn"], abs=5e-4), (d, h)
        assert v == pytest.approx(sim.output["speed"], abs=5e-4), (d, h)
    # the largest difference found (a review's dense search): a clipped output term whose kink
    # falls between the output grid's points, the O(h^2) of the centroid (docs/safety.md)
    for h in (0.76794, -0.76794):
        sim.input["distance"], sim.input["heading"] = 0.5, h
        sim.compute()
        omega, v = FLC(0.5, h)
        assert 5e-4 < abs(omega - sim.output["turn"]) < 1e-3
        assert v == pytest.approx(sim.output["speed"], abs=5e-4)


def _old_fuzzify_scalar(x: float, table: tuple) -> list[float]:
    """The scalar memberships before issue 20's ninth round: Python floats, ``bisect``."""
    inner, fp, slope, left, lo, hi = table
    x = min(max(x, lo), hi)
    k = bisect.bisect_right(inner.tolist(), x)
    dx = x - left.tolist()[k]
    return [f + s * dx for f, s in zip(fp[:, k].tolist(), slope[:, k].tolist(), strict=True)]


def _old_infer_scalar(controller: FuzzyController, d: float, h: float) -> tuple[float, float]:
    """``_infer_scalar`` before issue 20's seventh round (the oracle): every rule in Python
    floats, NumPy for the clipping, the aggregation and the centroid."""
    tab = controller._tables
    names = [list(var.terms) for var in (controller.distance, controller.heading,
                                         controller.turn, controller.speed)]
    nt = len(names[2])
    rules = [(i, j, names[2].index(controller.rules[(dt, ht)][0]),
              nt + names[3].index(controller.rules[(dt, ht)][1]))
             for i, dt in enumerate(names[0]) for j, ht in enumerate(names[1])]
    mu_d = _old_fuzzify_scalar(d, tab["inputs"][0])
    mu_h = _old_fuzzify_scalar(h, tab["inputs"][1])
    grid = tab["grid"][:, 0, :]
    out = [0.0] * len(grid)
    for i, j, t, s in rules:
        w = min(mu_d[i], mu_h[j])
        if w > out[t]:
            out[t] = w
        if w > out[s]:
            out[s] = w
    clipped = np.minimum(np.array(out)[:, None], grid)
    ta, tm = clipped[:nt].max(axis=0) @ tab["moments"][0]
    sa, sm = clipped[nt:].max(axis=0) @ tab["moments"][1]
    return min(max(tm / ta, -1.0), 1.0), min(max(sm / sa, 0.0), 1.0)


def test_scalar_path_equals_the_old_code_bit_for_bit():
    """The scalar inference (only the fired rules, Python floats for the centroid) gives the
    old code's floats: random inputs, every term corner and its neighbours, the universe's
    ends and beyond, signed zeros, tiny values; the default controller and one whose terms
    overlap in threes and leave points with a single tiny membership."""
    custom = FuzzyController(
        distance=FuzzyVariable("d", (0.0, 5.0, 11), {"a": (0.0, 0.0, 1.0, 3.0),
                                                     "b": (0.5, 2.0, 4.0), "c": (1.0, 4.5, 5.0),
                                                     "e": (2.0, 5.0, 5.0)}),
        heading=FuzzyVariable("h", (-PI, PI, 9), {"n": (-PI, -PI, 0.0), "z": (-1.0, 0.0, 1.0),
                                                  "p": (0.0, PI, PI)}),
        turn=FuzzyVariable("t", (-1.0, 1.0, 101), {"r": (-1.0, -1.0, 0.2), "s": (-0.5, 0.0, 0.5),
                                                   "l": (-0.2, 1.0, 1.0)}),
        speed=FuzzyVariable("v", (0.0, 1.0, 77), {"lo": (0.0, 0.0, 0.6), "hi": (0.3, 1.0, 1.0)}),
        rules={(dt, ht): ({"n": "r", "z": "s", "p": "l"}[ht], "lo" if dt in "ab" else "hi")
               for dt in "abce" for ht in "nzp"})
    rng = np.random.default_rng(7)
    for controller in (FLC, custom):
        corners_d = [v for p in controller.distance.terms.values() for v in p]
        corners_h = [v for p in controller.heading.terms.values() for v in p]
        ds = [0.0, -0.0, 5e-324, 1e-300, math.inf, 1e9, *corners_d,
              *[math.nextafter(v, math.inf) for v in corners_d],
              *[math.nextafter(v, -math.inf) for v in corners_d],
              *rng.uniform(-1.0, 12.0, 400).tolist()]
        hs = [0.0, -0.0, 5e-324, -5e-324, PI, -PI, *corners_h,
              *[math.nextafter(v, math.inf) for v in corners_h],
              *[math.nextafter(v, -math.inf) for v in corners_h],
              *rng.uniform(-PI, PI, 400).tolist()]
        specials = [(d, h) for d in ds[:-400] for h in hs[:-400]]
        for d, h in specials + list(zip(ds[-400:], hs[-400:], strict=True)):
            got = controller._infer_scalar(d, h)
            want = _old_infer_scalar(controller, d, h)
            for g, w in zip(got, want, strict=True):
                assert isinstance(g, float)
                assert g == w and math.copysign(1.0, g) == math.copysign(1.0, w), (d, h)
