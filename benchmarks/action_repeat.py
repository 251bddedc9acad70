"""What deferring the unread observations saves in the training setups (action repeat 16).

:class:`~aoass_env.wrappers.ActionRepeat` returns only the last held step's observation, so the
steps before it build none (``defer=True``, the default). This script steps each registered
training setup twice in one process, deferring and building every observation
(``defer=False``), with the same seeds and random agent actions, so the two play the same
episodes (checked: equal rewards); the two are stepped in turn in chunks of agent steps, so they
meet the same machine drift. It prints CPU microseconds per control period of each and their
ratio; resets are not timed (the twins share the per-map caches, so the first to visit a map
would pay for both).

Run: ``python3 benchmarks/action_repeat.py [--steps N] [--chunk N]``.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym

import aoass_env  # noqa: F401  (registers the ids)
from aoass_env.registration import ADAPTIVE_TRAIN_ENV_ID, TRAIN_ENV_ID
from aoass_env.wrappers import ActionRepeat


def _repeat_layer(env: gym.Env) -> ActionRepeat:
    layer = env
    while not isinstance(layer, ActionRepeat):
        layer = layer.env
    return layer


def _twins(env_id: str, seed: int) -> dict[bool, tuple[gym.Env, ActionRepeat]]:
    """The registered setup, deferring and building every observation, reset with ``seed``."""
    out = {}
    for defer in (True, False):
        env = gym.make(env_id)
        layer = _repeat_layer(env)
        if not defer:
            layer._source = None        # ActionRepeat(..., defer=False) on the same stack
        env.reset(seed=seed)
        env.action_space.seed(seed)
        out[defer] = (env, layer)
    return out


def measure(env_id: str, steps: int, chunk: int, seed: int = 0) -> None:
    twins = _twins(env_id, seed)
    cpu = dict.fromkeys(twins, 0.0)
    periods = dict.fromkeys(twins, 0)
    rewards: dict[bool, list[float]] = {defer: [] for defer in twins}
    for env, _ in twins.values():          # warm-up: lazy imports, compiled kernels
        for _ in range(20):
            *_, terminated, truncated, _ = env.step(env.action_space.sample())
            if terminated or truncated:
                env.reset()
    done = 0
    while done < steps:
        for defer, (env, _) in twins.items():
            base = env.unwrapped
            for _ in range(chunk):
                before = base._steps
                start = time.process_time()
                _, reward, terminated, truncated, _ = env.step(env.action_space.sample())
                cpu[defer] += time.process_time() - start
                periods[defer] += base._steps - before
                rewards[defer].append(reward)
                if terminated or truncated:
                    env.reset()         # not timed: the twins share the per-map caches
        done += chunk
    if rewards[True] != rewards[False] or periods[True] != periods[False]:
        raise SystemExit(f"{env_id}: the deferring stack played other episodes")
    per = {defer: 1e6 * cpu[defer] / periods[defer] for defer in twins}
    print(f"{env_id:28s} {periods[True]:7d} periods  every observation {per[False]:6.1f} us"
          f"  deferred {per[True]:6.1f} us per period  ({per[False] / per[True]:.3f} x)")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=600, help="agent steps per setup and mode")
    parser.add_argument("--chunk", type=int, default=20, help="agent steps per turn")
    args = parser.parse_args(argv)
    for flag in ("steps", "chunk"):
        if getattr(args, flag) < 1:
            parser.error(f"--{flag} must be an integer >= 1, got {getattr(args, flag)}")
    print("CPU time per control period (16 per agent step), random agent actions, resets "
          "not timed:")
    for env_id in (TRAIN_ENV_ID, ADAPTIVE_TRAIN_ENV_ID):
        measure(env_id, args.steps, args.chunk)


if __name__ == "__main__":
    main()
