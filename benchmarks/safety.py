"""Safety record, Kalman accuracy and speed of the AOASS safety stack (issue 4).

Four measurements, each printed as a table and saved to ``OUT/results.json``:

1. **contacts**: ``--episodes`` episodes (default 200) on generated 100 m maps of densities
   0.1-0.6, driven by uniformly random actions (a worst-case agent), inside the full stack
   (``make_safe_env``) and, on the same seeds, on bare AOASS-v0: anchor contacts with static
   obstacles (walls included) and with moving obstacles, per 100 episodes (targets inside the
   stack: zero static contacts, at most 1 moving contact per 100 episodes).
2. **zero action**: the zero action inside the stack on the shipped test maps of densities
   0.1-0.4 (100 m): completed spirals and node coverage (target: complete, coverage >= 97 %).
3. **kalman**: velocity error of the raw detections and of the Kalman tracks against the true
   velocities, for several observation-noise levels.
4. **speed**: steps per second of the wrapped and the bare environment in the same run
   (target: ratio >= 0.5).

Run: ``python3 benchmarks/safety.py [--episodes 200] [--jobs 2] [--parts contacts zero kalman
speed] [--out out/bench_safety]`` (about 20 min for everything on 2 cores).
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
from aoass_env.atomic import write_text_atomic
from aoass_env.maps import list_maps
from aoass_env.wrappers import KalmanObstacleTracker, make_safe_env

DENSITIES = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6)


def episode(task: tuple[str, bool, float | str, int, str]) -> dict:
    """One episode: (policy 'random' or 'zero', inside the stack?, density or map name, seed,
    label) -> its record."""
    policy, stacked, where, seed, label = task
    kwargs = {"map": where} if isinstance(where, str) else {"obstacle_density": where}
    env = make_safe_env(**kwargs) if stacked else gym.make("AOASS-v0", **kwargs)
    rng = np.random.default_rng(seed + 1_000_003)
    env.reset(seed=seed)
    interventions, active_static, steps = 0.0, 0, 0
    while True:
        action = (rng.uniform(-1.0, 1.0, 2) if policy == "random"
                  else np.zeros(2)).astype(np.float32)
        _, _, terminated, truncated, info = env.step(action)
        steps += 1
        if stacked:
            interventions += info["safety"]["intervention"]
            active_static += info["safety"]["active_static"] > 0
        if terminated or truncated:
            break
    ep = info["episode_metrics"]
    env.close()
    return {"label": label, "policy": policy, "stack": stacked, "where": where, "seed": seed,
            "static_contacts": info["static_contacts"] + info["wall_contacts"],
            "moving_contacts": info["moving_contacts"], "coverage": ep["coverage"],
            "complete": bool(ep["path_complete"]), "steps": steps,
            "eta_traj": ep["eta_traj"], "mean_intervention": interventions / steps,
            "static_active_steps": active_static}


def run_contacts(n: int, jobs: int) -> dict:
    tasks = []
    for i in range(n):
        density = DENSITIES[i % len(DENSITIES)]
        seed = 10_000 + i
        tasks += [("random", True, density, seed, "stack"), ("random", False, density, seed,
                                                             "bare")]
    rows = _map(tasks, jobs)
    out = {}
    print(f"\n1. random actions, {n} episodes (densities {DENSITIES[0]}-{DENSITIES[-1]}, "
          f"100 m fields)")
    print(f"{'':8s} {'static/100 ep':>14s} {'moving/100 ep':>14s} {'ep. with contact':>17s} "
          f"{'coverage':>9s} {'complete':>9s}")
    for label in ("stack", "bare"):
        sel = [r for r in rows if r["label"] == label]
        static = sum(r["static_contacts"] for r in sel)
        moving = sum(r["moving_contacts"] for r in sel)
        touched = sum(r["static_contacts"] + r["moving_contacts"] > 0 for r in sel)
        cov = float(np.mean([r["coverage"] for r in sel]))
        complete = float(np.mean([r["complete"] for r in sel]))
        out[label] = {"episodes": len(sel), "static_contacts": static, "moving_contacts": moving,
                      "static_per_100": 100 * static / len(sel),
                      "moving_per_100": 100 * moving / len(sel),
                      "episodes_with_contact": touched, "coverage": cov, "complete": complete}
        print(f"{label:8s} {100 * static / len(sel):14.2f} {100 * moving / len(sel):14.2f} "
              f"{touched:17d} {cov:9.3f} {complete:9.2f}")
    per_density = {}
    for d in DENSITIES:
        sel = [r for r in rows if r["where"] == d]
        per_density[str(d)] = {lab: {k: int(sum(r[k] for r in sel if r["label"] == lab))
                                     for k in ("static_contacts", "moving_contacts")}
                               for lab in ("stack", "bare")}
    out["per_density"] = per_density
    out["rows"] = rows
    return out


def run_zero(seeds: int, jobs: int) -> dict:
    maps = list_maps("test", field_size=100, densities=(0.0, 0.4))
    tasks = [("zero", True, m, s, "stack") for m in maps for s in range(seeds)]
    rows = _map(tasks, jobs)
    print(f"\n2. zero action inside the stack, {len(maps)} test maps x {seeds} seeds")
    print(f"{'density':8s} {'episodes':>8s} {'complete':>9s} {'coverage min':>13s} "
          f"{'coverage mean':>14s} {'contacts':>9s}")
    out = {}
    for d in sorted({m.split("/")[1].split("_")[0] for m in maps}):
        sel = [r for r in rows if f"/{d}_" in r["where"]]
        cov = [r["coverage"] for r in sel]
        out[d] = {"episodes": len(sel), "complete": sum(r["complete"] for r in sel),
                  "coverage_min": min(cov), "coverage_mean": float(np.mean(cov)),
                  "contacts": sum(r["static_contacts"] + r["moving_contacts"] for r in sel)}
        print(f"{d:8s} {len(sel):8d} {out[d]['complete']:9d} {min(cov):13.3f} "
              f"{np.mean(cov):14.3f} {out[d]['contacts']:9d}")
    out["rows"] = rows
    return out


def kalman_error(noise: float, seed: int, steps: int) -> tuple[float, float, int]:
    """RMS velocity error (m/s) of the raw detections and of the confirmed tracks matched to
    a true obstacle, with velocity noise ``noise`` (position noise 1.5x), over ``steps``."""
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
    return (float(np.sqrt(np.mean(np.square(raw_err)))),
            float(np.sqrt(np.mean(np.square(kf_err)))), len(kf_err))


def run_kalman(steps: int) -> dict:
    print("\n3. Kalman tracks: RMS velocity error (m/s), 8 moving obstacles, zero action")
    print(f"{'velocity noise':>15s} {'raw':>7s} {'tracked':>8s} {'ratio':>6s} {'samples':>8s}")
    out = {}
    for noise in (0.05, 0.1, 0.2, 0.4, 0.8):
        raw, kf, n = kalman_error(noise, seed=7, steps=steps)
        out[str(noise)] = {"raw": raw, "tracked": kf, "samples": n}
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
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--zero-seeds", type=int, default=3)
    parser.add_argument("--kalman-steps", type=int, default=600)
    parser.add_argument("--speed-steps", type=int, default=3000)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--parts", nargs="+", default=["contacts", "zero", "kalman", "speed"],
                        choices=["contacts", "zero", "kalman", "speed"])
    parser.add_argument("--out", type=Path, default=Path("out/bench_safety"))
    args = parser.parse_args()
    results = {}
    if "speed" in args.parts:
        results["speed"] = run_speed(args.speed_steps)
    if "kalman" in args.parts:
        results["kalman"] = run_kalman(args.kalman_steps)
    if "zero" in args.parts:
        results["zero"] = run_zero(args.zero_seeds, args.jobs)
    if "contacts" in args.parts:
        results["contacts"] = run_contacts(args.episodes, args.jobs)
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "results.json"
    write_text_atomic(path, json.dumps(results, indent=1, default=float))
    print(f"\nwrote {path}")


if __name__ == "__main__":
    main()
