"""The evaluation sweep on the local backend against a local Ray instance, on this machine.

One small sweep (default: preset ``quick`` for ``spiral scan ohm fdpp``, 2 seeds, both
localizers: 32 episodes) runs twice in this process, each time into a fresh folder: first on
the local backend (``--workers`` processes), then on a new local Ray instance of ``--workers``
CPUs. Prints both wall times, the Ray start-up time and the ratios, and checks that the two
``episodes.csv`` hold the same lines once the timing columns are left out (the local run comes
first, so that its worker processes are not forked from a process connected to Ray).

    python3 benchmarks/ray_backend.py [--workers 2] [--seeds 2] [--methods spiral scan ...]
"""

from __future__ import annotations

import argparse
import platform
import sys
import tempfile
import time
from pathlib import Path

import torch

from aoass_env.backends import LocalBackend, RayBackend, require_ray
from aoass_env.evaluation.methods import RunOptions, select_methods
from aoass_env.evaluation.store import EpisodeStore, EvaluationError, comparable_lines
from aoass_env.evaluation.sweep import PRESETS, Job, episode_jobs, run_jobs
from aoass_env.validators import argparse_number

LOCALIZERS = ("dvhop", "olstm-dvhop")


def timed_sweep(jobs: list[Job], backend: LocalBackend | RayBackend, folder: Path
                ) -> tuple[float, set[str]]:
    """Wall time (s) of the sweep into ``folder`` and its episodes.csv lines without timings."""
    with EpisodeStore(folder / "episodes.csv") as store:
        report = run_jobs(jobs, store, backend=backend, options=RunOptions(), progress=False)
    if report.failed or report.finished != len(jobs):
        sys.exit(f"{backend.description}: {len(report.failed)} episode(s) failed")
    return report.wall_seconds, comparable_lines(folder / "episodes.csv")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--preset", choices=list(PRESETS), default="quick")
    parser.add_argument("--methods", nargs="+", default=["spiral", "scan", "ohm", "fdpp"])
    parser.add_argument("--seeds", type=argparse_number(int, 1), default=2)
    parser.add_argument("--workers", type=argparse_number(int, 1), default=2,
                        help="local processes, and CPUs of the Ray instance (default: 2)")
    args = parser.parse_args()
    # checked before Ray starts: an unknown method failed in every episode, on both backends
    try:
        methods = select_methods(args.methods)
    except EvaluationError as err:
        parser.error(f"--methods: {err}")
    try:
        jobs = episode_jobs(PRESETS[args.preset], methods, LOCALIZERS, args.seeds)
    except EvaluationError as err:
        parser.error(f"--preset {args.preset} with --seeds {args.seeds}: {err}")
    ray = require_ray()
    torch.set_num_threads(1)
    print(f"{len(jobs)} episodes: preset {args.preset}, {' '.join(args.methods)}, "
          f"{args.seeds} seed(s), {' + '.join(LOCALIZERS)}; {args.workers} workers; "
          f"Python {platform.python_version()}, Ray {ray.__version__}", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        local_s, local_lines = timed_sweep(jobs, LocalBackend(args.workers), Path(tmp) / "local")
        print(f"local backend ({args.workers} processes): {local_s:6.1f} s", flush=True)
        t0 = time.perf_counter()
        backend = RayBackend(num_cpus=args.workers)
        start_s = time.perf_counter() - t0
        ray_s, ray_lines = timed_sweep(jobs, backend, Path(tmp) / "ray")
        print(f"{backend.description}: {ray_s:6.1f} s "
              f"(+ {start_s:.1f} s to start the instance)")
        ray.shutdown()
    print(f"ratio local / Ray: {local_s / ray_s:.2f} for the sweep, "
          f"{local_s / (ray_s + start_s):.2f} with the start-up")
    same = local_lines == ray_lines
    print(f"episodes.csv: {len(local_lines) - 1} rows, "
          + ("identical on both backends (timing columns left out)" if same
             else f"DIFFERENT: {len(local_lines ^ ray_lines)} lines differ"))
    if not same:
        sys.exit(1)


if __name__ == "__main__":
    main()
