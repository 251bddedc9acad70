"""``python3 evaluate.py``: run a preset's episodes for the chosen methods, localize every beacon
log, write episodes.csv, summary.csv, summary.md and the figures (docs/evaluation.md). The
``robustness`` preset (generated maps) is not localized unless ``--localizers`` asks for it, and
its summary.md opens with the per-density robustness tables.

Exit status: 0 done, 1 some episodes failed (the others are written), 2 bad input (nothing run),
130 interrupted (Ctrl-C; the finished episodes are written).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch

from aoass_env.atomic import remove_stale_temporaries, write_text_atomic
from aoass_env.backends import (
    BackendError,
    add_backend_arguments,
    deliver_interrupts,
    make_backend,
)
from aoass_env.evaluation.episode import GENERATED_PREFIX, ROBUSTNESS_MAP_SEED, log_name
from aoass_env.evaluation.methods import (
    DEFAULT_POLICY,
    METHODS,
    RunOptions,
    select_methods,
    zero_action_stack_digest,
)
from aoass_env.evaluation.report import (
    draw_figures,
    label,
    robustness_markdown,
    seconds_per_episode,
    summary_markdown,
    write_summary_csv,
)
from aoass_env.evaluation.store import (
    BLAS_KERNELS,
    NO_LOCALIZER,
    EpisodeStore,
    EvaluationError,
    apply_inputs,
    blas_kernels,
    config_input,
    file_digest,
    in_key_order,
    record_run,
    row_key,
    stale_rows,
)
from aoass_env.evaluation.sweep import (
    PRESETS,
    ROBUSTNESS_EPISODE_SEED_BASE,
    Job,
    Preset,
    episode_jobs,
    log_jobs,
    run_jobs,
)
from aoass_env.localization import METHODS as LOCALIZERS
from aoass_env.localization.olstm import DEFAULT_CHECKPOINT, CheckpointError, load_checkpoint

DEFAULT_LOCALIZERS = ("dvhop", "olstm-dvhop")
LOCALIZER_COMMAND = "python3 train.py localizer"


#: The most seeds per grid point of ``--seeds``.
MAX_SEEDS = 10_000


def _names(values: list[str] | None, flag: str) -> list[str] | None:
    """Names given as separate words and/or comma-separated; an error naming ``flag`` when it
    was given but names nothing."""
    if values is None:
        return None
    names = [n.strip() for v in values for n in v.split(",") if n.strip()]
    if not names:
        raise EvaluationError(f"{flag}: no name given ({values!r}); leave {flag} out for the "
                              f"default")
    return names


def _check_policy(policy: Path, run: Path | None) -> Path:
    """The run record of ``policy`` (``run``, else the run.yml beside it), after loading the
    policy once without unpickling anything; an error naming the file otherwise."""
    from agents.checkpoints import PolicyFileError, record_path
    from aoass_env.evaluation.methods import load_policy
    record = run if run is not None else record_path(policy)
    if not record.is_file():
        raise EvaluationError(
            f"--policy {policy}: no run.yml beside it, so the stack it was trained in "
            f"(action_repeat, tracker, safety) is unknown; copy its run.yml along or give "
            f"one with --policy-run FILE" if run is None else f"--policy-run {run}: no such file")
    try:
        load_policy(str(policy.resolve()), record=str(record.resolve()))
    except PolicyFileError as exc:
        # the flag that gave the file at fault: the run record's own, when it is the record
        flag = "--policy-run" if run is not None and str(record.resolve()) in str(exc) \
            else "--policy"
        raise EvaluationError(f"{flag}: {exc}") from None
    return record


def _check_checkpoint(method: str, checkpoint: Path) -> None:
    """Load ``method``'s own policy checkpoint once before any episode (every episode failed
    on its own traceback otherwise); an error naming the method and the file."""
    from agents.checkpoints import PolicyFileError
    from aoass_env.evaluation.methods import load_policy
    try:
        load_policy(str(checkpoint))     # as the episodes load it (run.yml beside it)
    except PolicyFileError as exc:
        raise EvaluationError(f"method {method}: its checkpoint: {exc}") from None


def build_parser() -> argparse.ArgumentParser:
    presets = "\n".join(f"  {p.name:10s} {p.description}; {p.seeds} seed(s)"
                        for p in PRESETS.values())
    parser = argparse.ArgumentParser(
        prog="evaluate.py", formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Benchmark the sweep methods on the shipped test maps or freshly generated "
                    "ones (Eq. 15-19).",
        epilog=f"presets:\n{presets}\n\nmethods: {', '.join(METHODS)}\n"
               f"localizers: {', '.join(LOCALIZERS)}, or {NO_LOCALIZER} (no localization)"
               f"\n\nSee docs/evaluation.md.")
    parser.add_argument("--preset", choices=list(PRESETS), default=None,
                        help="episode grid (default: quick)")
    parser.add_argument("--methods", nargs="+", metavar="M",
                        help="methods to run (default: all)")
    parser.add_argument("--localizers", nargs="+", metavar="L",
                        help=f"localizers, or {NO_LOCALIZER} (default: "
                             f"{' '.join(DEFAULT_LOCALIZERS)}; for a preset on generated "
                             f"maps: {NO_LOCALIZER})")
    parser.add_argument("--seeds", type=int, metavar="S",
                        help="seeds 0..S-1 per grid point (default: the preset's)")
    parser.add_argument("--workers", type=int, metavar="W",
                        help="worker processes (default: all cores); with --backend ray and no "
                             "--address, the CPUs of the local Ray instance")
    add_backend_arguments(parser, "episode", "--workers processes")
    parser.add_argument("--out", type=Path, metavar="DIR",
                        help="output folder (default: out/<preset>, with --logs out/localized)")
    parser.add_argument("--save-logs", action="store_true",
                        help="save every episode's beacon log to DIR/logs/<method>/")
    parser.add_argument("--logs", type=Path, metavar="DIR",
                        help="localize the saved beacon logs (*.npz) in DIR instead of running "
                             "episodes")
    parser.add_argument("--policy", type=Path, metavar="ZIP",
                        help="checkpoint of the aoass policy (default: the shipped one)")
    parser.add_argument("--policy-run", type=Path, metavar="YML",
                        help="run record (run.yml of train.py) of the stack the policy was "
                             "trained in (default: the run.yml beside --policy; a policy "
                             "without one is refused)")
    parser.add_argument("--discard-changed", action="store_true",
                        help="resuming DIR: drop the episodes of the methods whose config "
                             "defaults or checkpoints changed since they ran, and run them "
                             "again (without it such a resume is refused)")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    return parser


def _check_localizers(names: list[str] | None,
                      default: tuple[str, ...] = DEFAULT_LOCALIZERS) -> tuple[str, ...]:
    chosen = tuple(dict.fromkeys(names or default))
    if NO_LOCALIZER in chosen:
        if len(chosen) > 1:
            raise EvaluationError(f"--localizers {NO_LOCALIZER} turns localization off; it "
                                  f"does not go with other localizers")
        return chosen
    unknown = [n for n in chosen if n not in LOCALIZERS]
    if unknown:
        raise EvaluationError(f"unknown localizer(s) {', '.join(map(repr, unknown))}; valid: "
                              f"{', '.join(LOCALIZERS)}, or {NO_LOCALIZER}")
    if "olstm-dvhop" in chosen and not DEFAULT_CHECKPOINT.is_file():
        raise EvaluationError(f"localizer olstm-dvhop needs its checkpoint {DEFAULT_CHECKPOINT}, "
                              f"which is missing; produce it with `{LOCALIZER_COMMAND}`")
    if "olstm-dvhop" in chosen:
        try:        # once here, so that a damaged checkpoint fails before any episode
            load_checkpoint(DEFAULT_CHECKPOINT)
        except CheckpointError as exc:
            raise EvaluationError(f"localizer olstm-dvhop: {exc}") from None
    return chosen


def _maps_note(preset: Preset | None) -> str:
    """Where the episodes' maps and seeds come from, for summary.md."""
    if preset is not None and preset.maps == "generated":
        return (f"Maps generated afresh: map s of density d is generate_map(F, d, "
                f"default_rng([{ROBUSTNESS_MAP_SEED}, round(100 d), s])), the episode's random "
                f"generator seeded with {ROBUSTNESS_EPISODE_SEED_BASE} + 1000 round(100 d) + s.")
    return ("Maps from maps/test, the k maps of each field size and density taken in turn by "
            "seed (seed s: map s mod k), the episode's random generator seeded with s.")


def _check_saved_logs(jobs: list[Job], store: EpisodeStore, logs: Path,
                      stale: Callable[[dict[str, Any]], bool] | None) -> None:
    """:class:`EvaluationError` when ``--save-logs`` would leave logs out: episodes already in
    ``store`` are not played again (but its ``stale`` rows, which are to be dropped), so those
    without a saved log would never get one."""
    done = {row_key(r) for r in store.rows if stale is None or not stale(r)}
    missing = [job.key for job in jobs
               if all((job.key, name) in done for name in job.localizers)
               and not (logs / log_name(job.key)).is_file()]
    if missing:
        raise EvaluationError(
            f"--save-logs: {len(missing)} episode(s) are already in {store.path} without a "
            f"saved log (e.g. {logs / log_name(missing[0])}), and finished episodes are not "
            f"played again; give another --out to save every log")


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    store = None
    try:
        if args.seeds is not None and not 1 <= args.seeds <= MAX_SEEDS:
            raise EvaluationError(f"--seeds must be in [1, {MAX_SEEDS}], got {args.seeds}")
        if args.workers is not None and args.workers < 1:
            raise EvaluationError(f"--workers must be at least 1, got {args.workers}")
        preset = PRESETS[args.preset or "quick"]
        policy = args.policy or DEFAULT_POLICY
        localizers = _check_localizers(
            _names(args.localizers, "--localizers"),
            DEFAULT_LOCALIZERS if preset.localize or args.logs else (NO_LOCALIZER,))
        if args.logs is not None:
            if (args.preset or args.methods or args.seeds or args.save_logs or args.policy
                    or args.policy_run):
                raise EvaluationError("--logs localizes every log in its folder; --preset, "
                                      "--methods, --seeds, --save-logs, --policy and "
                                      "--policy-run do not apply")
            out = args.out or Path("out") / "localized"
            jobs = log_jobs(args.logs.resolve(), localizers)
            title = f"AOASS evaluation: beacon logs of {args.logs}"
        else:
            methods = select_methods(_names(args.methods, "--methods"), policy)
            out = args.out or Path("out") / preset.name
            jobs = episode_jobs(preset, methods, localizers, args.seeds)
            title = f"AOASS evaluation: preset {preset.name}"
        # what each method's rows were made with, and the methods each input concerns
        inputs: dict[str, str] = {}
        scope: dict[str, list[str]] = {}
        record = None
        if args.logs is None:
            for name in methods:
                spec = METHODS[name]
                inputs[config_input(name)] = spec.defaults_digest
                scope[config_input(name)] = [name]
                if spec.checkpoint:
                    _check_checkpoint(name, spec.checkpoint)
                    inputs[f"{name} checkpoint"] = file_digest(
                        spec.checkpoint, spec.checkpoint.with_name("run.yml"))
                    scope[f"{name} checkpoint"] = [name]
            scope["policy"] = [m for m in methods if METHODS[m].uses_policy]
            if any(METHODS[m].stack == "policy" for m in methods):
                record = _check_policy(policy, args.policy_run)
                if scope["policy"]:
                    inputs["policy"] = file_digest(policy, record)
            elif args.policy or args.policy_run:
                users = [n for n, spec in METHODS.items() if spec.stack == "policy"]
                raise EvaluationError(
                    f"--policy and --policy-run are for the method(s) that run that policy or "
                    f"play in its stack ({', '.join(users)}); none of {', '.join(methods)} "
                    f"does")
            stacked = RunOptions(policy=str(policy.resolve()),
                                 policy_run=None if record is None else str(record.resolve()))
            for name in methods:     # the zero-action ablations: the recorded stack they play in
                spec = METHODS[name]
                if spec.stack and not spec.uses_policy and spec.checkpoint is None:
                    inputs[f"{name} stack"] = zero_action_stack_digest(name, stacked)
                    scope[f"{name} stack"] = [name]
        if "olstm-dvhop" in localizers:
            inputs["olstm-dvhop"] = file_digest(DEFAULT_CHECKPOINT)
        # this machine's BLAS kernels: a resume elsewhere must not mix last-bit differences
        inputs[BLAS_KERNELS] = blas_kernels()
        backend = make_backend(args.backend, workers=args.workers, address=args.address)
        store = EpisodeStore(out / "episodes.csv")
        for folder in (out, *sorted(p for p in (out / "logs").glob("*") if p.is_dir())):
            for stale in remove_stale_temporaries(folder):
                print(f"removed {stale}, left by an interrupted write", file=sys.stderr)
        stale = stale_rows(store, inputs, scope, discard=args.discard_changed,
                           localizers={"olstm-dvhop": "olstm-dvhop"})
        if args.save_logs:     # before any row is dropped: a refused run changes nothing
            _check_saved_logs(jobs, store, out / "logs", stale)
        apply_inputs(store, inputs, stale)
    except (EvaluationError, BackendError) as exc:
        if store is not None:
            store.close()       # its lock on the folder (main may run again in one process)
        parser.error(str(exc))

    torch.set_num_threads(1)
    # absolute paths: the workers of a Ray cluster may run in another folder
    options = RunOptions(policy=str(policy.resolve()),
                         policy_run=None if record is None else str(record.resolve()))
    log_dir = (out / "logs").resolve() if args.save_logs else None
    run = {"preset": None if args.logs else preset.name,
           "seeds": None if args.logs else args.seeds or preset.seeds,
           "backend": backend.description}
    with store:
        start, before = time.perf_counter(), {key for key, _ in store.done}
        try:
            with deliver_interrupts():  # also when an episode runs in this process (1 worker)
                report = run_jobs(jobs, store, backend=backend, options=options,
                                  log_dir=log_dir, progress=not args.no_progress,
                                  desc=args.logs.name if args.logs else preset.name)
        except KeyboardInterrupt:
            # the episodes it finished and its time count in the page's wall time too
            finished = len({key for key, _ in store.done} - before)
            record_run(store, {**run, "finished": finished, "interrupted": True,
                               "wall_seconds": time.perf_counter() - start})
            print(f"\ninterrupted: the finished episodes are in {store.path}; run the same "
                  f"command again to continue", file=sys.stderr)
            return 130
        record_run(store, {**run, "finished": report.finished, "skipped": report.skipped,
                           "failed": len(report.failed), "wall_seconds": report.wall_seconds})
    rows = in_key_order(store.rows)     # the tables and figures whatever order rows came in
    timing = seconds_per_episode(rows)
    notes = ("" if args.logs else f"{preset.description}. ") + (
        f"This run: {report.finished} episode(s) finished, {report.skipped} already in "
        f"episodes.csv, {len(report.failed)} failed; wall time {report.wall_seconds:.0f} s on "
        f"{backend.description}. {_maps_note(None if args.logs else preset)} "
        f"Mean wall seconds per episode (simulation + localizers): "
        + ", ".join(f"{label(m)} {s:.1f}" for m, s in timing.items()) + ".")
    generated = args.logs is None and preset.maps == "generated"
    # only the generated maps' episodes: a folder shared with another preset holds shipped-map
    # episodes too, which would pool into the "freshly generated maps" tables
    fresh = [r for r in rows if r["map"].startswith(GENERATED_PREFIX)]
    markdown = summary_markdown(rows, title, notes,
                                lead=robustness_markdown(fresh) if generated else "")
    write_text_atomic(out / "summary.md", markdown)
    write_summary_csv(rows, out / "summary.csv")
    figures = draw_figures(rows, out)
    print(markdown)
    print(f"wrote {out / 'episodes.csv'}, {out / 'summary.csv'}, {out / 'summary.md'}"
          + "".join(f", {f}" for f in figures))
    for key, _ in report.failed:
        print(f"FAILED: {key} (traceback above)", file=sys.stderr)
    return 1 if report.failed else 0
