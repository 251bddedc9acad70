"""Speed of the Eq. 7 fuzzy controller (aoass_env.safety.fuzzy).

Prints microseconds per scalar call ``FuzzyController()(d, dtheta)`` (target < 30 us), per
element of a vectorised call on ``--batch`` points, and, when scikit-fuzzy (``skfuzzy``) is
installed, per scalar call of its Mamdani control system with the same sets and rules: the
reference, timed the same way in the same process on the same 64 inputs, and the ratio of
the scalar calls, ours / skfuzzy's (< 1: ours is faster). Best of three passes.

Run: ``python3 benchmarks/fuzzy.py [--calls 20000] [--batch 10000] [--sk-calls 200]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from aoass_env.safety.fuzzy import FuzzyController
from aoass_env.validators import argparse_number


def best_of_three(fn, n: int) -> float:
    """Best of three passes of ``n`` calls, seconds per call."""
    best = float("inf")
    for _ in range(3):
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        best = min(best, (time.perf_counter() - t0) / n)
    return best


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--calls", type=argparse_number(int, 1), default=20000)
    parser.add_argument("--batch", type=argparse_number(int, 1), default=10000)
    parser.add_argument("--sk-calls", type=argparse_number(int, 1), default=200,
                        help="scalar calls per pass of skfuzzy's control system (ms each)")
    args = parser.parse_args(argv)
    flc = FuzzyController()
    rng = np.random.default_rng(0)
    pts = list(zip(rng.uniform(0, 10, 64).tolist(), rng.uniform(-3, 3, 64).tolist(),
                   strict=True))
    it = iter(range(10 ** 9))
    ours = best_of_three(lambda: flc(*pts[next(it) % 64]), args.calls)
    print(f"scalar call                : {ours * 1e6:7.1f} us")
    d, h = rng.uniform(0, 10, args.batch), rng.uniform(-3, 3, args.batch)
    t = best_of_three(lambda: flc(d, h), 3)
    print(f"vectorised, {args.batch} points : {t / args.batch * 1e6:7.2f} us per point "
          f"({t * 1e3:.1f} ms)")
    try:
        import skfuzzy as fuzz
        from skfuzzy import control as ctrl
    except ImportError:
        print("skfuzzy not installed (pip install scikit-fuzzy): no reference, no ratio")
        return

    def var(cls, v):
        lo, hi, n = v.universe
        u = np.linspace(lo, hi, n)
        out = cls(u, v.name)
        for name, p in v.terms.items():
            out[name] = fuzz.trimf(u, list(p)) if len(p) == 3 else fuzz.trapmf(u, list(p))
        return out

    dist, head = var(ctrl.Antecedent, flc.distance), var(ctrl.Antecedent, flc.heading)
    turn, speed = var(ctrl.Consequent, flc.turn), var(ctrl.Consequent, flc.speed)
    sim = ctrl.ControlSystemSimulation(ctrl.ControlSystem(
        [ctrl.Rule(dist[a] & head[b], (turn[c], speed[e]))
         for (a, b), (c, e) in flc.rules.items()]), cache=False)

    def sk() -> None:
        x, y = pts[next(it) % 64]
        sim.input["distance"], sim.input["heading"] = x, y
        sim.compute()

    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        t = best_of_three(sk, args.sk_calls)
    print(f"scikit-fuzzy scalar call   : {t * 1e6:7.1f} us")
    print(f"ratio ours / skfuzzy (scalar calls): {ours / t:.3g} (skfuzzy takes {t / ours:.0f} "
          f"x as long)")


if __name__ == "__main__":
    main()
