"""Safety record, Kalman accuracy and speed of the AOASS safety stack (issues 4 and 24).

Five measurements, each printed as a table and saved to ``OUT/results.json``. The stacks
compared (``--stacks``, ``--cost-stacks``) run the same seeds: ``stack`` (the defaults: ORCA
plus the look-ahead of issue 24, which yields to the sweep; the clearance first, one cost while
yielding, as ``yield-one-cost``), ``eager`` (the look-ahead's first
version: it escapes whenever ORCA's velocity falls short anywhere in its horizon, without a
price on headway or an escape budget), ``orca`` (the filter before the look-ahead,
``SafetyConfig.orca_only()``), ``bare`` (AOASS-v0 without a stack), and two ablations of the
defaults that tell which of the yielding look-ahead's changes costs contacts: ``early``
(escapes start whenever ORCA's velocity falls short in the horizon) and ``no-headway`` (no
price on the sweep's headway); ``one-cost`` (issue 24's first defaults: the escape's prices
on free space and headway compete with the clearance shortfall on one cost and can buy a
candidate with more shortfall), ``clearance-first`` (they choose only among the candidates
within 1 m x steps of the least shortfall, ``shortfall_tolerance=1``, also while yielding to
the sweep), ``yield-one-cost`` (clearance first until the escape budget yields, then one
cost) and ``yield-tolerance`` (clearance first, within 3 m x steps while yielding).

1. **contacts**: ``--episodes`` episodes (default 200) on generated 100 m maps of densities
   0.1-0.6 in turn, driven by uniformly random actions (a worst-case agent): anchor contacts
   with static obstacles (walls included) and with moving obstacles per 100 episodes, overall
   and by density, and the minimum separation (m, surface to surface) from a moving obstacle
   (issue 24 targets inside the stack: zero static contacts, at most 10 moving contacts per
   100 episodes).
2. **zero**: the zero action inside the stacks on the shipped test maps of densities 0.1-0.4
   (100 m): completed spirals, node coverage, contacts, path and time (reported, never tuned on).
2b. **cost**: the zero action in ``stack`` and ``orca`` on ``--cost-episodes`` generated maps
   of densities 0.1-0.6: the same, and the path and time ratios on the episodes both complete.
3. **kalman**: velocity error of the raw detections and of the Kalman tracks against the true
   velocities, for several observation-noise levels.
4. **speed**: steps per second of the wrapped and the bare environment in the same run
   (target: ratio >= 0.5).

Run: ``python3 benchmarks/safety.py [--episodes 200] [--jobs 2] [--parts contacts zero cost
kalman speed] [--stacks stack orca bare] [--cost-stacks stack orca] [--first-seed 10000]
[--cost-first-seed 40000] [--out out/bench_safety]``.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from multiprocessing import Pool
from pathlib import Path

import gymnasium as gym
import numpy as np

import aoass_env  # noqa: F401  (registers AOASS-v0)
from aoass_env.atomic import folder_problem, write_text_atomic
from aoass_env.maps import list_maps
from aoass_env.safety.config import SafetyConfig
from aoass_env.validators import argparse_number
from aoass_env.wrappers import KalmanObstacleTracker, make_safe_env

DENSITIES = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6)
#: The stacks compared, on the same seeds: the defaults (look-ahead, issue 24), the filter
#: before it (ORCA alone against the moving obstacles, ``SafetyConfig.orca_only()``) and bare
#: AOASS-v0.
STACKS = {"stack": SafetyConfig(), "orca": SafetyConfig.orca_only(), "bare": None,
          # the look-ahead's first version: an escape whenever ORCA's velocity falls short
          # anywhere in the horizon, no price on the sweep's headway, no escape budget
          "eager": SafetyConfig(look_ahead_react=60.0, progress_weight=0.0,
                                escape_budget=1e4, shortfall_tolerance=None,
                                yield_shortfall_tolerance=None),
          # the yielding look-ahead less one of its changes each, to tell which costs contacts:
          # escapes start whenever ORCA falls short in the horizon; no price on the headway
          # (ablations of issue 24's first defaults, the one-cost contest)
          "early": SafetyConfig(look_ahead_react=60.0, shortfall_tolerance=None,
                                yield_shortfall_tolerance=None),
          "no-headway": SafetyConfig(progress_weight=0.0, shortfall_tolerance=None,
                                     yield_shortfall_tolerance=None),
          # the escape's prices on free space, headway, preference and turning compete with
          # the clearance shortfall on one cost (issue 24's first defaults), or choose only
          # among the candidates within 1 m x steps of the least shortfall (issue 24's second
          # round), also while yielding to the sweep
          "one-cost": SafetyConfig(shortfall_tolerance=None, yield_shortfall_tolerance=None),
          "clearance-first": SafetyConfig(shortfall_tolerance=1.0, yield_shortfall_tolerance=1.0),
          # clearance first until the escape budget is spent; while yielding, the prices
          # (headway priced yield_progress_weight) compete with the shortfall on one cost, or
          # choose among the candidates within 3 m x steps of the least (issue 24's third round)
          "yield-one-cost": SafetyConfig(shortfall_tolerance=1.0, yield_shortfall_tolerance=None),
          "yield-tolerance": SafetyConfig(shortfall_tolerance=1.0, yield_shortfall_tolerance=3.0)}


def episode(task: tuple[str, str, float | str, int]) -> dict:
    """One episode: (policy 'random' or 'zero', stack label of STACKS, density or map name,
    seed) -> its record."""
    policy, label, where, seed = task
    kwargs = {"map": where} if isinstance(where, str) else {"obstacle_density": where}
    safety = STACKS[label]
    stacked = safety is not None
    env = make_safe_env(safety=safety, **kwargs) if stacked else gym.make("AOASS-v0", **kwargs)
    rng = np.random.default_rng(seed + 1_000_003)
    env.reset(seed=seed)
    world = env.unwrapped.sim.world
    reach = world.config.anchor_radius + world.config.moving_obstacle_radius
    interventions, active_static, escaping, steps = 0.0, 0, 0, 0
    separation = math.inf
    while True:
        action = (rng.uniform(-1.0, 1.0, 2) if policy == "random"
                  else np.zeros(2)).astype(np.float32)
        _, _, terminated, truncated, info = env.step(action)
        steps += 1
        moving = world.moving_positions
        if len(moving):
            gap = np.hypot(*(moving - world.position).T) - reach
            separation = min(separation, float(gap.min()))
        if stacked:
            interventions += info["safety"]["intervention"]
            active_static += info["safety"]["active_static"] > 0
            escaping += info["safety"].get("escaping", False)
        if terminated or truncated:
            break
    ep = info["episode_metrics"]
    env.close()
    return {"label": label, "policy": policy, "stack": stacked, "where": where, "seed": seed,
            "static_contacts": info["static_contacts"] + info["wall_contacts"],
            "moving_contacts": info["moving_contacts"], "coverage": ep["coverage"],
            "complete": bool(ep["path_complete"]), "steps": steps,
            "path_length": info["path_length"], "time": info["time"],
            "min_separation": separation,
            "eta_traj": ep["eta_traj"], "mean_intervention": interventions / steps,
            "static_active_steps": active_static, "escaping_steps": escaping}


def _summary(rows: list[dict], labels: tuple[str, ...]) -> dict:
    out = {}
    for label in labels:
        sel = [r for r in rows if r["label"] == label]
        if not sel:
            continue
        static = sum(r["static_contacts"] for r in sel)
        moving = sum(r["moving_contacts"] for r in sel)
        out[label] = {"episodes": len(sel), "static_contacts": static, "moving_contacts": moving,
                      "static_per_100": 100 * static / len(sel),
                      "moving_per_100": 100 * moving / len(sel),
                      "episodes_with_contact": sum(r["static_contacts"] + r["moving_contacts"]
                                                   > 0 for r in sel),
                      "coverage": float(np.mean([r["coverage"] for r in sel])),
                      "complete": float(np.mean([r["complete"] for r in sel])),
                      "min_separation": min(r["min_separation"] for r in sel),
                      "median_min_separation": float(np.median([r["min_separation"]
                                                                for r in sel])),
                      "path_length": float(np.mean([r["path_length"] for r in sel])),
                      "time": float(np.mean([r["time"] for r in sel]))}
    return out


def _print_summary(out: dict) -> None:
    print(f"{'':6s} {'static/100':>10s} {'moving/100':>10s} {'ep. touched':>11s} "
          f"{'coverage':>8s} {'complete':>8s} {'min sep':>8s} {'median':>7s} {'path m':>8s} "
          f"{'time s':>7s}")
    for label, o in out.items():
        print(f"{label:6s} {o['static_per_100']:10.2f} {o['moving_per_100']:10.2f} "
              f"{o['episodes_with_contact']:11d} {o['coverage']:8.3f} {o['complete']:8.2f} "
              f"{o['min_separation']:8.2f} {o['median_min_separation']:7.2f} "
              f"{o['path_length']:8.0f} {o['time']:7.0f}")


def _per_density(rows: list[dict], labels: tuple[str, ...]) -> dict:
    per = {}
    for d in DENSITIES:
        per[str(d)] = {lab: {
            "episodes": sum(r["where"] == d for r in rows if r["label"] == lab),
            "moving_contacts": int(sum(r["moving_contacts"] for r in rows
                                       if r["label"] == lab and r["where"] == d)),
            "static_contacts": int(sum(r["static_contacts"] for r in rows
                                       if r["label"] == lab and r["where"] == d)),
            "min_separation": min((r["min_separation"] for r in rows
                                   if r["label"] == lab and r["where"] == d), default=math.nan)}
            for lab in labels}
    print("moving contacts per 100 episodes by density (min separation, m):")
    for d, by in per.items():
        print(f"  {d}: " + "  ".join(
            f"{lab} {100 * v['moving_contacts'] / max(v['episodes'], 1):6.1f} "
            f"({v['min_separation']:.2f})" for lab, v in by.items()))
    return per


def _generated(policy: str, title: str, n: int, jobs: int, labels: tuple[str, ...],
               first_seed: int) -> tuple[dict, list[dict]]:
    """``n`` episodes of ``policy`` on generated 100 m maps (densities in turn), the same seed
    for every stack of ``labels``: the printed summary (with ``per_density``) and the rows."""
    rows = _map([(policy, label, DENSITIES[i % len(DENSITIES)], first_seed + i)
                 for i in range(n) for label in labels], jobs)
    print(f"\n{title}, {n} episodes (densities {DENSITIES[0]}-{DENSITIES[-1]}, 100 m fields, "
          f"seeds {first_seed}-{first_seed + n - 1}, the same for every stack)")
    out = _summary(rows, labels)
    _print_summary(out)
    out["per_density"] = _per_density(rows, labels)
    return out, rows


def run_contacts(n: int, jobs: int, labels: tuple[str, ...] = ("stack", "orca", "bare"),
                 first_seed: int = 10_000) -> dict:
    out, rows = _generated("random", "1. random actions", n, jobs, labels, first_seed)
    out["rows"] = rows
    return out


def run_cost(n: int, jobs: int, labels: tuple[str, ...] = ("stack", "orca"),
             first_seed: int = 40_000) -> dict:
    """The zero action in each stack on ``n`` generated maps (densities in turn), the same
    seeds: completion, coverage, path and time (the look-ahead's cost against ORCA alone)."""
    out, rows = _generated("zero", "2b. zero action", n, jobs, labels, first_seed)
    pairs = {}
    for r in rows:
        pairs.setdefault((r["where"], r["seed"]), {})[r["label"]] = r
    both = [p for p in pairs.values() if all(p[lab]["complete"] for lab in labels)]
    if len(labels) >= 2 and both:
        a, b = labels[:2]
        path = float(np.mean([p[a]["path_length"] / p[b]["path_length"] for p in both]))
        time_ = float(np.mean([p[a]["time"] / p[b]["time"] for p in both]))
        out["ratio"] = {"episodes_both_complete": len(both), "path": path, "time": time_}
        print(f"{a} / {b} on the {len(both)} episodes both completed: path x{path:.3f}, "
              f"time x{time_:.3f}")
    out["rows"] = rows
    return out


def run_zero(seeds: int, jobs: int, labels: tuple[str, ...] = ("stack", "orca")) -> dict:
    maps = list_maps("test", field_size=100, densities=(0.0, 0.4))
    tasks = [("zero", label, m, s) for m in maps for s in range(seeds) for label in labels]
    rows = _map(tasks, jobs)
    print(f"\n2. zero action inside the stacks, {len(maps)} test maps x {seeds} seeds")
    print(f"{'stack':6s} {'density':8s} {'episodes':>8s} {'complete':>9s} {'coverage min':>13s} "
          f"{'coverage mean':>14s} {'moving':>7s} {'static':>7s} {'path m':>7s} {'time s':>7s}")
    out: dict = {}
    for label in labels:
        out[label] = {}
        for d in sorted({m.split("/")[1].split("_")[0] for m in maps}):
            sel = [r for r in rows if f"/{d}_" in r["where"] and r["label"] == label]
            cov = [r["coverage"] for r in sel]
            o = out[label][d] = {
                "episodes": len(sel), "complete": sum(r["complete"] for r in sel),
                "coverage_min": min(cov), "coverage_mean": float(np.mean(cov)),
                "moving_contacts": sum(r["moving_contacts"] for r in sel),
                "static_contacts": sum(r["static_contacts"] for r in sel),
                "path_length": float(np.mean([r["path_length"] for r in sel])),
                "time": float(np.mean([r["time"] for r in sel]))}
            print(f"{label:6s} {d:8s} {len(sel):8d} {o['complete']:9d} {min(cov):13.3f} "
                  f"{np.mean(cov):14.3f} {o['moving_contacts']:7d} {o['static_contacts']:7d} "
                  f"{o['path_length']:7.0f} {o['time']:7.0f}")
    out["rows"] = rows
    return out


def rms(errors: list[float]) -> float | None:
    """Root mean square of ``errors``; None when there are none (no sample to average)."""
    return float(np.sqrt(np.mean(np.square(errors)))) if errors else None


def kalman_error(noise: float, seed: int, steps: int) -> tuple[float | None, float | None, int]:
    """RMS velocity error (m/s) of the raw detections and of the confirmed tracks matched to
    a true obstacle (None where there was none), with velocity noise ``noise`` (position
    noise 1.5x), over ``steps``; and the number of track samples."""
    base = gym.make("AOASS-v0", obstacle_density=0.2, n_moving_obstacles=8,
                    obs_moving_obstacles=8, obs_velocity_noise=noise,
                    obs_position_noise=1.5 * noise)
    env = KalmanObstacleTracker(base)
    raw_env = env.unwrapped
    env.reset(seed=seed)
    raw_err, kf_err = [], []
    for _ in range(steps):
        _, _, term, trunc, _ = env.step(np.zeros(2, np.float32))
        world = raw_env.sim.world
        true_p, true_v = world.moving_positions, world.moving_velocities
        for x, y, vx, vy in env.last_detections:    # what the tracker was given this step
            j = int(np.argmin(np.hypot(true_p[:, 0] - x, true_p[:, 1] - y)))
            raw_err.append(math.hypot(vx - true_v[j, 0], vy - true_v[j, 1]))
        for x, y, vx, vy, _ in env.tracked_obstacles:
            d = np.hypot(true_p[:, 0] - x, true_p[:, 1] - y)
            j = int(np.argmin(d))
            if d[j] < 1.0:
                kf_err.append(math.hypot(vx - true_v[j, 0], vy - true_v[j, 1]))
        if term or trunc:
            break
    return rms(raw_err), rms(kf_err), len(kf_err)


def run_kalman(steps: int) -> dict:
    print("\n3. Kalman tracks: RMS velocity error (m/s), 8 moving obstacles, zero action")
    print(f"{'velocity noise':>15s} {'raw':>7s} {'tracked':>8s} {'ratio':>6s} {'samples':>8s}")
    out = {}
    for noise in (0.05, 0.1, 0.2, 0.4, 0.8):
        raw, kf, n = kalman_error(noise, seed=7, steps=steps)
        out[str(noise)] = {"raw": raw, "tracked": kf, "samples": n}
        if raw is None or kf is None:       # no detection or no confirmed track yet
            print(f"{noise:15.2f} {'-':>7s} {'-':>8s} {'-':>6s} {n:8d}  (no "
                  f"{'detection' if raw is None else 'confirmed track'} in {steps} steps: "
                  f"raise --kalman-steps)")
            continue
        print(f"{noise:15.2f} {raw:7.3f} {kf:8.3f} {kf / raw:6.2f} {n:8d}")
    return out


def rate(env: gym.Env, steps: int, seed: int) -> float:
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    start = time.perf_counter()
    for _ in range(steps):
        _, _, term, trunc, _ = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        if term or trunc:
            env.reset()
    return steps / (time.perf_counter() - start)


def run_speed(steps: int) -> dict:
    print(f"\n4. speed: random actions, density 0.3, {steps} steps, same run")
    bare, stack = [], []
    for rep in range(2):       # interleaved, so drift in the machine's speed hits both
        bare.append(rate(gym.make("AOASS-v0", obstacle_density=0.3), steps, rep))
        stack.append(rate(make_safe_env(obstacle_density=0.3), steps, rep))
    b, s = max(bare), max(stack)
    print(f"{'bare AOASS-v0':16s} {b:8.0f} steps/s {1e6 / b:7.0f} us/step")
    print(f"{'full stack':16s} {s:8.0f} steps/s {1e6 / s:7.0f} us/step   ratio {s / b:.2f} "
          f"(target >= 0.5)")
    return {"bare_steps_per_s": b, "stack_steps_per_s": s, "ratio": s / b,
            "runs": {"bare": bare, "stack": stack}}


def _map(tasks: list, jobs: int) -> list[dict]:
    if jobs <= 1:
        return [episode(t) for t in tasks]
    with Pool(jobs) as pool:
        return pool.map(episode, tasks, chunksize=1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    count = argparse_number(int, 1)
    parser.add_argument("--episodes", type=count, default=200)
    parser.add_argument("--zero-seeds", type=count, default=3)
    parser.add_argument("--kalman-steps", type=count, default=600)
    parser.add_argument("--speed-steps", type=count, default=3000)
    parser.add_argument("--jobs", type=count, default=2)
    parser.add_argument("--cost-episodes", type=count, default=60)
    parser.add_argument("--cost-first-seed", type=argparse_number(int, 0), default=40_000,
                        help="seed of the cost part's first episode")
    parser.add_argument("--first-seed", type=argparse_number(int, 0), default=10_000,
                        help="seed of the contacts part's first episode")
    parser.add_argument("--stacks", nargs="+", default=["stack", "orca", "bare"],
                        choices=list(STACKS), help="what the contacts part compares")
    parser.add_argument("--cost-stacks", nargs="+", default=["stack", "orca"],
                        choices=[label for label in STACKS if label != "bare"],
                        help="what the cost part compares (ratios: the first two)")
    parser.add_argument("--parts", nargs="+",
                        default=["contacts", "zero", "cost", "kalman", "speed"],
                        choices=["contacts", "zero", "cost", "kalman", "speed"])
    parser.add_argument("--out", type=Path, default=Path("out/bench_safety"))
    args = parser.parse_args()
    problem = folder_problem(args.out)    # refused now, not after the work
    if problem is not None:
        parser.error(f"--out {args.out}: {problem}")
    results = {}
    if "speed" in args.parts:
        results["speed"] = run_speed(args.speed_steps)
    if "kalman" in args.parts:
        results["kalman"] = run_kalman(args.kalman_steps)
    if "zero" in args.parts:
        results["zero"] = run_zero(args.zero_seeds, args.jobs)
    if "cost" in args.parts:
        results["cost"] = run_cost(args.cost_episodes, args.jobs, tuple(args.cost_stacks),
                                   first_seed=args.cost_first_seed)
    if "contacts" in args.parts:
        results["contacts"] = run_contacts(args.episodes, args.jobs, tuple(args.stacks),
                                           args.first_seed)
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "results.json"
    write_text_atomic(path, json.dumps(results, indent=1, default=float))
    print(f"\nwrote {path}")


if __name__ == "__main__":
    main()
