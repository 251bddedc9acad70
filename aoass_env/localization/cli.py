"""Localize a folder of saved beacon logs and print RMSE, localized fraction and coverage.

``python -m aoass_env.localization LOGDIR [--method olstm-dvhop|consensus|dvhop]
[--checkpoint PATH]`` (``--checkpoint``: olstm-dvhop only)

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
    """Run the CLI; returns the exit status (0 ok, 1 no logs); bad input (a LOGDIR that is no
    folder, a bad log or checkpoint, a --checkpoint the method does not read) exits with
    argparse's status 2 and a one-line error."""
    parser = argparse.ArgumentParser(prog="python -m aoass_env.localization",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("logdir", type=Path, help="folder of .npz beacon logs")
    parser.add_argument("--method", choices=METHODS, default="olstm-dvhop")
    parser.add_argument("--checkpoint", type=Path, default=None,
                        help=f"OLSTM checkpoint of --method olstm-dvhop (default: "
                             f"{DEFAULT_CHECKPOINT})")
    args = parser.parse_args(argv)
    if not args.logdir.is_dir():
        why = "not a folder" if args.logdir.exists() else "no such folder"
        parser.error(f"LOGDIR {args.logdir}: {why}")
    if args.checkpoint is not None and args.method != "olstm-dvhop":
        parser.error(f"--checkpoint is read only by --method olstm-dvhop, not {args.method}")
    torch.set_num_threads(1)
    paths = sorted(args.logdir.glob("*.npz"))
    if not paths:
        nested = sorted({p.parent for p in args.logdir.glob("*/**/*.npz")})
        hint = (f" (its subfolders hold some; pass one of them: "
                f"{', '.join(str(p) for p in nested[:3])}{', ...' if len(nested) > 3 else ''})"
                if nested else "")
        print(f"no .npz logs in {args.logdir}{hint}", file=sys.stderr)
        return 1
    try:
        model = load_checkpoint(args.checkpoint or DEFAULT_CHECKPOINT) \
            if args.method == "olstm-dvhop" else None
    except CheckpointError as exc:
        parser.error(f"--checkpoint {exc}")
    width = max(len(p.name) for p in paths)
    print(f"{'log':<{width}}  {'nodes':>5}  {'RMSE [m]':>8}  {'localized':>9}  {'coverage':>8}")
    sq, n_loc, n_cov, n_all = 0.0, 0, 0, 0
    for path in paths:
        try:
            episode = prepare(BeaconLog.load(path))
        except FileNotFoundError:
            parser.error(f"{path}: no such file (a broken link, or removed while the folder "
                         f"was read)")
        except BeaconLogError as exc:      # prepare()'s errors name no file: named here
            parser.error(str(exc) if exc.path is not None
                         else str(BeaconLogError(exc.reason, exc.key, path)))
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
