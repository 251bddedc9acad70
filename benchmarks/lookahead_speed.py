"""Speed of the safety stack's look-ahead and ORCA edge queries against a reference commit, in
one process, on the calls random-action AOASS-Safe-v0 episodes make.

The script records every ``escape_velocity`` call (aoass_env/safety/lookahead.py) and every
static-edge query (``StaticObstacles.edges_near`` and ORCA's own, ``_EdgeCache.near``) of
random-action AOASS-Safe-v0 episodes, then replays them through the reference commit's
functions (loaded from ``git show REF:path``) and the current ones, after one untimed pass of
each, in alternating rounds (the reference first in the odd-numbered rounds 1, 3, ..., second
in the even ones: ``git_history.in_turn``), checks that both give the same answers bit for bit,
and prints CPU microseconds per call and per Safe step and the speed-up (reference / current)
of each round.

The reference must take today's calls: since ``f61c563`` they pass the contest's
``tolerance``, so the default is the tenth round's reference ``f04fd57``; an earlier one (the
fifth round's ``ab67c18``) is refused in one line. Since the obstacles bounce off their own
edges (``bounce_starts``, ``bounce_ends``), a reference without them takes those edges among
the anchor's (:func:`reference_calls`): the same answers, for a few more edges in its
rollouts.

Run: ``python3 benchmarks/lookahead_speed.py [--ref f04fd57] [--steps 4000] [--rounds 5]``.
"""

from __future__ import annotations

import argparse
import atexit
import copy
import importlib.util
import inspect
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import ModuleType
from typing import Any

import gymnasium as gym
import numpy as np
from git_history import git_problem, in_turn

import aoass_env  # noqa: F401  (registers AOASS-Safe-v0)
from aoass_env import wrappers
from aoass_env.safety import lookahead, orca

ROOT = Path(__file__).resolve().parents[1]

#: the episodes recorded: (AOASS-Safe-v0 keywords, seed); the default config, and a small field
#: with many fast moving obstacles (the look-ahead escapes often)
EPISODES: tuple[tuple[dict[str, Any], int], ...] = (
    ({}, 0),
    ({"field_size": 70.0, "obstacle_density": 0.2, "n_moving_obstacles": 8,
      "moving_obstacle_speed": (0.5, 1.5)}, 13),
)


def reference_module(ref: str, path: str, name: str) -> ModuleType:
    """The module at ``path`` as of commit ``ref``, imported under ``name`` from a file in a
    temporary folder (removed at exit), where numba can cache its compiled functions; SystemExit
    with one line when git cannot read it there."""
    problem = git_problem(ref, path)
    if problem:
        raise SystemExit(f"--ref {ref}: {problem}")
    source = subprocess.run(["git", "show", f"{ref}:{path}"], cwd=ROOT, check=True,
                            capture_output=True, text=True).stdout
    folder = Path(tempfile.mkdtemp(prefix="aoass_ref_"))
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    file = folder / f"{name}.py"
    file.write_text(source)
    spec = importlib.util.spec_from_file_location(name, file)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def random_steps(env_id: str, kwargs: dict[str, Any], seed: int, steps: int) -> None:
    """``steps`` random actions in ``env_id`` made with ``kwargs``, seeded with ``seed``
    (reset whenever an episode ends)."""
    env = gym.make(env_id, **kwargs)
    env.action_space.seed(seed)
    env.reset(seed=seed)
    for _ in range(steps):
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            env.reset()


def record(steps: int) -> tuple[list[tuple[tuple, dict]], list[tuple[Any, float, float, float]],
                                int]:
    """(escape_velocity calls, edge queries (obstacles, x, y, reach), Safe steps taken) over
    ``steps`` random steps of each of :data:`EPISODES`."""
    calls: list[tuple[tuple, dict]] = []
    queries: list[tuple[Any, float, float, float]] = []
    original = wrappers.escape_velocity
    near = orca._EdgeCache.near

    def recording(*args: Any, **kwargs: Any) -> Any:
        calls.append(copy.deepcopy((args, kwargs)))
        return original(*args, **kwargs)

    def recording_near(self: Any, px: float, py: float, reach: float) -> list[int]:
        queries.append((self, px, py, reach))
        return near(self, px, py, reach)

    wrappers.escape_velocity = recording
    orca._EdgeCache.near = recording_near
    try:
        for kwargs, seed in EPISODES:
            random_steps("AOASS-Safe-v0", kwargs, seed, steps)
    finally:
        wrappers.escape_velocity = original
        orca._EdgeCache.near = near
    return calls, queries, steps * len(EPISODES)


#: the replay benchmarks' default reference: issue 20's tenth round's, whose functions take
#: today's calls
REFERENCE = "f04fd57"


def replayable(function: Any, calls: list[tuple[tuple, dict]], ref: str, name: str) -> None:
    """Exit with one line when ``function`` (``name`` as of commit ``ref``) cannot take the
    arguments of the recorded ``calls`` (a parameter added since ``ref``), or when no call was
    recorded (too few --steps: the per-call times divided by zero)."""
    if not calls:
        raise SystemExit(f"no {name} call was recorded in the replayed steps; give more --steps")
    signature = inspect.signature(function)
    for args, kwargs in calls:
        try:
            signature.bind(*args, **kwargs)
        except TypeError as error:
            raise SystemExit(f"--ref {ref}: its {name} cannot replay today's calls ({error}); "
                             f"choose a later commit, e.g. the default {REFERENCE}") from None


def reference_calls(function: Any, calls: list[tuple[tuple, dict]]
                    ) -> list[tuple[tuple, dict]]:
    """``calls`` of ``escape_velocity`` as a reference ``function`` that predates the obstacles'
    own edges takes them: their ``bounce_starts`` and ``bounce_ends`` joined to the anchor's
    ``starts`` and ``ends`` (each edge once, the anchor's first). The answers are the same: the
    anchor's edges hold every edge its rollouts can meet and the obstacles' every edge they can
    bounce off, so the edges added to either lie beyond what it reads. A reference that takes
    them gets ``calls`` unchanged."""
    if "bounce_starts" in inspect.signature(function).parameters:
        return calls
    adapted = []
    for args, kwargs in calls:
        if "bounce_starts" not in kwargs:
            adapted.append((args, kwargs))
            continue
        kwargs = dict(kwargs)
        bounce_starts, bounce_ends = kwargs.pop("bounce_starts"), kwargs.pop("bounce_ends")
        edges = np.concatenate([np.hstack([kwargs["starts"], kwargs["ends"]]),
                                np.hstack([bounce_starts, bounce_ends])])
        _, first = np.unique(edges, axis=0, return_index=True)
        edges = edges[np.sort(first)]
        kwargs["starts"], kwargs["ends"] = edges[:, :2].copy(), edges[:, 2:].copy()
        adapted.append((args, kwargs))
    return adapted


def timed(function: Any, calls: list[tuple[tuple, dict]]) -> tuple[float, list[Any]]:
    """(CPU seconds, results) of ``function`` over ``calls``."""
    start = time.process_time()
    results = [function(*args, **kwargs) for args, kwargs in calls]
    return time.process_time() - start, results


def timed_in_turn(round_: int, *replays: tuple[Any, list[tuple[tuple, dict]]]
                  ) -> list[tuple[float, list[Any]]]:
    """:func:`timed` of each (function, calls) of ``replays``, run in round ``round_``'s order
    (``git_history.in_turn``: the first given, the reference, leads the rounds 0, 2, ...);
    returned in the order given."""
    done = {k: timed(*replays[k]) for k in in_turn(round_, *range(len(replays)))}
    return [done[k] for k in range(len(replays))]


def warm_up(*replays: tuple[Any, list[tuple[tuple, dict]]]) -> None:
    """One untimed pass of each (function, calls): a reference's kernels compile on their first
    calls (one version per kind of argument), the current ones load from numba's cache."""
    for function, calls in replays:
        timed(function, calls)


def same_escape(a: Any, b: Any) -> bool:
    return (np.array_equal(a.velocity, b.velocity) and a.escaping == b.escaping
            and a.shortfall == b.shortfall and a.chosen_shortfall == b.chosen_shortfall)


def replay_arguments(doc: str, ref: str, steps: int, rounds: int,
                     paths: tuple[str, ...] = ()) -> argparse.Namespace:
    """The validated ``--ref``, ``--steps`` and ``--rounds`` of a replay benchmark (described
    by the first line of ``doc``), with these defaults; ``--ref`` must hold the files ``paths``
    (a commit that does not exist was a CalledProcessError traceback)."""
    parser = argparse.ArgumentParser(description=doc.split("\n")[0])
    parser.add_argument("--ref", default=ref, help="reference commit")
    parser.add_argument("--steps", type=int, default=steps, help="random steps per episode")
    parser.add_argument("--rounds", type=int, default=rounds,
                        help="timing rounds, the reference first in every other one")
    args = parser.parse_args()
    if args.steps < 1 or args.rounds < 1:
        parser.error("--steps and --rounds must be positive")
    for path in paths:
        problem = git_problem(args.ref, path)
        if problem:
            parser.error(f"--ref {args.ref}: {problem}")
    return args


def main() -> None:
    args = replay_arguments(__doc__, REFERENCE, 4000, 5,
                            ("aoass_env/safety/lookahead.py", "aoass_env/safety/orca.py"))
    old_lookahead = reference_module(args.ref, "aoass_env/safety/lookahead.py", "lookahead_ref")
    old_orca = reference_module(args.ref, "aoass_env/safety/orca.py", "orca_ref")
    calls, queries, steps = record(args.steps)
    old_calls = reference_calls(old_lookahead.escape_velocity, calls)
    replayable(old_lookahead.escape_velocity, old_calls, args.ref, "escape_velocity")
    # the reference's edge queries: its own _EdgeCache built from the same obstacle arrays
    caches = {}
    for cache, *_ in queries:
        if id(cache) not in caches:
            edges, links = cache.edges, cache.links      # rows [ax, ay, ..., dx, dy]
            caches[id(cache)] = old_orca._EdgeCache.build(
                edges[:, :2].copy(), edges[:, 7:9].copy(), links[:, 0].copy(),
                links[:, 1].copy(), links[:, 2].astype(bool))
    old_queries = [((caches[id(c)], x, y, r), {}) for c, x, y, r in queries]
    new_queries = [((c, x, y, r), {}) for c, x, y, r in queries]
    print(f"recorded {len(calls)} escape_velocity calls and {len(queries)} edge queries in "
          f"{steps} AOASS-Safe-v0 steps; reference {args.ref}")
    print(f"{'round':>5s} {'look-ahead ref':>15s} {'now':>8s} {'speed-up':>8s}   "
          f"{'edge query ref':>15s} {'now':>8s} {'speed-up':>8s}   (CPU us per Safe step)")
    warm_up((old_lookahead.escape_velocity, old_calls), (lookahead.escape_velocity, calls),
            (old_orca._EdgeCache.near, old_queries), (orca._EdgeCache.near, new_queries))
    for i in range(args.rounds):
        (t_old, r_old), (t_new, r_new) = timed_in_turn(
            i, (old_lookahead.escape_velocity, old_calls), (lookahead.escape_velocity, calls))
        (q_old, a_old), (q_new, a_new) = timed_in_turn(
            i, (old_orca._EdgeCache.near, old_queries), (orca._EdgeCache.near, new_queries))
        if not all(same_escape(a, b) for a, b in zip(r_old, r_new, strict=True)):
            raise SystemExit("escape_velocity differs from the reference")
        if a_old != a_new:
            raise SystemExit("edge queries differ from the reference")
        print(f"{i + 1:5d} {1e6 * t_old / steps:15.1f} {1e6 * t_new / steps:8.1f} "
              f"{t_old / t_new:8.2f}   {1e6 * q_old / steps:15.1f} {1e6 * q_new / steps:8.1f} "
              f"{q_old / q_new:8.2f}")
    print(f"per call: look-ahead {1e6 * t_old / len(calls):.0f} -> {1e6 * t_new / len(calls):.0f}"
          f" us, edge query {1e6 * q_old / len(queries):.1f} -> "
          f"{1e6 * q_new / len(queries):.1f} us (last round); answers identical")


if __name__ == "__main__":
    main()
