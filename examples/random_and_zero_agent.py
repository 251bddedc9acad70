"""Run a random agent and the zero-action agent (which follows the spiral) on AOASS-v0.

Each agent plays one episode on a small field; the script prints the episode return, coverage,
collisions and path length, and saves an animated GIF per agent (every k-th frame)::

    python examples/random_and_zero_agent.py --field-size 30 --seed 0 --out out/examples
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

import gymnasium as gym
import numpy as np
from PIL import Image

import aoass_env  # noqa: F401  (registers AOASS-v0)
from aoass_env.atomic import atomic_open
from aoass_env.config import AOASSConfig
from aoass_env.validators import argparse_number

Policy = Callable[[gym.Env, np.ndarray], np.ndarray]

POLICIES: dict[str, Policy] = {
    "random": lambda env, obs: env.action_space.sample(),
    "zero": lambda env, obs: np.zeros(env.action_space.shape, dtype=np.float32),
}


def run_episode(env: gym.Env, policy: Policy, seed: int,
                frame_every: int) -> tuple[dict[str, float], list[np.ndarray]]:
    """One episode with ``policy``; its summary and every ``frame_every``-th rendered frame."""
    obs, info = env.reset(seed=seed)
    env.action_space.seed(seed)
    frames, total, steps, done = [env.render()], 0.0, 0, False
    while not done:
        obs, reward, terminated, truncated, info = env.step(policy(env, obs))
        total += reward
        steps += 1
        done = terminated or truncated
        if done or steps % frame_every == 0:
            frames.append(env.render())
    summary = {"return": total, "steps": steps, "coverage": info["coverage"],
               "collisions": info["collisions"], "path_length_m": info["path_length"],
               "time_s": info["time"]}
    return summary, frames


def save_gif(frames: list[np.ndarray], path: Path, fps: float, width: int) -> None:
    """Write ``frames`` as a looping GIF of ``width`` px at ``fps`` frames per second,
    atomically."""
    images = [Image.fromarray(f) for f in frames]
    if images[0].width != width:
        height = round(images[0].height * width / images[0].width)
        images = [im.resize((width, height), Image.Resampling.BILINEAR) for im in images]
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_open(path, "wb") as f:
        images[0].save(f, format="GIF", save_all=True, append_images=images[1:],
                       duration=round(1000 / fps), loop=0)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--field-size", type=float, default=30.0, help="field side (m)")
    parser.add_argument("--seed", type=argparse_number(int, 0), default=0)
    parser.add_argument("--out", type=Path, default=Path("out/examples"),
                        help="folder for the GIFs")
    parser.add_argument("--max-steps", type=argparse_number(int, 0), default=0,
                        help="step limit per episode (0: the environment's own limit)")
    parser.add_argument("--frame-every", type=argparse_number(int, 1), default=4,
                        help="keep every k-th frame in the GIF")
    parser.add_argument("--gif-width", type=argparse_number(int, 1), default=400,
                        help="GIF width (px)")
    args = parser.parse_args(argv)
    settings = dict(field_size=args.field_size, n_nodes=40, obstacle_density=0.1,
                    n_moving_obstacles=2)
    try:
        AOASSConfig(**settings)            # a bad --field-size: its one-line error, here
    except ValueError as exc:
        parser.error(f"--field-size: {exc}")
    if args.out.exists() and not args.out.is_dir():
        parser.error(f"--out {args.out}: is a file, not a folder")
    try:
        args.out.mkdir(parents=True, exist_ok=True)     # before the episodes, not after
    except OSError as exc:
        parser.error(f"--out {args.out}: {exc.strerror or exc}")

    limit = {"max_episode_steps": args.max_steps} if args.max_steps > 0 else {}
    for name, policy in POLICIES.items():
        env = gym.make("AOASS-v0", render_mode="rgb_array", **settings, **limit)
        summary, frames = run_episode(env, policy, args.seed, args.frame_every)
        fps = env.metadata["render_fps"]
        env.close()
        gif = args.out / f"{name}_agent.gif"
        try:
            save_gif(frames, gif, fps, args.gif_width)
        except OSError as exc:
            parser.error(f"--out {args.out}: {exc.strerror or exc}")
        print(f"{name:>6}: return {summary['return']:8.2f}  coverage "
              f"{100 * summary['coverage']:5.1f} %  collisions {summary['collisions']}  "
              f"path {summary['path_length_m']:6.1f} m  steps {summary['steps']}  "
              f"-> {gif} ({len(frames)} frames)")


if __name__ == "__main__":
    main()
