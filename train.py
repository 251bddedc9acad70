"""Training entry point: ``python train.py <what> [options]``.

Subcommands:
    localizer   simulate beacon logs on maps/train and train the OLSTM-DV-Hop localizer
                (aoass_env/localization/training.py), writing checkpoints/olstm_dvhop.pt
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import torch

from aoass_env.localization.training import TrainConfig, train_localizer


def _add_localizer(sub: argparse._SubParsersAction) -> None:
    defaults = TrainConfig()
    p = sub.add_parser("localizer", help="train the OLSTM-DV-Hop localizer",
                       description="Simulate logs on maps/train (cached in --data-dir), train "
                                   "the OLSTM with early stopping on held-out training maps, "
                                   "write the checkpoint.")
    for field in dataclasses.fields(TrainConfig):
        default = getattr(defaults, field.name)
        kind = Path if isinstance(default, Path) else type(default)
        p.add_argument(f"--{field.name.replace('_', '-')}", type=kind, default=default,
                       help=f"(default: {default})")
    p.add_argument("--threads", type=int, default=1, help="torch threads (default: 1)")
    p.set_defaults(run=_run_localizer)


def _run_localizer(args: argparse.Namespace) -> None:
    torch.set_num_threads(args.threads)
    cfg = TrainConfig(**{f.name: getattr(args, f.name) for f in dataclasses.fields(TrainConfig)})
    train_localizer(cfg, report=lambda line: print(line, flush=True))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True, metavar="{localizer}")
    _add_localizer(sub)
    args = parser.parse_args(argv)
    args.run(args)


if __name__ == "__main__":
    main()
