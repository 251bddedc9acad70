"""The situation of every moving contact in the safety stack (issue 24): why contacts happen.

Runs the episodes of ``benchmarks/safety.py``'s contacts part (or of its cost part with
``--policy zero``) -- the same maps, seeds and actions, one stack of its ``STACKS`` per run --
and logs, for each contact with a moving obstacle, the 16 control periods before it: the
nearest obstacle's offset and velocity, the anchor's velocity, speed and heading, the executed
command, whether the look-ahead escaped and whether it yielded, its shortfall, the number of
static ORCA lines active (the anchor pressed against walls), the gap to the nearest obstacle,
and the Kalman track of that obstacle (position and velocity error, position std). One JSON
line per episode is appended to ``--out`` as it ends (a run cut short keeps what it did), and
a summary is printed: contacts per 100 episodes by density, and how many contacts came while
or just after escaping, while yielding, at speed, or with the anchor standing pinned.

Run: ``python3 benchmarks/safety_contacts.py --stack stack --episodes 150 --first-seed 61000
--out out/contacts_stack.jsonl [--policy random|zero] [--jobs 2] [--set FIELD=JSON ...]
[--env FIELD=JSON ...]`` (``--set`` changes fields of the stack, e.g. ``escape_budget=10``,
``--env`` fields of the environment's AOASSConfig, e.g. ``replan_excess=30``);
``--summary FILE ...`` prints the summary of earlier runs.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections import deque
from multiprocessing import Pool
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from safety import DENSITIES, STACKS  # noqa: E402  (benchmarks/safety.py)

from aoass_env.atomic import folder_problem, write_text_atomic  # noqa: E402
from aoass_env.config import AOASSConfig  # noqa: E402
from aoass_env.safety.lookahead import position_std  # noqa: E402
from aoass_env.validators import argparse_number  # noqa: E402
from aoass_env.wrappers import make_safe_env  # noqa: E402

#: control periods logged before each contact
HISTORY = 16
#: AOASSConfig fields of the environment changed by ``--env`` (read by the forked workers)
ENV_FIELDS: dict = {}


def episode(task: tuple[str, str, float, int]) -> dict:
    """One episode of ``benchmarks/safety.py``'s ``episode`` (policy, stack label, density,
    seed: the same actions and map) with each moving contact's history."""
    policy, label, density, seed = task
    env = make_safe_env(safety=STACKS[label], **{**ENV_FIELDS, "obstacle_density": density})
    rng = np.random.default_rng(seed + 1_000_003)
    env.reset(seed=seed)
    world = env.unwrapped.sim.world
    tracker = env.env
    reach = world.config.anchor_radius + world.config.moving_obstacle_radius
    history: deque = deque(maxlen=HISTORY)
    contacts, seen, separation = [], 0, math.inf
    while True:
        action = (rng.uniform(-1.0, 1.0, 2) if policy == "random"
                  else np.zeros(2)).astype(np.float32)
        _, _, terminated, truncated, info = env.step(action)
        report, anchor = info["safety"], env.unwrapped.anchor
        moving, velocity = world.moving_positions, world.moving_velocities
        row = {"escaping": report["escaping"], "yielding": report["yielding"],
               "shortfall": report["look_ahead_shortfall"],
               "static_active": report["active_static"], "speed": float(anchor.speed),
               "heading": float(anchor.heading), "velocity": list(map(float, anchor.velocity)),
               "command": [report["speed_cmd"], report["heading_cmd"]],
               "obstacle_gap": float(anchor.obstacle_gap)}
        if len(moving):
            gap = np.hypot(*(moving - world.position).T) - reach
            j = int(np.argmin(gap))
            separation = min(separation, float(gap[j]))
            row.update(gap=float(gap[j]), offset=list(map(float, moving[j] - world.position)),
                       obstacle_velocity=list(map(float, velocity[j])))
            tracks = tracker.tracked_obstacles
            if len(tracks):
                error = np.hypot(*(tracks[:, :2] - moving[j]).T)
                k = int(np.argmin(error))
                std = position_std(tracker.tracked_covariances[k:k + 1], np.zeros(1))[0, 0]
                row["track"] = {"error": float(error[k]), "std": float(std),
                                "velocity_error": float(np.hypot(*(tracks[k, 2:4]
                                                                   - velocity[j])))}
        history.append(row)
        if info["moving_contacts"] > seen:
            seen = info["moving_contacts"]
            contacts.append({"period": int(info["time"] / world.config.dt),
                             "history": list(history)})
        if terminated or truncated:
            break
    ep = info["episode_metrics"]
    env.close()
    return {"label": label, "policy": policy, "density": density, "seed": seed,
            "moving_contacts": info["moving_contacts"],
            "static_contacts": info["static_contacts"] + info["wall_contacts"],
            "coverage": ep["coverage"], "complete": bool(ep["path_complete"]),
            "time": info["time"], "path_length": info["path_length"],
            "min_separation": separation, "contacts": contacts}


def summary(rows: list[dict]) -> dict:
    """Contacts per 100 episodes (overall, by density) and what the contacts had in common."""
    n = len(rows)
    found = [c for r in rows for c in r["contacts"]]
    last = [c["history"][-1] for c in found]
    tracked = [h["track"] for c in found for h in c["history"][-4:-1] if "track" in h]
    out = {"episodes": n, "moving_contacts": sum(r["moving_contacts"] for r in rows),
           "static_contacts": sum(r["static_contacts"] for r in rows),
           "complete": sum(r["complete"] for r in rows),
           "coverage": float(np.mean([r["coverage"] for r in rows])),
           "path_length": float(np.mean([r["path_length"] for r in rows])),
           "time": float(np.mean([r["time"] for r in rows])),
           "median_min_separation": float(np.median([r["min_separation"] for r in rows])),
           "escaping_in_last_8": sum(any(h["escaping"] for h in c["history"][-8:])
                                     for c in found),
           "yielding": sum(h["yielding"] for h in last),
           "at_speed": sum(h["speed"] >= 1.0 for h in last),
           "pinned": sum(h["speed"] < 0.1 and h["static_active"] >= 2 for h in last),
           "track_error_median": float(np.median([t["error"] for t in tracked]))
           if tracked else math.nan,
           "track_std_max": max((t["std"] for t in tracked), default=math.nan)}
    out["moving_per_100"] = 100 * out["moving_contacts"] / max(n, 1)
    out["by_density"] = {str(d): [sum(r["density"] == d for r in rows),
                                  sum(r["moving_contacts"] for r in rows if r["density"] == d)]
                         for d in DENSITIES}
    return out


def _fields(items: list[str], flag: str) -> dict:
    """``FIELD=JSON`` items as a dict; ValueError naming ``flag`` and the bad item."""
    fields = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise ValueError(f"{flag} {item!r}: expected FIELD=JSON, e.g. escape_budget=10")
        try:
            fields[key] = json.loads(value)
        except json.JSONDecodeError:
            raise ValueError(f"{flag} {item!r}: {value!r} is not JSON (a number, true, false "
                             "or null)") from None
    return fields


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--stack", default="stack", choices=[k for k in STACKS if k != "bare"])
    parser.add_argument("--policy", default="random", choices=["random", "zero"])
    parser.add_argument("--episodes", type=int, default=150)
    parser.add_argument("--first-seed", type=argparse_number(int, 0), default=61_000)
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--out", type=Path, default=Path("out/safety_contacts.jsonl"))
    parser.add_argument("--set", nargs="+", default=[], metavar="FIELD=JSON",
                        help="change fields of the stack's SafetyConfig, e.g. escape_budget=10 "
                             "yield_shortfall_tolerance=null")
    parser.add_argument("--env", nargs="+", default=[], metavar="FIELD=JSON",
                        help="change fields of the environment's AOASSConfig, e.g. "
                             "replan_excess=30")
    parser.add_argument("--summary", type=Path, nargs="+",
                        help="print the summary of these earlier runs and stop")
    args = parser.parse_args(argv)
    for flag in ("episodes", "jobs"):
        if getattr(args, flag) < 1:
            parser.error(f"--{flag} must be at least 1, got {getattr(args, flag)}")
    if args.summary:
        for path in args.summary:
            try:
                rows = [json.loads(line) for line in path.read_text(encoding="utf-8")
                        .splitlines() if line]
                print(path, json.dumps(summary(rows)))
            except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError) as exc:
                parser.error(f"--summary {path}: not a safety_contacts.py --out file "
                             f"({type(exc).__name__}: {exc})")
        return
    try:
        stack = STACKS[args.stack].replace(**_fields(args.set, "--set"))
        env_fields = _fields(args.env, "--env")
        AOASSConfig.from_kwargs(**env_fields)       # refused here, not in a worker
    except ValueError as exc:       # ConfigError included: the field and what is valid
        parser.error(str(exc))
    # the pool's workers are forked after this: they read the changed stack and fields
    STACKS[args.stack] = stack
    ENV_FIELDS.update(env_fields)
    tasks = [(args.policy, args.stack, DENSITIES[i % len(DENSITIES)], args.first_seed + i)
             for i in range(args.episodes)]
    problem = folder_problem(args.out.parent)     # refused now, not after the work
    if problem is not None:
        parser.error(f"--out {args.out}: {problem}")
    rows = []
    with Pool(args.jobs) as pool:
        for row in pool.imap(episode, tasks):
            rows.append(row)
            # the rows so far replace the file whole: a kill leaves the last episode's rows,
            # never a half line or an emptied earlier result
            write_text_atomic(args.out, "".join(json.dumps(r) + "\n" for r in rows))
            print(row["seed"], row["density"], row["moving_contacts"], row["static_contacts"],
                  row["complete"], f"{row['coverage']:.3f}", flush=True)
    print(json.dumps(summary(rows)))


if __name__ == "__main__":
    main()
