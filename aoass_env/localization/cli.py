"""Localize a folder of saved beacon logs and print RMSE, localized fraction and coverage.

``python -m aoass_env.localization LOGDIR [--method olstm-dvhop|consensus|dvhop]
[--checkpoint PATH]``

One line per ``.npz`` log, then an overall line: the RMSE pooled over every localized node of
every log (Eq. 15), the localized fraction and the Eq. 18 coverage over all nodes.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import torch

from aoass_env.beacon_log import BeaconLog, BeaconLogError
from aoass_env.localization import METHODS, localize, prepare
from aoass_env.localization.olstm import DEFAULT_CHECKPOINT, CheckpointError, load_checkpoint
from aoass_env.metrics import localization_rmse

__all__ = ["main"]


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the exit status (0 ok, 1 no logs, 2 a bad log or checkpoint); a
    LOGDIR that is no folder exits with argparse's status 2."""
    parser = argparse.ArgumentParser(prog="python -m aoass_env.localization",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("logdir", type=Path, help="folder of .npz beacon logs")
    parser.add_argument("--method", choices=METHODS, default="olstm-dvhop")
    parser.add_argument("--checkpoint", type=Path, default=DEFAULT_CHECKPOINT)
    args = parser.parse_args(argv)
    if not args.logdir.is_dir():
        why = "not a folder" if args.logdir.exists() else "no such folder"
        parser.error(f"LOGDIR {args.logdir}: {why}")
    torch.set_num_threads(1)
    paths = sorted(args.logdir.glob("*.npz"))
    if not paths:
        print(f"no .npz logs in {args.logdir}", file=sys.stderr)
        return 1
    try:
        model = load_checkpoint(args.checkpoint) if args.method == "olstm-dvhop" else None
    except CheckpointError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    width = max(len(p.name) for p in paths)
    print(f"{'log':<{width}}  {'nodes':>5}  {'RMSE [m]':>8}  {'localized':>9}  {'coverage':>8}")
    sq, n_loc, n_cov, n_all = 0.0, 0, 0, 0
    for path in paths:
        try:
            episode = prepare(BeaconLog.load(path))
        except BeaconLogError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        est = localize(episode, args.method, checkpoint=model) if model is not None \
            else localize(episode, args.method)
        rmse, frac = localization_rmse(episode.log.nodes, est)
        n = episode.log.n_nodes
        ok = np.all(np.isfinite(est), axis=1)
        sq += float(np.sum((est[ok] - episode.log.nodes[ok]) ** 2))
        n_loc, n_cov, n_all = n_loc + int(ok.sum()), n_cov + int(episode.covered.sum()), n_all + n
        print(f"{path.name:<{width}}  {n:>5}  {rmse:>8.3f}  {frac:>9.3f}  "
              f"{episode.covered.mean():>8.3f}")
    overall = np.sqrt(sq / n_loc) if n_loc else float("nan")
    print(f"{'overall':<{width}}  {n_all:>5}  {overall:>8.3f}  {n_loc / n_all:>9.3f}  "
          f"{n_cov / n_all:>8.3f}")
    return 0
