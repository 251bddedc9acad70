"""Speed of ``unicycle_command`` (aoass_env/safety/unicycle.py) and of the waypoint follower's
``command`` (aoass_env/planning/follower.py) against a reference commit, in one process, on the
calls random-action episodes make.

The script records every ``unicycle_command`` call of random-action AOASS-Safe-v0 episodes (the
default config and a 70 m field with 8 fast moving obstacles) and, for the follower, each
episode's follower as it is at its first command together with the (position, heading, dt) of
every call of random-action AOASS-v0 episodes (the default 100 m field and 200 m fields at
densities 0.2 and 0.4). It replays them through the reference commit's modules (loaded from
``git show REF:path``) and the current ones, after one untimed pass of each, in alternating
rounds (the reference first in the odd-numbered rounds 1, 3, ..., second in the even ones:
``git_history.in_turn``), checks that both give the same answers bit for bit (the follower:
every command, and its index, clock, budget, recoveries and skips at the end), and prints CPU
microseconds per call and the speed-up (reference / current).
The follower is timed twice: with its planner's searches (``DetourPlanner.path``, the same code
in both) and without them (their answers recorded once and handed back), which isolates the
follower's own per-step path.

Run: ``python3 benchmarks/unicycle_follower_speed.py [--ref 3fdd7e9] [--steps 3000]
[--rounds 3]``.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
from git_history import in_turn

import aoass_env  # noqa: F401  (registers the envs)
from aoass_env import wrappers
from aoass_env.planning import detour
from aoass_env.planning.follower import WaypointFollower
from aoass_env.safety import unicycle

try:
    from benchmarks.lookahead_speed import (
        random_steps,
        reference_module,
        replay_arguments,
        timed_in_turn,
        warm_up,
    )
except ImportError:         # run as a script from benchmarks/
    from lookahead_speed import (  # type: ignore[no-redef]
        random_steps,
        reference_module,
        replay_arguments,
        timed_in_turn,
        warm_up,
    )

#: AOASS-Safe-v0 episodes whose unicycle_command calls are recorded: (keywords, seed)
SAFE_EPISODES: tuple[tuple[dict[str, Any], int], ...] = (
    ({}, 0),
    ({"field_size": 70.0, "obstacle_density": 0.2, "n_moving_obstacles": 8,
      "moving_obstacle_speed": (0.5, 1.5)}, 13),
)
#: AOASS-v0 cases whose follower calls are recorded: (label, keywords, seed)
FOLLOWER_CASES: tuple[tuple[str, dict[str, Any], int], ...] = (
    ("100 m", {}, 3),
    ("200 m d0.2", {"field_size": 200.0}, 3),
    ("200 m d0.4", {"field_size": 200.0, "obstacle_density": 0.4}, 5),
)


def record_unicycle(steps: int) -> list[tuple[tuple, dict]]:
    """The arguments of every unicycle_command call of :data:`SAFE_EPISODES`."""
    calls: list[tuple[tuple, dict]] = []
    original = wrappers.unicycle_command

    def recording(*args: Any, **kwargs: Any) -> Any:
        calls.append(copy.deepcopy((args, kwargs)))
        return original(*args, **kwargs)

    wrappers.unicycle_command = recording
    try:
        for kwargs, seed in SAFE_EPISODES:
            random_steps("AOASS-Safe-v0", kwargs, seed, steps)
    finally:
        wrappers.unicycle_command = original
    return calls


def record_follower(steps: int) -> dict[str, list[tuple[WaypointFollower, list]]]:
    """label -> [(the follower before its first command, [(position, heading, dt), ...])]."""
    cases: dict[str, list[tuple[WaypointFollower, list]]] = {}
    original = WaypointFollower.command
    episodes: dict[int, tuple[WaypointFollower, list]] = {}

    depth = [0]

    def recording(self: WaypointFollower, position: np.ndarray, heading: float,
                  dt: float) -> Any:
        if depth[0]:        # the follower's own re-entry (after a back-out): not a call
            return original(self, position, heading, dt)
        if id(self) not in episodes:
            episodes[id(self)] = (copy.deepcopy(self), [])
            current.append(episodes[id(self)])
        episodes[id(self)][1].append((np.array(position, dtype=np.float64), heading, dt))
        depth[0] += 1
        try:
            return original(self, position, heading, dt)
        finally:
            depth[0] -= 1

    WaypointFollower.command = recording
    try:
        for label, kwargs, seed in FOLLOWER_CASES:
            current: list[tuple[WaypointFollower, list]] = []
            random_steps("AOASS-v0", kwargs, seed, steps)
            cases[label] = current
            episodes.clear()
    finally:
        WaypointFollower.command = original
    return cases


def as_class(follower: WaypointFollower, cls: type) -> Any:
    """A copy of ``follower``'s state as an instance of ``cls`` (the reference's class)."""
    out = cls.__new__(cls)
    out.__dict__.update(copy.deepcopy(follower.__dict__))
    return out


def replay(followers: list[Any], episodes: list[tuple[WaypointFollower, list]]
           ) -> tuple[float, list]:
    """(CPU seconds, [(commands, end state)]) of ``followers`` (fresh copies, one per
    episode) fed the recorded calls."""
    seconds, results = 0.0, []
    for follower, (_, calls) in zip(followers, episodes, strict=True):
        start = time.process_time()
        commands = [follower.command(p, h, dt) for p, h, dt in calls]
        seconds += time.process_time() - start
        state = (follower.index, follower._clock, follower._budget, follower.recoveries,
                 [(s.index, s.time, s.reason) for s in follower.skipped])
        results.append((commands, state))
    return seconds, results


def replay_in_turn(round_: int, episodes: list[tuple[WaypointFollower, list]], old_class: type,
                   play: Callable[[], None] | None = None) -> tuple[tuple[float, list], ...]:
    """(reference, current) :func:`replay` of ``episodes``: the reference's followers (copies as
    ``old_class``) and the current ones, run in round ``round_``'s order (``in_turn``: the
    reference leads the rounds 0, 2, ...); ``play``, when given, is called before each (the
    searches' answers handed back from the first)."""
    done = {}
    for side in in_turn(round_, "reference", "current"):
        followers = [as_class(f, old_class) if side == "reference" else copy.deepcopy(f)
                     for f, _ in episodes]
        if play:
            play()
        done[side] = replay(followers, episodes)
    return done["reference"], done["current"]


class _Answers:
    """DetourPlanner.path recorded once (``record``), then handed back in order (``play``)."""

    def __init__(self) -> None:
        self.original = detour.DetourPlanner.path
        self.answers: list[Any] = []
        self.it: Iterator[Any] = iter(())

    def record(self) -> None:
        answers, original = self.answers, self.original

        def recording(planner: Any, *args: Any, **kwargs: Any) -> Any:
            answers.append(original(planner, *args, **kwargs))
            return answers[-1]
        detour.DetourPlanner.path = recording

    def play(self) -> None:
        self.it = iter(self.answers)
        detour.DetourPlanner.path = lambda planner, *args, **kwargs: next(self.it)

    def restore(self) -> None:
        detour.DetourPlanner.path = self.original


def main() -> None:
    args = replay_arguments(__doc__, "3fdd7e9", 3000, 3,
                            ("aoass_env/safety/unicycle.py", "aoass_env/planning/follower.py"))
    old_unicycle = reference_module(args.ref, "aoass_env/safety/unicycle.py", "unicycle_ref")
    old_follower = reference_module(args.ref, "aoass_env/planning/follower.py", "follower_ref")

    calls = record_unicycle(args.steps)
    if not calls:       # the per-call times would divide by zero
        raise SystemExit("no unicycle_command call was recorded; give more --steps")
    old_calls = [(a[:8] + ((None if a[8] is None else old_unicycle.BrakingEnvelope(
        a[8].starts, a[8].ends, a[8].position, a[8].radius, a[8].max_accel, a[8].dt)),), k)
        for a, k in calls]
    print(f"unicycle_command: {len(calls)} calls recorded in {len(SAFE_EPISODES)} x "
          f"{args.steps} AOASS-Safe-v0 steps; reference {args.ref}")
    print(f"{'round':>5s} {'reference':>10s} {'now':>8s} {'speed-up':>8s}   (CPU us per call)")
    warm_up((old_unicycle.unicycle_command, old_calls), (unicycle.unicycle_command, calls))
    for i in range(args.rounds):
        (t_old, r_old), (t_new, r_new) = timed_in_turn(
            i, (old_unicycle.unicycle_command, old_calls), (unicycle.unicycle_command, calls))
        if r_old != r_new:
            raise SystemExit("unicycle_command differs from the reference")
        print(f"{i + 1:5d} {1e6 * t_old / len(calls):10.1f} {1e6 * t_new / len(calls):8.1f} "
              f"{t_old / t_new:8.2f}")

    cases = record_follower(args.steps)
    answers = _Answers()
    print(f"\nWaypointFollower.command: {args.steps} AOASS-v0 steps per case; reference "
          f"{args.ref} (CPU us per call; 'searches': with the planner's searches, "
          f"'own': their answers handed back)")
    print(f"{'round':>5s} {'case':>11s} {'searches ref':>12s} {'now':>7s} {'speed-up':>8s}   "
          f"{'own ref':>8s} {'now':>7s} {'speed-up':>8s}")
    for episodes in cases.values():     # one untimed pass of each, as the unicycle's warm_up
        replay_in_turn(0, episodes, old_follower.WaypointFollower)
    for i in range(args.rounds):
        for label, episodes in cases.items():
            n = sum(len(c) for _, c in episodes)
            row = []
            for own in (False, True):
                if own:         # the searches' answers, recorded once, then handed back
                    answers.record()
                    try:
                        replay([copy.deepcopy(f) for f, _ in episodes], episodes)
                    finally:
                        answers.restore()
                try:
                    (t_old, a_old), (t_new, a_new) = replay_in_turn(
                        i, episodes, old_follower.WaypointFollower, answers.play if own else None)
                finally:
                    answers.restore()
                if a_old != a_new:
                    raise SystemExit(f"the follower differs from the reference ({label})")
                row.append((t_old, t_new))
            answers.answers.clear()
            print(f"{i + 1:5d} {label:>11s} " + "   ".join(
                f"{1e6 * a / n:12.1f} {1e6 * b / n:7.1f} {a / b:8.2f}" for a, b in row))
    print("answers identical")


if __name__ == "__main__":
    main()
