"""Presets, the episode grid, and running it in worker processes with resume.

A preset is a grid of field sizes, node counts and obstacle densities with a number of seeds.
Episode ``(method, field size F, density d, N, seed s)`` runs on the shipped test map
``list_maps("test", field_size=F, densities=(d, d))[s % k]`` (the k test maps of that size and
density taken in turn) with the random generator seeded by ``s`` alone, so every method sees the
same map and nodes for the same seed, and the result depends on the key only -- not on the
worker count or the order of the episodes.

The ``robustness`` preset runs on freshly generated maps instead: episode (density d, seed
index s) plays :func:`~aoass_env.evaluation.episode.robustness_map` of the name
``generated/d<d>_f<F>_r<s>`` (map seed sequence ``[ROBUSTNESS_MAP_SEED, round(100 d), s]``) with
the episode seed :func:`robustness_seed` ``= ROBUSTNESS_EPISODE_SEED_BASE + 1000 round(100 d) +
s``; neither seed is used anywhere else in the project.

:func:`run_jobs` skips the (episode, localizer) pairs already in ``episodes.csv``, runs the
others on a backend (:mod:`aoass_env.backends`: local worker processes, or Ray tasks) and appends
each finished episode's rows as soon as it arrives, so an interrupted sweep resumes where it
stopped. This process is the only writer of ``episodes.csv``, whatever the backend.
"""

from __future__ import annotations

import contextlib
import functools
import time
import warnings
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from aoass_env.backends import Backend, LocalBackend, set_threads
from aoass_env.beacon_log import BeaconLog, BeaconLogError
from aoass_env.evaluation.episode import (
    localize_log,
    log_key,
    robustness_map_name,
    run_episode,
)
from aoass_env.evaluation.methods import RunOptions
from aoass_env.evaluation.store import EpisodeKey, EpisodeStore, EvaluationError
from aoass_env.maps import list_maps

__all__ = ["PRESETS", "ROBUSTNESS_EPISODE_SEED_BASE", "Job", "Preset", "SweepReport",
           "episode_jobs", "job_rows", "log_jobs", "robustness_seed", "run_jobs"]

#: Episode seeds of the ``robustness`` preset start here (the other presets use 0..seeds-1).
ROBUSTNESS_EPISODE_SEED_BASE = 710_000
#: Seed indices per density of a generated-map preset (they must not reach the next density's).
MAX_GENERATED_SEEDS = 1000


@dataclass(frozen=True)
class Preset:
    """A grid of episodes: field sides (m), node counts, obstacle densities, seeds 0..seeds-1.

    ``maps``: ``"test"``, the shipped test maps taken in turn by seed, or ``"generated"``, a
    freshly generated map per (density, seed) with the seeds of :func:`robustness_seed`.
    ``localize``: whether the episodes are localized unless ``--localizers`` says otherwise
    (False: one row per episode with localizer ``none``)."""

    name: str
    field_sizes: tuple[float, ...]
    n_nodes: tuple[int, ...]
    densities: tuple[float, ...]
    seeds: int
    description: str
    maps: str = "test"
    localize: bool = True


PRESETS: dict[str, Preset] = {p.name: p for p in (
    Preset("quick", (100.0,), (100,), (0.1, 0.2, 0.3, 0.4), 1,
           "every method once per density 0.1-0.4, 100 m, N = 100 (a few minutes on 2 cores)"),
    Preset("fig2", (100.0,), (100, 200, 300, 400, 500), (0.1, 0.2, 0.3, 0.4), 30,
           "Figure 2: 100 m, N = 100-500, densities 0.1-0.4"),
    Preset("fig3", (100.0, 200.0), (600, 700, 800, 900, 1000), (0.2,), 30,
           "Figure 3: N = 600-1000 on 100 m and 200 m fields, density 0.2"),
    Preset("fig4", (100.0,), (100,), (0.5, 0.6), 30,
           "Figure 4: densities 0.5 and 0.6, 100 m, N = 100"),
    Preset("smoke", (100.0,), (60,), (0.1,), 1,
           "one episode per method, 100 m, density 0.1, N = 60 (the test suite's)"),
    Preset("robustness", (100.0,), (100,), (0.1, 0.2, 0.3, 0.4, 0.5, 0.6), 50,
           "50 freshly generated maps per density 0.1-0.6, 100 m, N = 100, no localization",
           maps="generated", localize=False),
)}


def robustness_seed(density: float, index: int) -> int:
    """The episode seed of seed index ``index`` (0..999) at ``density`` in a generated-map
    preset: ``ROBUSTNESS_EPISODE_SEED_BASE + 1000 round(100 density) + index``."""
    return ROBUSTNESS_EPISODE_SEED_BASE + MAX_GENERATED_SEEDS * round(100 * density) + index


@dataclass(frozen=True)
class Job:
    """One unit of work: play episode ``key`` (or localize the saved ``log``) and localize it
    with ``localizers``."""

    key: EpisodeKey
    localizers: tuple[str, ...]
    log: Path | None = None


@dataclass
class SweepReport:
    """What :func:`run_jobs` did: episodes finished, skipped (already in the file), failed
    (key and traceback), and the wall time (s)."""

    finished: int = 0
    skipped: int = 0
    failed: list[tuple[EpisodeKey, str]] = field(default_factory=list)
    wall_seconds: float = 0.0


def episode_jobs(preset: Preset, methods: Iterable[str], localizers: tuple[str, ...],
                 seeds: int | None = None) -> list[Job]:
    """The preset's episodes for ``methods`` (``seeds`` overrides the preset's count), grid
    point by grid point, every method at each point.

    Raises:
        EvaluationError: no shipped test map of a field size and density of the grid; more
            than 1000 seeds for a generated-map preset.
    """
    methods = list(methods)
    if preset.maps == "generated":
        return _generated_jobs(preset, methods, localizers,
                               preset.seeds if seeds is None else seeds)
    jobs = []
    for size in preset.field_sizes:
        for density in preset.densities:
            maps = list_maps("test", field_size=size, densities=(density, density))
            if not maps:
                raise EvaluationError(f"no shipped test map of {size:g} m and density "
                                      f"{density:g} for preset {preset.name!r}")
            for n in preset.n_nodes:
                for seed in range(preset.seeds if seeds is None else seeds):
                    jobs += [Job(EpisodeKey(m, maps[seed % len(maps)], size, n, density, seed),
                                 localizers) for m in methods]
    return jobs


def _generated_jobs(preset: Preset, methods: list[str], localizers: tuple[str, ...],
                    seeds: int) -> list[Job]:
    """:func:`episode_jobs` of a generated-map preset: map ``s`` of each density and field
    size, episode seed :func:`robustness_seed`."""
    if seeds > MAX_GENERATED_SEEDS:
        raise EvaluationError(f"preset {preset.name!r} takes at most {MAX_GENERATED_SEEDS} "
                              f"seeds, got {seeds}")
    return [Job(EpisodeKey(m, robustness_map_name(size, density, s), size, n, density,
                           robustness_seed(density, s)), localizers)
            for size in preset.field_sizes for density in preset.densities
            for n in preset.n_nodes for s in range(seeds) for m in methods]


def log_jobs(folder: Path, localizers: tuple[str, ...]) -> list[Job]:
    """A job per beacon log (``*.npz``, searched recursively) in ``folder``; a copy of an
    earlier log (the same arrays) is left out with a warning.

    Raises:
        EvaluationError: ``folder`` is not a folder, holds no ``.npz`` file, one that is not a
            beacon log, or two different logs with one episode key (logs recorded without a
            seed, say: their rows could not be told apart).
    """
    if not folder.is_dir():
        raise EvaluationError(f"--logs {folder}: no such folder")
    paths = sorted(folder.rglob("*.npz"))
    if not paths:
        raise EvaluationError(f"--logs {folder}: no beacon log (*.npz) in it")
    jobs: dict[EpisodeKey, Job] = {}
    for path in paths:
        try:
            key = log_key(path)
        except BeaconLogError as exc:
            raise EvaluationError(f"--logs {folder}: {exc}") from None
        if key in jobs:
            first = jobs[key].log
            if not _same_log(first, path):
                raise EvaluationError(
                    f"--logs {folder}: {path} and {first} are different episodes with one "
                    f"key (method {key.method}, map {key.map}, N={key.n_nodes}, seed "
                    f"{key.seed}{', unknown' if key.seed < 0 else ''}); localize them in "
                    f"separate runs")
            warnings.warn(f"{path} is a copy of {first}; left out", stacklevel=2)
            continue
        jobs[key] = Job(key, localizers, path)
    return list(jobs.values())


def _same_log(a: Path, b: Path) -> bool:
    """Do the beacon logs at ``a`` and ``b`` hold the same arrays, bit for bit (extras
    included)?"""
    first, second = BeaconLog.load(a).arrays(), BeaconLog.load(b).arrays()
    return first.keys() == second.keys() and all(
        (x.dtype, x.shape, x.tobytes()) == (y.dtype, y.shape, y.tobytes())
        for x, y in ((np.asarray(first[k]), np.asarray(second[k])) for k in first))


def job_rows(job: Job, options: RunOptions, log_dir: Path | None) -> list[dict[str, Any]]:
    """The ``episodes.csv`` rows of ``job`` (run on a backend's worker; raises when the episode
    fails, so that a Ray task is retried)."""
    if job.log is not None:
        return localize_log(job.log, job.localizers)
    return run_episode(job.key, job.localizers, options, log_dir)


def run_jobs(jobs: list[Job], store: EpisodeStore, *, workers: int = 1,
             backend: Backend | None = None, options: RunOptions | None = None,
             log_dir: Path | None = None, progress: bool = True,
             desc: str = "episodes") -> SweepReport:
    """Run the jobs not yet in ``store`` on ``backend`` (default: ``workers`` local processes;
    1: in this process), appending each episode's rows as it finishes; a progress bar shows
    finished, skipped and failed counts. Sets this process's torch threads to 1."""
    t0 = time.perf_counter()
    report = SweepReport()
    todo = []
    for job in jobs:
        missing = tuple(name for name in job.localizers if (job.key, name) not in store.done)
        if missing:
            todo.append(replace(job, localizers=missing))
        else:
            report.skipped += 1
    set_threads(1)
    backend = backend or LocalBackend(workers)
    work = functools.partial(job_rows, options=options or RunOptions(), log_dir=log_dir)
    with tqdm(total=len(todo), desc=desc, unit="episode", disable=not progress,
              dynamic_ncols=True) as bar:
        bar.set_postfix(finished=0, skipped=report.skipped, failed=0)
        with contextlib.closing(backend.run(work, todo)) as results:
            for job, rows, error in results:
                if rows is not None:
                    try:     # rows the file could not read back: the episode failed (no row)
                        store.append(rows)
                    except ValueError as exc:
                        rows, error = None, f"its rows do not fit episodes.csv: {exc}"
                if rows is not None:
                    report.finished += 1
                else:
                    report.failed.append((job.key, error or ""))
                    tqdm.write(f"episode {job.key} failed:\n{error}")
                bar.update()
                bar.set_postfix(finished=report.finished, skipped=report.skipped,
                                failed=len(report.failed))
    report.wall_seconds = time.perf_counter() - t0
    return report
