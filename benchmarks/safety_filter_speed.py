"""Speed of the safety filter's functions changed in issue 20's fifth round against a reference
commit, in one process, on the calls random-action AOASS-Safe-v0 episodes make.

The script records every ``escape_velocity`` call (aoass_env/safety/lookahead.py), every action
decoding (``checked_action``: the agent's action in the filter and the filter's command in the
bare env) and every command encoding (``ResidualAction.action``) of the episodes of
``lookahead_speed.EPISODES``, replays them through the reference commit's modules (loaded with
``git show``) and the current ones, after one untimed pass of each, in alternating rounds (the
reference first in the odd-numbered rounds, second in the even ones:
``lookahead_speed.timed_in_turn``), checks that the answers are identical
(floats compared by their bits, signs of zeros included) and prints CPU microseconds per call
and the speed-up (reference / current) of each round.

The reference must take today's calls (``lookahead_speed.replayable``): the fifth round's
``ee9ff79`` no longer does (``escape_velocity`` has taken a ``tolerance`` since ``f61c563``), so
the default is ``lookahead_speed.REFERENCE``; a reference from before the obstacles' own edges
takes them among the anchor's (``lookahead_speed.reference_calls``).

Run: ``python3 benchmarks/safety_filter_speed.py [--ref f04fd57] [--steps 3000] [--rounds 3]``.
"""

from __future__ import annotations

import copy
import struct
from typing import Any

import numpy as np

import aoass_env  # noqa: F401  (registers the envs)
from aoass_env import action as action_module
from aoass_env import wrappers
from aoass_env.safety import lookahead

try:
    from benchmarks.lookahead_speed import (
        EPISODES,
        REFERENCE,
        random_steps,
        reference_calls,
        reference_module,
        replay_arguments,
        replayable,
        same_escape,
        timed_in_turn,
        warm_up,
    )
except ImportError:         # run as a script from benchmarks/
    from lookahead_speed import (  # type: ignore[no-redef]
        EPISODES,
        REFERENCE,
        random_steps,
        reference_calls,
        reference_module,
        replay_arguments,
        replayable,
        same_escape,
        timed_in_turn,
        warm_up,
    )

Calls = list[tuple[tuple, dict]]


def record(steps: int) -> tuple[Calls, Calls, Calls]:
    """(escape_velocity calls, checked_action calls, ResidualAction.action calls) over
    ``steps`` random steps of each of ``EPISODES``."""
    escapes: Calls = []
    checks: Calls = []
    encodes: Calls = []
    escape, check = wrappers.escape_velocity, action_module.checked_action
    encode = action_module.ResidualAction.action

    def recording_escape(*args: Any, **kwargs: Any) -> Any:
        escapes.append(copy.deepcopy((args, kwargs)))
        return escape(*args, **kwargs)

    def recording_check(*args: Any, **kwargs: Any) -> Any:
        checks.append(copy.deepcopy((args, kwargs)))
        return check(*args, **kwargs)

    def recording_encode(self: Any, *args: Any, **kwargs: Any) -> Any:
        encodes.append(((self, *args), kwargs))
        return encode(self, *args, **kwargs)

    wrappers.escape_velocity = recording_escape
    action_module.checked_action = recording_check
    action_module.ResidualAction.action = recording_encode
    try:
        for kwargs, seed in EPISODES:
            random_steps("AOASS-Safe-v0", kwargs, seed, steps)
    finally:
        wrappers.escape_velocity = escape
        action_module.checked_action = check
        action_module.ResidualAction.action = encode
    return escapes, checks, encodes


def bits(values: Any) -> list[bytes]:
    """The float64 bits of each value (NaN and signed zeros told apart)."""
    return [struct.pack("<d", float(v)) for v in np.ravel(np.asarray(values, np.float64))]


def main() -> None:
    args = replay_arguments(__doc__, REFERENCE, 3000, 3,
                            ("aoass_env/safety/lookahead.py", "aoass_env/action.py"))
    old_lookahead = reference_module(args.ref, "aoass_env/safety/lookahead.py", "lookahead_old")
    old_action = reference_module(args.ref, "aoass_env/action.py", "action_old")
    escapes, checks, encodes = record(args.steps)
    steps = args.steps * len(EPISODES)
    # the reference's ResidualAction.action on the same (self, speed, heading, nominal, knobs)
    old_encodes = [((old_action.ResidualAction(a[0].speed_scale, a[0].heading_scale,
                                               a[0].max_speed), *a[1:]), k) for a, k in encodes]
    print(f"recorded {len(escapes)} escape_velocity, {len(checks)} checked_action and "
          f"{len(encodes)} ResidualAction.action calls in {steps} AOASS-Safe-v0 steps; "
          f"reference {args.ref}")
    parts = (("escape_velocity", old_lookahead.escape_velocity, lookahead.escape_velocity,
              reference_calls(old_lookahead.escape_velocity, escapes), escapes, same_escape),
             ("checked_action", old_action.checked_action, action_module.checked_action,
              checks, checks, lambda a, b: bits(a) == bits(b)),
             ("ResidualAction.action", old_action.ResidualAction.action,
              action_module.ResidualAction.action, old_encodes,
              [((a[0], *a[1:]), k) for a, k in encodes],
              lambda a, b: a.dtype == b.dtype and bits(a) == bits(b)))
    for name, old, new, old_calls, new_calls, _ in parts:
        replayable(old, old_calls, args.ref, name)
        warm_up((old, old_calls), (new, new_calls))
    for i in range(args.rounds):
        for name, old, new, old_calls, new_calls, same in parts:
            (t_old, r_old), (t_new, r_new) = timed_in_turn(i, (old, old_calls), (new, new_calls))
            if not all(same(a, b) for a, b in zip(r_old, r_new, strict=True)):
                raise SystemExit(f"{name} differs from the reference")
            print(f"round {i + 1}: {name:22s} {1e6 * t_old / len(old_calls):8.2f} -> "
                  f"{1e6 * t_new / len(new_calls):8.2f} us per call ({len(new_calls)} calls), "
                  f"{t_old / t_new:5.2f} x; {1e6 * (t_old - t_new) / steps:5.2f} us per Safe "
                  f"step saved; answers identical")


if __name__ == "__main__":
    main()
