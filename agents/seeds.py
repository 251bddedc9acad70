"""Several training seeds: ``python train.py --seeds 0-4 [--backend ray]``.

Each seed is an independent :func:`~agents.training.train_agent` run: its models and run.yml in
``<out>/seed<S>/`` and its TensorBoard run in ``<log-dir>/<algo>_seed<S>_<n>`` (SB3 numbers the
runs of one name). The runs go through a backend of :mod:`aoass_env.backends`: one after
another in this process (``local``), or one Ray task per seed (``ray``), each with the CPUs of
its environments. A seed that fails is reported with its traceback; the others go on.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import re
from collections.abc import Callable, Sequence
from pathlib import Path

from agents.training import MAX_SEED, TrainRun, train_agent
from aoass_env.backends import Backend

__all__ = ["MAX_SEEDS", "parse_seeds", "portable", "report_line", "seed_runs", "train_seeds"]

_SEED_ITEM = re.compile(r"(\d+)(?:-(\d+))?")


#: The most seeds one ``--seeds`` may name (one training run each).
MAX_SEEDS = 1000


def parse_seeds(text: str, limit: int = MAX_SEEDS) -> list[int]:
    """The seeds of ``--seeds``: ranges ``A-B`` (A <= B, both included) and single seeds,
    comma-separated, e.g. ``0-4``, ``0,2,5`` or ``0-2,7``; at most ``limit`` seeds, checked
    before any list is built (linear time in the text and the seeds).

    Raises:
        ValueError: another form, a negative or descending range, a seed above
            :data:`~agents.training.MAX_SEED`, a seed given twice, or more than ``limit`` seeds.
    """
    spans = []
    for part in text.split(","):
        match = _SEED_ITEM.fullmatch(part.strip())
        if match is None or (match[2] is not None and int(match[2]) < int(match[1])):
            raise ValueError(f"--seeds {text!r}: expected non-negative integers as a range A-B "
                             f"(A <= B), a list A,B,C or both, e.g. 0-4 or 0,2,5")
        spans.append((int(match[1]), int(match[2] or match[1])))
    if max(high for _, high in spans) > MAX_SEED:
        raise ValueError(f"--seeds {text!r}: a seed above {MAX_SEED} (seeds are 32-bit)")
    total = sum(high - low + 1 for low, high in spans)
    if total > limit:
        raise ValueError(f"--seeds {text!r}: {total} seeds; at most {limit} (one run each)")
    seeds = [s for low, high in spans for s in range(low, high + 1)]
    seen: set[int] = set()
    repeated = sorted({s for s in seeds if s in seen or seen.add(s)})
    if repeated:
        raise ValueError(f"--seeds {text!r}: seed(s) {', '.join(map(str, repeated))} given "
                         f"twice")
    return seeds


def seed_runs(run: TrainRun, seeds: Sequence[int]) -> list[TrainRun]:
    """One copy of ``run`` per seed, writing its models into ``<run.out>/seed<S>/``."""
    return [dataclasses.replace(run, seed=seed, out=Path(run.out) / f"seed{seed}")
            for seed in seeds]


def portable(run: TrainRun) -> TrainRun:
    """``run`` with absolute paths, for a worker that may run in another folder."""
    def absolute(path: Path | None) -> Path | None:
        return None if path is None else Path(path).resolve()
    return dataclasses.replace(run, config=absolute(run.config), resume=absolute(run.resume),
                               out=absolute(run.out), log_dir=absolute(run.log_dir))


def report_line(line: str) -> None:
    """Print a progress line at once (also from a Ray worker, whose output the driver shows)."""
    print(line, flush=True)


def train_seeds(runs: Sequence[TrainRun], backend: Backend,
                report: Callable[[str], None] = report_line
                ) -> list[tuple[TrainRun, Path | None, str | None]]:
    """Train ``runs`` on ``backend``; returns ``(run, final model, None)`` or ``(run, None,
    traceback)`` per run, in completion order, and reports each as it ends. ``report`` must be
    picklable for a Ray backend (a module-level function)."""
    train = functools.partial(train_agent, report=report)
    results = []
    with contextlib.closing(backend.run(train, [portable(r) for r in runs])) as outcomes:
        for run, final, error in outcomes:
            report(f"seed {run.seed}: " + (f"done, {final}" if error is None else "FAILED"))
            results.append((run, final, error))
    return results
