"""Pendulum-POMDP (no angular velocity): RecurrentTD3 against feed-forward TD3.

The protocol of LSTM-TD3 (Meng, Gorbet, Kulić 2021): Pendulum-v1 with the angular velocity
removed from the observation (``[cos th, sin th]`` only), so that a policy must infer the velocity
from its history. Both algorithms get the same env, action noise (Gaussian, sigma 0.1),
``learning_starts``, ``gamma``, buffer size and one gradient step per env step; each keeps its own
network defaults (TD3: MLP [400, 300], batch 256 transitions; RecurrentTD3: LSTM 64 + MLP [64, 64],
batch 64 windows). Every run trains ``--steps`` env steps, is evaluated every ``--eval-freq``
steps (5 episodes) and at the end on 10 deterministic episodes of a separately seeded env.

Prints per seed and median final mean returns (targets: RecurrentTD3 median >= -300 and at
least 300 above TD3) and, with ``--out DIR``, writes ``pendulum_memory.csv`` and
``pendulum_memory.json`` there atomically after every run.

Run: ``python3 benchmarks/pendulum_memory.py [--steps 50000] [--seeds 0 1 2]
[--algos RecurrentTD3 TD3] [--out out/pendulum_memory]``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # one core: set before numpy / torch load their thread pools

import argparse  # noqa: E402
import csv  # noqa: E402
import io  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402
from stable_baselines3 import TD3  # noqa: E402
from stable_baselines3.common.env_util import make_vec_env  # noqa: E402
from stable_baselines3.common.evaluation import evaluate_policy  # noqa: E402
from stable_baselines3.common.noise import NormalActionNoise  # noqa: E402

from agents import RecurrentTD3  # noqa: E402
from aoass_env.atomic import write_text_atomic  # noqa: E402
from aoass_env.validators import (  # noqa: E402
    argparse_number,
    keyword_names,
    one_line,
    parse_json,
    unknown_key_message,
)

torch.set_num_threads(1)
ALGOS = {"RecurrentTD3": (RecurrentTD3, "MlpLstmPolicy"), "TD3": (TD3, "MlpPolicy")}
COMMON = dict(learning_starts=5_000, gamma=0.98, buffer_size=200_000, learning_rate=1e-3,
              train_freq=1, gradient_steps=1)


class NoVelocity(gym.ObservationWrapper):
    """Pendulum-v1 observation ``[cos th, sin th, th_dot]`` without ``th_dot``."""

    def __init__(self, env: gym.Env):
        super().__init__(env)
        box = env.observation_space
        assert isinstance(box, gym.spaces.Box) and box.shape == (3,)
        self.observation_space = gym.spaces.Box(box.low[:2], box.high[:2], dtype=box.dtype)

    def observation(self, observation: np.ndarray) -> np.ndarray:
        return observation[:2]


def make_env(seed: int, n_envs: int = 1):
    """Vectorized Pendulum-POMDP envs (Monitor-wrapped by SB3)."""
    return make_vec_env("Pendulum-v1", n_envs=n_envs, seed=seed, wrapper_class=NoVelocity)


def run(algo: str, seed: int, steps: int, eval_freq: int, extra: dict[str, Any]) -> dict:
    """Train one algorithm on one seed; returns the final evaluation and the learning curve."""
    cls, policy = ALGOS[algo]
    noise = NormalActionNoise(np.zeros(1), 0.1 * np.ones(1))
    model = cls(policy, make_env(seed), action_noise=noise, seed=seed, device="cpu",
                **COMMON, **extra)
    eval_env = make_env(10_000 + seed)
    curve: list[tuple[int, float]] = []
    train_s, done = 0.0, 0
    while done < steps:
        chunk = min(eval_freq, steps - done) if eval_freq > 0 else steps - done
        start = time.perf_counter()
        model.learn(chunk, reset_num_timesteps=done == 0)
        train_s += time.perf_counter() - start
        done += chunk
        if done < steps:
            curve.append((done, float(evaluate_policy(model, eval_env, n_eval_episodes=5)[0])))
    mean, std = evaluate_policy(model, eval_env, n_eval_episodes=10, deterministic=True)
    curve.append((steps, float(mean)))
    return {"algo": algo, "seed": seed, "steps": steps, "mean_return": float(mean),
            "std_return": float(std), "train_seconds": round(train_s, 1),
            "steps_per_second": round(steps / train_s, 1), "curve": curve}


def json_object(text: str) -> dict[str, Any]:
    """An argparse ``type``: a JSON object (dict)."""
    try:
        value = parse_json(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(f"not JSON ({err}), got {text!r}") from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(f"must be a JSON object of keyword arguments, got "
                                         f"{text!r}")
    return value


def rtd3_problem(extra: dict[str, Any]) -> str | None:
    """Why RecurrentTD3 cannot be built with ``extra`` on top of the protocol's arguments (an
    unknown keyword, one the protocol sets, a value it refuses), or None: a TypeError or
    ValueError once the runs before it had trained."""
    fixed = {"policy", "env", "action_noise", "seed", "device", *COMMON}
    valid = [k for k in keyword_names(RecurrentTD3.__init__)
             if k not in fixed and not k.startswith("_")]
    for key in extra:
        if key in fixed:
            return f"{key!r} is set by the protocol, the same for both algorithms"
        if key not in valid:
            return unknown_key_message(key, valid, "RecurrentTD3 keyword")
    try:
        RecurrentTD3("MlpLstmPolicy", make_env(0), device="cpu", **COMMON, **extra)
    except (TypeError, ValueError) as err:
        return one_line(err)
    return None


def write_results(out: Path, results: list[dict], args: argparse.Namespace) -> None:
    """``pendulum_memory.csv`` (one row per run) and ``pendulum_memory.json`` (with curves)."""
    buf = io.StringIO()
    fields = ["algo", "seed", "steps", "mean_return", "std_return", "train_seconds",
              "steps_per_second"]
    writer = csv.DictWriter(buf, fieldnames=fields, extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    writer.writerows(results)
    write_text_atomic(out / "pendulum_memory.csv", buf.getvalue())
    meta = {"args": vars(args) | {"out": str(args.out)}, "common": COMMON,
            "action_noise_sigma": 0.1, "results": results}
    write_text_atomic(out / "pendulum_memory.json", json.dumps(meta, indent=1) + "\n")


def print_table(results: list[dict], seeds: list[int]) -> None:
    algos = list(dict.fromkeys(r["algo"] for r in results))
    finals = {a: {r["seed"]: r["mean_return"] for r in results if r["algo"] == a} for a in algos}
    print(f"\n{'algorithm':13s} " + " ".join(f"{f'seed {s}':>9s}" for s in seeds)
          + f" {'median':>9s} {'steps/s':>8s}")
    medians = {}
    for a in algos:
        medians[a] = statistics.median(finals[a].values())
        rate = statistics.median(r["steps_per_second"] for r in results if r["algo"] == a)
        cells = " ".join(f"{finals[a][s]:9.1f}" if s in finals[a] else f"{'-':>9s}"
                         for s in seeds)
        print(f"{a:13s} {cells} {medians[a]:9.1f} {rate:8.1f}")
    if "RecurrentTD3" in medians:
        rec = medians["RecurrentTD3"]
        verdict = "met" if rec >= -300 else "MISSED"
        print(f"RecurrentTD3 median {rec:.1f} (target >= -300: {verdict})")
        if "TD3" in medians:
            gap = rec - medians["TD3"]
            print(f"median gap RecurrentTD3 - TD3: {gap:.1f} "
                  f"(target >= 300: {'met' if gap >= 300 else 'MISSED'})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=argparse_number(int, 1),
                        default=50_000, help="env steps per run")
    parser.add_argument("--seeds", type=argparse_number(int, 0), nargs="+", default=[0, 1, 2])
    parser.add_argument("--algos", nargs="+", choices=list(ALGOS), default=list(ALGOS))
    parser.add_argument("--eval-freq", type=argparse_number(int, 0), default=10_000,
                        help="steps between learning-curve evaluations (0: final only)")
    parser.add_argument("--rtd3-kwargs", type=json_object, default={},
                        help="JSON dict of extra RecurrentTD3 keyword arguments (tuning)")
    parser.add_argument("--out", type=Path, default=None, help="folder for the CSV and JSON")
    args = parser.parse_args()
    problem = rtd3_problem(args.rtd3_kwargs) if args.rtd3_kwargs else None
    if problem:
        parser.error(f"--rtd3-kwargs: {problem}")
    results: list[dict] = []
    for seed in args.seeds:
        for algo in args.algos:
            extra = args.rtd3_kwargs if algo == "RecurrentTD3" else {}
            result = run(algo, seed, args.steps, args.eval_freq, extra)
            results.append(result)
            curve = " ".join(f"{s // 1000}k:{r:.0f}" for s, r in result["curve"])
            print(f"{algo:13s} seed {seed}: {result['mean_return']:8.1f} +- "
                  f"{result['std_return']:6.1f}  ({result['train_seconds']:.0f} s)  {curve}",
                  flush=True)
            if args.out is not None:
                write_results(args.out, results, args)
    print_table(results, args.seeds)


if __name__ == "__main__":
    main()
