"""Training curve of a ``python train.py`` run: evaluation return on the validation maps and the
training episodes' Eq. 14 return, coverage and safety intervention (from the run's TensorBoard
logs).

Run: ``python3 scripts/plot_training.py [RUN_DIR] [--tensorboard out/tensorboard/td3-lstm_seed0_1]
[--out docs/figures/training_curve.png]``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from agents.callbacks import read_evaluations  # noqa: E402
from aoass_env.atomic import save_figure_atomic  # noqa: E402

SCALARS = (("rollout/ep_rew_mean", "training episodes: Eq. 14 return"),
           ("aoass/coverage", "training episodes: coverage (Eq. 18)"),
           ("aoass/intervention", "mean safety intervention |v* - v_des| (m/s)"))


def tensorboard_scalars(folder: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """tag -> (steps, values) of the TensorBoard event files in ``folder``."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator
    acc = EventAccumulator(str(folder))
    acc.Reload()
    out = {}
    for tag in acc.Tags()["scalars"]:
        events = acc.Scalars(tag)
        out[tag] = (np.array([e.step for e in events]), np.array([e.value for e in events]))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("run", type=Path, nargs="?", default=Path("checkpoints/aoass_td3_lstm"))
    parser.add_argument("--tensorboard", type=Path, default=None)
    parser.add_argument("--out", type=Path, default=Path("docs/figures/training_curve.png"))
    args = parser.parse_args()
    npz = args.run / "evaluations.npz"
    if not npz.is_file():
        parser.error(f"RUN {args.run}: holds no evaluations.npz (a python train.py run folder, "
                     f"e.g. checkpoints/aoass_td3_lstm)")
    if args.tensorboard is not None and not args.tensorboard.is_dir():
        parser.error(f"--tensorboard {args.tensorboard}: not a folder")
    try:                          # the training's own reader: no pickles, shapes checked
        ev = read_evaluations(npz)
    except ValueError as exc:
        parser.error(str(exc))
    if not len(ev.timesteps):
        parser.error(f"{npz}: holds no evaluation yet")
    scalars = tensorboard_scalars(args.tensorboard) if args.tensorboard else {}
    if args.tensorboard is not None and not any(tag in scalars for tag, _ in SCALARS):
        parser.error(f"--tensorboard {args.tensorboard}: holds none of the run's scalars "
                     f"({', '.join(tag for tag, _ in SCALARS)}) in its own event files; give "
                     f"the run's folder, e.g. out/tensorboard/td3-lstm_seed0_1")
    panels = 1 + sum(tag in scalars for tag, _ in SCALARS)
    fig, axes = plt.subplots(1, panels, figsize=(4.2 * panels, 3.4), squeeze=False)
    ax = axes[0, 0]
    returns = ev.results
    ax.plot(ev.timesteps, returns.mean(axis=1), marker="o", label="mean")
    ax.fill_between(ev.timesteps, returns.min(axis=1), returns.max(axis=1), alpha=0.25,
                    label="min-max")
    ax.set(xlabel="environment steps", ylabel="return", title="evaluation on the validation maps")
    ax.legend(fontsize=8)
    k = 1
    for tag, title in SCALARS:
        if tag in scalars:
            steps, values = scalars[tag]
            axes[0, k].plot(steps, values, marker="o")
            axes[0, k].set(xlabel="environment steps", title=title)
            axes[0, k].title.set_fontsize(9)
            k += 1
    fig.suptitle(f"{args.run.name}: TD3-LSTM inside the safety stack", fontsize=10)
    fig.tight_layout()
    try:
        save_figure_atomic(fig, args.out, dpi=110)
    except (OSError, ValueError) as exc:
        parser.error(f"--out {args.out}: {getattr(exc, 'strerror', None) or exc}")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
