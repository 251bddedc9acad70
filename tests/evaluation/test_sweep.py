"""Presets, the episode grid, resume, the worker pool and --logs jobs."""

import math
import shutil
from dataclasses import replace

import numpy as np
import pytest

from aoass_env.env import AOASSEnv
from aoass_env.evaluation.episode import (
    GENERATED_PREFIX,
    ROBUSTNESS_MAP_SEED,
    episode_map,
    log_key,
    robustness_map,
    robustness_map_name,
    run_episode,
)
from aoass_env.evaluation.methods import RunOptions
from aoass_env.evaluation.store import (
    NO_LOCALIZER,
    EpisodeKey,
    EpisodeStore,
    EvaluationError,
    read_episodes,
)
from aoass_env.evaluation.sweep import (
    PRESETS,
    ROBUSTNESS_EPISODE_SEED_BASE,
    Job,
    episode_jobs,
    log_jobs,
    robustness_seed,
    run_jobs,
)
from aoass_env.maps import DENSITY_TOL, generate_map, list_maps
from aoass_env.maps.generator import clear_cache as forget_generated_maps

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


def test_rows_the_file_cannot_hold_fail_their_episode_only(small_key, tmp_path, monkeypatch):
    # a ValueError of store.append ended the whole run in a traceback
    from aoass_env.evaluation import sweep
    real = sweep.job_rows

    def odd_rows(job, **kwargs):
        rows = real(job, **kwargs)
        return [{**r, "coverage": 5.0} for r in rows] if job.key.method == "spiral" else rows

    monkeypatch.setattr(sweep, "job_rows", odd_rows)
    with EpisodeStore(tmp_path / "episodes.csv") as store:
        report = run_jobs([Job(small_key("spiral"), ("dvhop",)), Job(small_key("scan"),
                                                                     ("dvhop",))],
                          store, options=OPTIONS, progress=False)
    assert report.finished == 1 and [k for k, _ in report.failed] == [small_key("spiral")]
    assert "its rows do not fit episodes.csv: coverage='5.0'" in report.failed[0][1]
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


def test_an_unseeded_log_s_rows_read_back(tmp_path):
    """A log recorded without a seed gets the key seed -1; its rows were refused when read
    back (seed >= 0), so the folder could be neither resumed nor summarised again."""
    from aoass_env.evaluation import cli
    env = AOASSEnv(map="test/d0.10_f100_s500", n_nodes=20)
    env.reset(seed=0)
    env.reset()                              # unseeded: the log records no seed
    for _ in range(30):
        env.step(np.zeros(2))
    (tmp_path / "logs").mkdir()
    env.beacon_log.save(tmp_path / "logs" / "a.npz")
    argv = ["--logs", str(tmp_path / "logs"), "--localizers", "dvhop", "--workers", "1",
            "--out", str(tmp_path / "out"), "--no-progress"]
    assert cli.main(argv) == 0
    assert cli.main(argv) == 0               # resumed: the row is read back, nothing rerun
    (row,) = read_episodes(tmp_path / "out" / "episodes.csv")
    assert row["seed"] == -1 and row["localizer"] == "dvhop"


def test_log_jobs_skip_copies_and_refuse_different_logs_with_one_key(tmp_path):
    """Logs recorded without a seed share the key seed -1: the second used to be left out
    with a warning, a different episode dropped from the table."""
    env = AOASSEnv(map="test/d0.10_f100_s500", n_nodes=20)
    env.reset(seed=0)
    folder = tmp_path / "logs"
    folder.mkdir()
    for name in ("b", "c"):                  # unseeded resets: the logs record no seed
        env.reset()
        for _ in range(30):
            env.step(np.zeros(2))
        env.beacon_log.save(folder / f"{name}.npz")
    b, c = (log_key(folder / f"{n}.npz") for n in "bc")
    assert b == c and b.seed == -1
    with pytest.raises(EvaluationError, match=r"c.npz and .*b.npz are different episodes with "
                                              r"one key \(method aoass-env, .*seed -1, "
                                              r"unknown\); localize them in separate runs"):
        log_jobs(folder, ("dvhop",))
    (folder / "c.npz").unlink()
    shutil.copy(folder / "b.npz", folder / "b_copy.npz")
    with pytest.warns(UserWarning, match=r"b_copy.npz is a copy of .*b.npz; left out"):
        (job,) = log_jobs(folder, ("dvhop",))
    assert job.log.name == "b.npz"


def test_robustness_maps_are_regenerated_from_their_name():
    name = robustness_map_name(100.0, 0.3, 7)
    assert name == "generated/d0.30_f100_r7"
    robustness_map.cache_clear()
    first = robustness_map(name)
    robustness_map.cache_clear()
    forget_generated_maps()            # generate_map's own cache of recent draws (issue 20)
    again = robustness_map(name)
    assert first is not again and len(first.polygons) == len(again.polygons)
    assert all(np.array_equal(a, b) for a, b in zip(first.polygons, again.polygons, strict=True))
    assert abs(first.density - 0.3) <= DENSITY_TOL and first.width == 100.0
    expected = generate_map(100.0, 0.3, np.random.default_rng([ROBUSTNESS_MAP_SEED, 30, 7]),
                            clearance=2.5)
    assert all(np.array_equal(a, b) for a, b in zip(first.polygons, expected.polygons,
                                                    strict=True))
    other = robustness_map(robustness_map_name(100.0, 0.3, 8))
    assert not all(np.array_equal(a, b) for a, b in zip(first.polygons, other.polygons,
                                                        strict=False))
    with pytest.raises(EvaluationError, match="not a generated map name"):
        robustness_map("generated/d0.3_r7")


def test_a_generated_map_must_match_its_key():
    key = EpisodeKey("spiral", robustness_map_name(100.0, 0.1, 0), 100.0, 20, 0.1, 1)
    assert episode_map(key).width == 100.0
    with pytest.raises(EvaluationError, match="density"):
        episode_map(replace(key, obstacle_density=0.2))
    with pytest.raises(EvaluationError, match="wide"):
        episode_map(replace(key, field_size=200.0))


def test_robustness_grid_uses_its_own_seeds():
    preset = PRESETS["robustness"]
    assert preset.densities == (0.1, 0.2, 0.3, 0.4, 0.5, 0.6) and preset.seeds >= 50
    assert (preset.field_sizes, preset.n_nodes, preset.localize) == ((100.0,), (100,), False)
    jobs = episode_jobs(preset, ["spiral", "scan"], (NO_LOCALIZER,))
    assert len(jobs) == 2 * 6 * preset.seeds
    spiral = [j.key for j in jobs if j.key.method == "spiral"]
    assert len({k.seed for k in spiral}) == len({k.map for k in spiral}) == len(spiral)
    assert {(k.map, k.seed) for k in spiral} == {(j.key.map, j.key.seed) for j in jobs
                                                 if j.key.method == "scan"}
    assert all(k.map.startswith(GENERATED_PREFIX) for k in spiral)
    assert spiral[0].seed == robustness_seed(0.1, 0) == ROBUSTNESS_EPISODE_SEED_BASE + 10_000
    others = {j.key.seed for name, p in PRESETS.items() if p.maps != "generated"
              for j in episode_jobs(p, ["spiral"], ("dvhop",))}
    assert not others & {k.seed for k in spiral}
    with pytest.raises(EvaluationError, match="at most 1000 seeds"):
        episode_jobs(preset, ["spiral"], (NO_LOCALIZER,), seeds=1001)


def test_an_unlocalized_episode_has_one_row_with_empty_localization(small_key):
    (row,) = run_episode(small_key("spiral"), (NO_LOCALIZER,), OPTIONS)
    assert row["localizer"] == NO_LOCALIZER and row["rmse"] is None
    assert row["localize_seconds"] == 0.0 and 0.0 <= row["coverage"] <= 1.0
