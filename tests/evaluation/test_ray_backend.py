"""The Ray backend on a local Ray instance (2 CPUs): the rows of the local backend, resume,
retries of failed tasks and their report, training seeds as Ray tasks."""

import os
from dataclasses import replace
from pathlib import Path

import pytest
import yaml

ray = pytest.importorskip("ray", reason="the Ray backend needs the extra: pip install -e '.[ray]'")

from agents.seeds import seed_runs, train_seeds  # noqa: E402
from agents.training import TrainRun  # noqa: E402
from aoass_env.backends import RayBackend  # noqa: E402
from aoass_env.evaluation import cli  # noqa: E402
from aoass_env.evaluation.methods import RunOptions  # noqa: E402
from aoass_env.evaluation.store import EpisodeStore, comparable_lines  # noqa: E402
from aoass_env.evaluation.sweep import Job, run_jobs  # noqa: E402

SWEEP = ["--preset", "smoke", "--methods", "spiral,scan", "--localizers", "dvhop", "--seeds",
         "2", "--no-progress"]


@pytest.fixture(scope="module")
def local_sweep(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The sweep on the local backend (2 processes), before Ray starts in this process."""
    out = tmp_path_factory.mktemp("local")
    assert cli.main([*SWEEP, "--workers", "2", "--out", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def ray_instance(local_sweep: Path):
    """A local Ray instance of 2 CPUs for this module."""
    ray.init(address="local", num_cpus=2, include_dashboard=False)
    yield
    ray.shutdown()


def test_ray_sweep_writes_the_rows_of_the_local_backend_and_resumes(local_sweep, ray_instance,
                                                                    tmp_path):
    argv = [*SWEEP, "--backend", "ray", "--out", str(tmp_path)]
    assert cli.main(argv) == 0
    lines = comparable_lines(tmp_path / "episodes.csv")   # all columns but the 2 timings
    assert len(lines) == 1 + 4                              # header, 2 methods x 2 seeds
    assert lines == comparable_lines(local_sweep / "episodes.csv")
    assert "on Ray (2 CPU(s) on 1 node(s))" in (tmp_path / "summary.md").read_text()
    before = (tmp_path / "episodes.csv").read_text()
    assert cli.main(argv) == 0                              # resume: nothing left to run
    assert (tmp_path / "episodes.csv").read_text() == before
    assert "0 episode(s) finished, 4 already in" in (tmp_path / "summary.md").read_text()


class CountingRayBackend(RayBackend):
    """A Ray backend whose tasks first append the job's method to ``counter``: the attempts,
    counted across worker processes."""

    def __init__(self, counter: Path, **kwargs) -> None:
        super().__init__(**kwargs)
        self.counter = counter

    def run(self, fn, items):
        counter = self.counter

        def counted(job):            # a local function: shipped to the workers by value
            with counter.open("a") as f:
                f.write(f"{job.key.method}\n")
            return fn(job)

        return super().run(counted, items)


def test_a_task_that_raises_is_retried_then_reported_with_its_key(ray_instance, small_key,
                                                                  tmp_path):
    bad = Job(replace(small_key("spiral"), map=str(tmp_path / "missing.txt")), ("dvhop",))
    good = Job(small_key("scan"), ("dvhop",))
    counter = tmp_path / "attempts.txt"
    with EpisodeStore(tmp_path / "episodes.csv") as store:
        report = run_jobs([bad, good], store, backend=CountingRayBackend(counter, retries=2),
                          options=RunOptions(max_steps=80), progress=False)
        assert [r["method"] for r in store.rows] == ["scan"]
    assert sorted(counter.read_text().split()) == ["scan", "spiral", "spiral", "spiral"]
    assert report.finished == 1 and len(report.failed) == 1
    key, error = report.failed[0]
    assert key == bad.key
    assert "after 3 attempt(s)" in error and "MapError" in error and "missing.txt" in error


def test_a_dead_worker_is_retried_then_reported(ray_instance, tmp_path):
    counter = tmp_path / "attempts.txt"

    def work(item: str) -> str:
        with counter.open("a") as f:
            f.write(f"{item}\n")
        if item == "die":
            os._exit(1)              # the worker process dies mid-task
        return item.upper()

    results = sorted(RayBackend(retries=1).run(work, ["ok", "die"]), key=lambda r: r[0])
    assert results[1] == ("ok", "OK", None)
    item, value, error = results[0]
    assert (item, value) == ("die", None)
    assert "after 2 attempt(s)" in error and "died" in error
    assert sorted(counter.read_text().split()) == ["die", "die", "ok"]


def test_training_seeds_run_as_ray_tasks(ray_instance, tmp_path):
    config = tmp_path / "tiny.yml"
    config.write_text(yaml.safe_dump({"td3": {
        "learning_starts": 100, "buffer_size": 500, "policy_kwargs": {"net_arch": [4]},
        "env": {"densities": [0.1, 0.1], "n_nodes": 20, "time_limit_factor": 1.0},
        "eval": {"freq": 1000, "episodes": 1}, "checkpoint_freq": 1000}}))
    run = TrainRun(algo="td3", timesteps=10, config=config, out=tmp_path / "runs",
                   log_dir=tmp_path / "tb", progress_bar=False)
    results = train_seeds(seed_runs(run, [0, 1]), RayBackend(retries=0))
    assert sorted((r.seed, final, error) for r, final, error in results) == [
        (s, tmp_path / "runs" / f"seed{s}" / "final.zip", None) for s in (0, 1)]
    assert all(final.is_file() for _, final, _ in results)
    assert sorted(p.name for p in (tmp_path / "tb").iterdir()) == ["td3_seed0_1", "td3_seed1_1"]
