"""Training throughput of RecurrentTD3 against SB3's TD3, measured in the same process.

Each algorithm runs with its own default hyperparameters (same ``train_freq=1`` and
``gradient_steps=1``: one gradient step per env step) on one env and one torch thread. The clock
starts at the first env step after ``learning_starts`` (so the gradient steps are included) and
stops at the end of ``learn``. Runs alternate TD3, RecurrentTD3, TD3, ... ``--repeats`` times
each and the median steps/s of each algorithm is reported with the ratio RecurrentTD3 / TD3
(target >= 0.5).

Run: ``python3 benchmarks/recurrent_td3_speed.py [--steps 2000] [--repeats 3] [--env ID]``.
Profile: ``pyinstrument benchmarks/recurrent_td3_speed.py --steps 1000 --repeats 1``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # one core: set before numpy / torch load their thread pools

import argparse  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402

import gymnasium as gym  # noqa: E402
import torch  # noqa: E402
from stable_baselines3 import TD3  # noqa: E402
from stable_baselines3.common.callbacks import BaseCallback  # noqa: E402
from stable_baselines3.common.env_util import make_vec_env  # noqa: E402

from agents import RecurrentTD3  # noqa: E402
from aoass_env.validators import argparse_number, one_line  # noqa: E402

torch.set_num_threads(1)
POLICIES = {"TD3": (TD3, "MlpPolicy"), "RecurrentTD3": (RecurrentTD3, "MlpLstmPolicy")}


class _Clock(BaseCallback):
    """Records the time and step count at the first step past ``learning_starts``."""

    def __init__(self, learning_starts: int):
        super().__init__()
        self.learning_starts = learning_starts
        self.start: tuple[float, int] | None = None

    def _on_step(self) -> bool:
        if self.start is None and self.num_timesteps > self.learning_starts:
            self.start = (time.perf_counter(), self.num_timesteps)
        return True


def steps_per_second(name: str, env_id: str, steps: int, seed: int) -> float:
    """Env steps per second of ``learn`` after ``learning_starts`` (default hyperparameters)."""
    cls, policy = POLICIES[name]
    model = cls(policy, make_vec_env(env_id, n_envs=1, seed=seed), seed=seed, device="cpu")
    clock = _Clock(model.learning_starts)
    model.learn(model.learning_starts + steps, callback=clock)
    assert clock.start is not None
    t0, n0 = clock.start
    return (model.num_timesteps - n0) / (time.perf_counter() - t0)


def env_problem(env_id: str) -> str | None:
    """Why both algorithms cannot train on ``env_id`` (unknown, or not Box actions and
    observations), or None."""
    try:
        env = gym.make(env_id)
    except gym.error.Error as err:          # NameNotFound, a malformed id, a missing package
        return one_line(err)
    spaces = env.action_space, env.observation_space
    env.close()
    if not isinstance(spaces[0], gym.spaces.Box):
        return f"its actions are {spaces[0]}; TD3 and RecurrentTD3 need Box (continuous) actions"
    if not isinstance(spaces[1], gym.spaces.Box):
        return f"its observations are {type(spaces[1]).__name__}; both policies here need a Box"
    return None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--env", default="Pendulum-v1", help="Gymnasium env id (Box actions)")
    # the clock starts at the first step past learning_starts: one step measured nothing
    # (a ZeroDivisionError)
    parser.add_argument("--steps", type=argparse_number(int, 2),
                        default=2000, help="steps per run after learning_starts (at least 2)")
    parser.add_argument("--repeats", type=argparse_number(int, 1),
                        default=3, help="runs per algorithm")
    args = parser.parse_args()
    problem = env_problem(args.env)       # a traceback from inside SB3 before
    if problem:
        parser.error(f"--env {args.env}: {problem}")
    rates: dict[str, list[float]] = {name: [] for name in POLICIES}
    for r in range(args.repeats):
        for name in POLICIES:
            rates[name].append(steps_per_second(name, args.env, args.steps, seed=r))
            print(f"run {r + 1}/{args.repeats} {name:13s} {rates[name][-1]:8.1f} steps/s",
                  flush=True)
    med = {name: statistics.median(v) for name, v in rates.items()}
    print(f"\n{args.env}: {args.steps} steps after learning_starts, median of {args.repeats}")
    print(f"{'algorithm':13s} {'steps/s':>8s} {'ms/step':>8s}")
    for name, rate in med.items():
        print(f"{name:13s} {rate:8.1f} {1e3 / rate:8.2f}")
    print(f"ratio RecurrentTD3 / TD3: {med['RecurrentTD3'] / med['TD3']:.2f} (target >= 0.5)")


if __name__ == "__main__":
    main()
