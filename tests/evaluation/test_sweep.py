"""Presets, the episode grid, resume, the worker pool and --logs jobs."""

import math
from dataclasses import replace

import pytest

from aoass_env.evaluation.episode import run_episode
from aoass_env.evaluation.methods import RunOptions
from aoass_env.evaluation.store import EpisodeStore, EvaluationError, read_episodes
from aoass_env.evaluation.sweep import PRESETS, Job, episode_jobs, log_jobs, run_jobs
from aoass_env.maps import list_maps

OPTIONS = RunOptions(max_steps=80)


def _stable(rows):
    """Rows without the timings, in key order, missing values (None, NaN) as "-"."""
    def cell(v):
        return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else v
    return sorted(({k: cell(v) for k, v in r.items() if not k.endswith("seconds")}
                   for r in rows),
                  key=lambda r: (r["method"], r["seed"], r["localizer"]))


def test_presets_match_the_issue():
    assert PRESETS["fig2"].n_nodes == (100, 200, 300, 400, 500)
    assert PRESETS["fig2"].densities == (0.1, 0.2, 0.3, 0.4)
    assert PRESETS["fig3"].n_nodes == (600, 700, 800, 900, 1000)
    assert PRESETS["fig3"].field_sizes == (100.0, 200.0)
    assert PRESETS["fig4"].densities == (0.5, 0.6)
    assert all(PRESETS[p].seeds == 30 for p in ("fig2", "fig3", "fig4"))


def test_grid_cycles_the_test_maps_by_seed():
    jobs = episode_jobs(PRESETS["fig4"], ["spiral", "scan"], ("dvhop",), seeds=4)
    assert len(jobs) == 2 * 4 * 2                       # densities x seeds x methods
    maps = list_maps("test", field_size=100, densities=(0.5, 0.5))
    spiral = [j.key for j in jobs if j.key.method == "spiral" and j.key.obstacle_density == 0.5]
    assert [k.map for k in spiral] == [maps[s % len(maps)] for s in range(4)]
    assert [k.seed for k in spiral] == [0, 1, 2, 3]
    assert len({j.key for j in jobs}) == len(jobs)


def test_resume_skips_finished_rows_and_runs_only_missing_localizers(small_key, tmp_path):
    path = tmp_path / "episodes.csv"
    jobs = [Job(small_key("spiral", seed), ("dvhop",)) for seed in (0, 1)]
    with EpisodeStore(path) as store:
        report = run_jobs(jobs, store, options=OPTIONS, progress=False)
    assert (report.finished, report.skipped, report.failed) == (2, 0, [])
    with EpisodeStore(path) as store:
        report = run_jobs(jobs, store, options=OPTIONS, progress=False)
    assert (report.finished, report.skipped) == (0, 2)
    more = [Job(j.key, ("dvhop", "consensus")) for j in jobs]
    with EpisodeStore(path) as store:
        report = run_jobs(more, store, options=OPTIONS, progress=False)
    assert report.finished == 2
    rows = read_episodes(path)
    assert sorted((r["seed"], r["localizer"]) for r in rows) == [
        (0, "consensus"), (0, "dvhop"), (1, "consensus"), (1, "dvhop")]


def test_a_failed_episode_is_reported_and_the_others_written(small_key, tmp_path):
    bad = Job(replace(small_key("spiral"), map=str(tmp_path / "missing.txt")), ("dvhop",))
    with EpisodeStore(tmp_path / "episodes.csv") as store:
        report = run_jobs([bad, Job(small_key("scan"), ("dvhop",))], store, options=OPTIONS,
                          progress=False)
    assert report.finished == 1 and len(report.failed) == 1
    assert report.failed[0][0] == bad.key and "MapError" in report.failed[0][1]
    assert [r["method"] for r in store.rows] == ["scan"]


def test_worker_pool_gives_the_rows_of_one_process(small_key, tmp_path):
    jobs = [Job(small_key(m), ("dvhop",)) for m in ("spiral", "aoass-scripted")]
    with EpisodeStore(tmp_path / "pool" / "episodes.csv") as store:
        report = run_jobs(jobs, store, workers=2, options=OPTIONS, progress=False)
    assert report.finished == 2
    serial = [row for j in jobs for row in run_episode(j.key, j.localizers, OPTIONS)]
    assert _stable(read_episodes(tmp_path / "pool" / "episodes.csv")) == _stable(serial)


def test_log_jobs_read_the_key_of_each_saved_log(small_key, tmp_path):
    key = small_key("spiral", 3)
    run_episode(key, ("dvhop",), OPTIONS, log_dir=tmp_path / "logs")
    (job,) = log_jobs(tmp_path / "logs", ("dvhop",))
    assert job.key == key and job.log.suffix == ".npz"
    (tmp_path / "empty").mkdir()
    with pytest.raises(EvaluationError, match="no beacon log"):
        log_jobs(tmp_path / "empty", ("dvhop",))
