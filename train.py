"""Training entry point.

    python train.py [options]            train the AOASS agent (TD3-LSTM) inside the safety
                                         stack (agents/training.py; hyperparameters in
                                         configs/aoass.yml); --seeds 0-4 trains one run per
                                         seed, --backend ray as Ray tasks (docs/cluster.md)
    python train.py localizer [options]  simulate beacon logs on maps/train and train the
                                         OLSTM-DV-Hop localizer, writing checkpoints/olstm_dvhop.pt

``python train.py --help`` and ``python train.py localizer --help`` list the options.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import shlex
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch

from aoass_env.backends import add_backend_arguments, deliver_interrupts, make_backend
from aoass_env.localization.training import (
    TRAIN_RANGES,
    CachedLogError,
    DivergedError,
    TrainConfig,
    draw_episodes,
    train_localizer,
)
from aoass_env.validators import argparse_number


def _key_value(flag: str) -> Callable[[str], tuple[str, Any]]:
    """An argparse type of ``flag``: ``key:value``, the value read as safe YAML
    (:func:`agents.sections.key_value`)."""
    def parse(text: str) -> tuple[str, Any]:
        from agents.sections import key_value
        try:
            return key_value(text, flag)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
    parse.__name__ = "key:value"
    return parse


def _overrides(flag: str, pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """The ``key:value`` pairs of ``flag`` as a dict; a key given twice is a ValueError naming
    it (the last one used to win unseen, where a key given twice in a YAML file is refused)."""
    found: dict[str, Any] = {}
    for key, value in pairs:
        if key in found:
            raise ValueError(f"{flag} {key}: given twice ({found[key]!r}, then {value!r})")
        found[key] = value
    return found


def _path(text: str) -> Path:
    """An argparse ``type``: a path, never the empty string (which ``Path`` reads as the
    working folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"must be a path, got {text!r}")
    return Path(text)


_path.__name__ = "path"


def _folder(flag: str, path: Path) -> None:
    """A one-line error naming ``flag`` unless ``path`` is a folder this process can write, or
    can create (nothing is created here)."""
    if path.exists() and not path.is_dir():
        raise ValueError(f"{flag} {path}: is a file, not a folder")
    existing = next(p for p in (path, *path.absolute().parents) if p.exists())
    if not existing.is_dir():
        raise ValueError(f"{flag} {path}: {existing} is a file, not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ValueError(f"{flag} {path}: {existing} is not writable")


def _localizer_parser() -> argparse.ArgumentParser:
    defaults = TrainConfig()
    p = argparse.ArgumentParser(
        prog="train.py localizer", description="Simulate logs on maps/train (cached in "
        "--data-dir), train the OLSTM with early stopping on held-out training maps, write the "
        "checkpoint.")
    for field in dataclasses.fields(TrainConfig):
        default = getattr(defaults, field.name)
        kind = (_path if isinstance(default, Path)
                else argparse_number(*TRAIN_RANGES[field.name]))
        p.add_argument(f"--{field.name.replace('_', '-')}", type=kind, default=default,
                       help=f"(default: {default})")
    p.add_argument("--threads", type=argparse_number(int, 1), default=1,
                   help="torch threads (default: 1)")
    return p


def _run_localizer(argv: list[str]) -> None:
    parser = _localizer_parser()
    args = parser.parse_args(argv)
    try:                                  # before any log is simulated or epoch trained
        cfg = TrainConfig(**{f.name: getattr(args, f.name)
                             for f in dataclasses.fields(TrainConfig)})
        _folder("--data-dir", cfg.data_dir)
        if cfg.checkpoint.is_dir():
            raise ValueError(f"--checkpoint {cfg.checkpoint}: is a folder, not a file")
        _folder(f"--checkpoint {cfg.checkpoint}: its folder", cfg.checkpoint.parent)
        draw_episodes(cfg)
    except ValueError as exc:
        name, eq, rest = str(exc).partition("=")   # "seed=..." names its flag, "--seed ..."
        parser.error(f"--{name.replace('_', '-')} {rest}" if eq and name in TRAIN_RANGES
                     else str(exc))
    torch.set_num_threads(args.threads)
    try:
        train_localizer(cfg, report=lambda line: print(line, flush=True))
    except CachedLogError as exc:      # a file an earlier run left in --data-dir
        parser.error(f"--data-dir: {exc}")
    except DivergedError as exc:
        parser.error(f"--learning-rate {args.learning_rate:g}: {exc}")


def _agent_parser() -> argparse.ArgumentParser:
    from agents.training import DEFAULT_CONFIG, MAX_SEED
    p = argparse.ArgumentParser(
        prog="train.py", description=__doc__.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="Subcommand: 'python train.py localizer --help' trains the OLSTM-DV-Hop "
               "localizer instead.")
    p.add_argument("--algo", choices=["td3-lstm", "td3"], default="td3-lstm",
                   help="td3-lstm: recurrent TD3 (agents.RecurrentTD3); td3: SB3's "
                        "feedforward TD3 (ablation) (default: td3-lstm)")
    p.add_argument("--timesteps", type=argparse_number(int, 1), default=None,
                   help="environment steps (default: the config's n_timesteps)")
    seeds = p.add_mutually_exclusive_group()
    seeds.add_argument("--seed", type=argparse_number(int, 0, high=MAX_SEED), default=None,
                       help="(default: 0; with --resume, the resumed run's, from its run.yml)")
    seeds.add_argument("--seeds", metavar="LIST",
                       help="one run per seed: a range 0-4 and/or a list 0,2,5; run S writes "
                            "into <out>/seed<S>/")
    add_backend_arguments(p, "seed", "the runs one after another in this process")
    p.add_argument("--n-envs", type=argparse_number(int, 1), default=1,
                   help="parallel environments, subprocesses when > 1 (default: 1)")
    p.add_argument("--config", type=_path, default=DEFAULT_CONFIG,
                   help="hyperparameter YAML (default: configs/aoass.yml)")
    # "extend": a flag given twice adds its pairs (the default "store" dropped the first
    # flag's pairs unseen); a key given twice is refused by _overrides
    p.add_argument("--hyperparams", type=_key_value("--hyperparams"), nargs="+", default=[],
                   action="extend", metavar="KEY:VALUE",
                   help="replace keys of the config's section, values as YAML; a mapping "
                        "replaces the whole mapping, as in RL Zoo (e.g. learning_rate:0.0003 "
                        "'policy_kwargs:{lstm_hidden_size: 64, net_arch: [32, 32], "
                        "actor_final_init: 0.003}')")
    p.add_argument("--env-kwargs", type=_key_value("--env-kwargs"), nargs="+", default=[],
                   action="extend", metavar="KEY:VALUE",
                   help="replace keys of the section's env (e.g. n_nodes:50 "
                        "'densities:[0.2, 0.3]')")
    p.add_argument("--eval-freq", type=argparse_number(int, 1), default=None,
                   help="env steps between evaluations on the validation maps "
                        "(default: the config's eval.freq)")
    p.add_argument("--eval-episodes", type=argparse_number(int, 1), default=None,
                   help="episodes per evaluation (default: the config's eval.episodes)")
    p.add_argument("--checkpoint-freq", type=argparse_number(int, 1), default=None,
                   help="env steps between checkpoints (default: the config's checkpoint_freq)")
    p.add_argument("--log-interval", type=argparse_number(int, 1), default=4,
                   help="episodes between log rows; a last row is written at the end "
                        "(default: 4)")
    p.add_argument("--resume", type=_path, default=None,
                   help="continue training a saved model (.zip; its replay buffer is loaded "
                        "when saved beside it, as last.zip's is)")
    p.add_argument("--out", type=_path, default=None,
                   help="folder of the run's models, one run per folder (default: "
                        "out/train/aoass_<algo>; the shipped policies are in checkpoints/)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the files another run left in --out (else refused)")
    p.add_argument("--log-dir", type=_path, default=Path("out/tensorboard"),
                   help="TensorBoard folder (default: out/tensorboard)")
    p.add_argument("--no-tensorboard", action="store_true", help="do not write TensorBoard logs")
    p.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    p.add_argument("--threads", type=argparse_number(int, 1), default=1,
                   help="torch threads (default: 1)")
    return p


def _run_agent(argv: list[str]) -> None:
    from agents.checkpoints import PolicyFileError
    from agents.hyperparams import HyperparameterError
    from agents.seeds import parse_seeds, report_line, seed_runs, train_seeds
    from agents.training import (
        TrainRun,
        occupied_message,
        other_run_files,
        run_hyperparams,
        run_seed,
        train_agent,
    )
    parser = _agent_parser()
    args = parser.parse_args(argv)
    torch.set_num_threads(args.threads)
    out = args.out or Path(f"out/train/aoass_{args.algo.replace('-', '_')}")
    try:
        if args.config.is_dir():
            raise ValueError(f"--config {args.config}: is a folder, not a hyperparameter file")
        if args.resume is not None and not args.resume.is_file():
            raise ValueError(f"--resume {args.resume}: no such model file"
                             f"{' (a folder)' if args.resume.is_dir() else ''}")
        _folder("--out", out)
        if not args.no_tensorboard:
            _folder("--log-dir", args.log_dir)
        run = TrainRun(algo=args.algo, timesteps=args.timesteps,
                       seed=run_seed(args.resume, args.seed),
                       n_envs=args.n_envs, config=args.config, resume=args.resume, out=out,
                       log_dir=None if args.no_tensorboard else args.log_dir,
                       progress_bar=not args.no_progress and args.backend == "local",
                       command="python train.py " + " ".join(shlex.quote(a) for a in argv),
                       hyperparams=_overrides("--hyperparams", args.hyperparams),
                       env_kwargs=_overrides("--env-kwargs", args.env_kwargs),
                       eval_freq=args.eval_freq, eval_episodes=args.eval_episodes,
                       checkpoint_freq=args.checkpoint_freq, log_interval=args.log_interval,
                       overwrite=args.overwrite)
        run_hyperparams(run)      # bad files and overrides fail here, before any work
        if args.seeds is not None and args.resume is not None:
            raise ValueError("--resume continues one run; it does not combine with --seeds")
        runs = [run] if args.seeds is None else seed_runs(run, parse_seeds(args.seeds))
        for r in runs:            # a folder holding another run, refused before any run starts
            others = other_run_files(r)
            if others and not args.overwrite:
                raise ValueError(f"--out {occupied_message(r, others)}")
        # local: the runs one after another in this process; ray: a task per run, no retry
        # (a retry would start training again from step 0)
        backend = make_backend(args.backend, workers=1 if args.backend == "local" else None,
                               address=args.address, threads=args.threads, retries=0,
                               task_cpus=max(args.threads, args.n_envs))
        for flag, folder in (("--out", out), ("--log-dir", run.log_dir)):
            try:                        # every option is valid: the folders may be created
                if folder is not None:
                    folder.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise ValueError(f"{flag} {folder}: cannot create the folder "
                                 f"({exc.strerror})") from None
    except (HyperparameterError, ValueError) as exc:
        parser.exit(2, f"train.py: error: {exc}\n")
    try:
        with deliver_interrupts():     # the first Ctrl-C stops, even inside a physics callback
            if args.backend == "local" and args.seeds is None:
                train_agent(run, report=report_line)    # the single run of --seed, as always
                return
            outcomes = train_seeds(runs, backend)
    except PolicyFileError as exc:                       # --resume's files, read before any step
        parser.exit(2, f"train.py: error: --resume: {exc}\n")
    except KeyboardInterrupt:
        parser.exit(130, f"\ntrain.py: interrupted; the last checkpoints are in {out}\n")
    failed = [(r, error) for r, _, error in outcomes if error is not None]
    for r, error in failed:
        print(f"seed {r.seed} failed:\n{error}", file=sys.stderr)
    if failed:
        parser.exit(1, f"train.py: {len(failed)} of {len(runs)} run(s) failed: seed(s) "
                       f"{', '.join(str(r.seed) for r, _ in failed)}\n")


def main(argv: list[str] | None = None) -> None:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["localizer"]:
        _run_localizer(argv[1:])
    else:
        _run_agent(argv)


if __name__ == "__main__":
    main()
