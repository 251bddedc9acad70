"""Reference numbers: standard algorithms on the registered ids, one budget, several seeds.

Trains SB3's PPO, SAC and TD3, sb3-contrib's RecurrentPPO and the project's RecurrentTD3 with
one budget of agent steps and ``--seeds`` seeds each, on a registered id (``AOASS-Quick-v0`` by
default; ``AOASS-Train-v0`` is the shipped policy's setup). Every ``--eval-every`` steps each
model is evaluated, deterministically, on the same ``--eval-episodes`` held-out episodes:
generated maps from a seed no training episode uses, or, for ``AOASS-Train-v0``, the validation
maps (never maps/test). The zero action (the plain spiral inside the same stack) is evaluated
on the same episodes as the reference. Hyperparameters are the libraries' defaults, but for
``learning_starts`` and PPO's rollout length, scaled to the budget (:func:`hyperparameters`).

Writes ``OUT/curves.csv`` (algo, seed, steps, mean return), ``OUT/final.csv`` (algo, seed,
final return, wall seconds), ``OUT/summary.md`` (final return: mean ± 95 % t interval over
seeds, and wall time) and ``OUT/curves.png``. Runs go through :mod:`aoass_env.backends`: one
after another here (``--workers 1``), in local processes, or as Ray tasks (``--backend ray``).

Run: ``python3 benchmarks/algorithms.py [--env AOASS-Quick-v0] [--timesteps 3000]
[--seeds 0-2] [--algos ppo,sac,td3,recurrent-ppo,recurrent-td3] [--out out/algorithms]``.
"""

from __future__ import annotations

import argparse
import csv
import io
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from sb3_contrib import RecurrentPPO
from stable_baselines3 import PPO, SAC, TD3
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv

import aoass_env  # noqa: F401  (registers the ids)
from agents.recurrent_td3 import RecurrentTD3
from agents.sections import key_value
from agents.seeds import parse_seeds
from aoass_env.atomic import save_figure_atomic, write_text_atomic
from aoass_env.backends import add_backend_arguments, make_backend
from aoass_env.evaluation.report import ci_stats
from aoass_env.registration import ENV_IDS, QUICK_ENV_ID, TRAIN_ENV_ID

#: Algorithm name -> (class, policy).
ALGORITHMS: dict[str, tuple[type, str]] = {
    "ppo": (PPO, "MlpPolicy"), "sac": (SAC, "MlpPolicy"), "td3": (TD3, "MlpPolicy"),
    "recurrent-ppo": (RecurrentPPO, "MlpLstmPolicy"),
    "recurrent-td3": (RecurrentTD3, "MlpLstmPolicy")}
#: The zero action's row: the plain spiral inside the same stack.
ZERO = "zero-action"
#: Seed of the held-out evaluation episodes (training episodes draw from the run's seed).
EVAL_SEED = 1_000_000
#: Keywords that make an id's evaluation episodes held out (default: the id's own).
EVAL_KWARGS: dict[str, dict[str, Any]] = {TRAIN_ENV_ID: {"split": "validation",
                                                          "cycle": True}}


def hyperparameters(algo: str, timesteps: int, eval_every: int) -> dict[str, Any]:
    """The libraries' defaults, with the warm-up (off-policy ``learning_starts``: a tenth of
    the budget, at most their default of 100) and PPO's rollout (``n_steps``: at most 256 agent
    steps and ``eval_every``, so that short budgets still update and every evaluation falls on
    a rollout's end) scaled to the budget."""
    if algo in ("ppo", "recurrent-ppo"):
        n_steps = max(min(256, eval_every, timesteps), 2)
        return {"n_steps": n_steps, "batch_size": min(64, n_steps)}
    return {"learning_starts": max(min(100, timesteps // 10), 1)}


@dataclass(frozen=True)
class Run:
    """One training run: ``algo`` (or :data:`ZERO`) with ``seed`` on ``env_id``."""

    algo: str
    seed: int
    env_id: str
    timesteps: int
    eval_every: int
    eval_episodes: int
    env_kwargs: dict[str, Any] = field(default_factory=dict)


def _eval_env(run: Run) -> DummyVecEnv:
    """The held-out evaluation episodes, the same ones at every evaluation."""
    kwargs = {**run.env_kwargs, **EVAL_KWARGS.get(run.env_id, {})}
    venv = DummyVecEnv([lambda: Monitor(gym.make(run.env_id, **kwargs))])
    venv.seed(EVAL_SEED)
    return venv


def _evaluate(model: Any, run: Run) -> float:
    """Mean Eq. 14 return of ``model`` on the evaluation episodes (deterministic actions)."""
    venv = _eval_env(run)
    try:
        mean, _ = evaluate_policy(model, venv, n_eval_episodes=run.eval_episodes,
                                  deterministic=True)
    finally:
        venv.close()
    return float(mean)


class _ZeroPolicy:
    """The zero action, as ``evaluate_policy`` calls a model."""

    def __init__(self, n: int) -> None:
        self.n = n

    def predict(self, observation: Any, state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, None]:
        return np.zeros((len(observation), self.n), np.float32), None


def train_one(run: Run) -> dict[str, Any]:
    """Train ``run`` and evaluate it every ``eval_every`` steps; the learning curve
    [(steps, mean return)], the final return and the wall seconds."""
    torch.set_num_threads(1)           # small networks: threads only contend for the cores
    start = time.perf_counter()
    if run.algo == ZERO:
        ret = _evaluate(_ZeroPolicy(2), run)
        return {"curve": [(0, ret)], "final": ret, "wall": time.perf_counter() - start}
    cls, policy = ALGORITHMS[run.algo]
    env = Monitor(gym.make(run.env_id, **run.env_kwargs))
    model = cls(policy, env, seed=run.seed, device="cpu", verbose=0,
                **hyperparameters(run.algo, run.timesteps, run.eval_every))
    curve = []
    while model.num_timesteps < run.timesteps:
        chunk = min(run.eval_every, run.timesteps - model.num_timesteps)
        model.learn(chunk, reset_num_timesteps=False)
        curve.append((int(model.num_timesteps), _evaluate(model, run)))
    env.close()
    return {"curve": curve, "final": curve[-1][1], "wall": time.perf_counter() - start}


def _csv(header: list[str], rows: list[list[Any]]) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    return buffer.getvalue()


def summary_markdown(results: dict[tuple[str, int], dict[str, Any]], runs: list[Run],
                     command: str) -> str:
    """The final-return table: per algorithm, the mean over seeds with its 95 % t interval,
    the seeds, and the mean wall time per run."""
    first = runs[0]
    lines = [f"Final return (Eq. 14, mean of {first.eval_episodes} held-out episodes, "
             f"deterministic) after {first.timesteps} agent steps on {first.env_id}"
             f"{' ' + str(first.env_kwargs) if first.env_kwargs else ''}; mean ± 95 % t "
             f"interval over seeds.", "", f"Command: `{command}`", "",
             "| algorithm | seeds | final return | per seed | wall s / run |",
             "|---|---|---|---|---|"]
    for algo in dict.fromkeys(r.algo for r in runs):
        done = [results[(r.algo, r.seed)] for r in runs
                if r.algo == algo and (r.algo, r.seed) in results]
        if not done:
            continue
        n, mean, _, half = ci_stats(d["final"] for d in done)
        interval = f"{mean:.1f}" if math.isnan(half) else f"{mean:.1f} ± {half:.1f}"
        per_seed = ", ".join(f"{d['final']:.1f}" for d in done)
        wall = float(np.mean([d["wall"] for d in done]))
        lines.append(f"| {algo} | {n} | {interval} | {per_seed} | {wall:.0f} |")
    return "\n".join(lines) + "\n"


def draw_curves(results: dict[tuple[str, int], dict[str, Any]], path: Path) -> None:
    """Learning curves: mean over seeds, the band between the lowest and highest seed."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for algo in dict.fromkeys(a for a, _ in results):
        curves = [results[k]["curve"] for k in results if k[0] == algo]
        if algo == ZERO:
            ax.axhline(float(np.mean([c[0][1] for c in curves])), color="black", ls="--",
                       label=ZERO)
            continue
        length = min(len(c) for c in curves)
        steps = [s for s, _ in curves[0][:length]]
        values = np.array([[v for _, v in c[:length]] for c in curves])
        ax.plot(steps, values.mean(axis=0), marker="o", ms=3, label=f"{algo} ({len(curves)})")
        ax.fill_between(steps, values.min(axis=0), values.max(axis=0), alpha=0.2)
    ax.set(xlabel="agent steps", ylabel="evaluation return (Eq. 14)")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    save_figure_atomic(fig, path, dpi=110)
    plt.close(fig)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--env", choices=ENV_IDS, default=QUICK_ENV_ID, help="(default: %(default)s)")
    p.add_argument("--algos", default=",".join(ALGORITHMS),
                   help="comma-separated, of " + ", ".join(ALGORITHMS) + " (default: all)")
    p.add_argument("--seeds", default="0-2", help="e.g. 0-2 or 0,3,5 (default: 0-2)")
    p.add_argument("--timesteps", type=int, default=3000, help="agent steps per run")
    p.add_argument("--eval-every", type=int, default=1000, help="agent steps between "
                   "evaluations (default: 1000)")
    p.add_argument("--eval-episodes", type=int, default=5, help="(default: 5)")
    p.add_argument("--env-kwargs", metavar="KEY:VALUE", nargs="+", default=[],
                   help="keywords of the id, values as YAML (e.g. n_nodes:50)")
    p.add_argument("--workers", type=int, default=1, help="local processes (default: 1)")
    add_backend_arguments(p, "training run", "the runs in --workers local processes")
    p.add_argument("--out", type=Path, default=Path("out/algorithms"))
    return p


def main(argv: list[str] | None = None) -> dict[tuple[str, int], dict[str, Any]]:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = _parser()
    args = parser.parse_args(argv)
    try:
        algos = [a.strip() for a in args.algos.split(",") if a.strip()]
        unknown = [a for a in algos if a not in ALGORITHMS]
        if unknown or not algos:
            raise ValueError(f"--algos {args.algos!r}: each must be one of "
                             f"{', '.join(ALGORITHMS)}")
        for flag, value in (("--timesteps", args.timesteps), ("--eval-every", args.eval_every),
                            ("--eval-episodes", args.eval_episodes),
                            ("--workers", args.workers)):
            if value < 1:
                raise ValueError(f"{flag} must be >= 1, got {value}")
        seeds = parse_seeds(args.seeds)
        env_kwargs = dict(key_value(item, "--env-kwargs") for item in args.env_kwargs)
        gym.make(args.env, **env_kwargs).close()           # bad keywords fail before any work
        backend = make_backend(args.backend, workers=args.workers, address=args.address)
    except (ValueError, TypeError) as exc:
        parser.exit(2, f"algorithms.py: error: {exc}\n")
    common = dict(env_id=args.env, timesteps=args.timesteps, eval_every=args.eval_every,
                  eval_episodes=args.eval_episodes, env_kwargs=env_kwargs)
    # seed-major: an interrupted benchmark has every algorithm at its first seeds
    runs = [Run(ZERO, 0, **common)] + [Run(a, s, **common) for s in seeds for a in algos]
    command = "python3 benchmarks/algorithms.py " + " ".join(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    results: dict[tuple[str, int], dict[str, Any]] = {}
    for run, result, error in backend.run(train_one, runs):
        if error is not None:
            print(f"{run.algo} seed {run.seed} failed:\n{error}", file=sys.stderr)
            continue
        results[(run.algo, run.seed)] = result
        print(f"{run.algo} seed {run.seed}: final return {result['final']:.1f} "
              f"({result['wall']:.0f} s)", flush=True)
        # written after every run: an interrupted benchmark keeps what it finished
        write_text_atomic(args.out / "curves.csv", _csv(
            ["algo", "seed", "steps", "mean_return"],
            [[a, s, step, f"{v:.4f}"] for (a, s), r in results.items() for step, v in r["curve"]]))
        write_text_atomic(args.out / "final.csv", _csv(
            ["algo", "seed", "final_return", "wall_seconds"],
            [[a, s, f"{r['final']:.4f}", f"{r['wall']:.1f}"] for (a, s), r in results.items()]))
        write_text_atomic(args.out / "summary.md", summary_markdown(results, runs, command))
    draw_curves(results, args.out / "curves.png")
    print(summary_markdown(results, runs, command))
    return results


if __name__ == "__main__":
    main()
