"""evaluate.py end to end on the smoke preset, --logs mode, and its usage errors (exit 2)."""

import csv
import json
import math
import shutil
import sys
import zipfile
from dataclasses import replace

import numpy as np
import pytest
import yaml

from aoass_env.config import AOASSConfig
from aoass_env.evaluation import cli, methods
from aoass_env.evaluation.methods import DEFAULT_POLICY, METHODS, POLICY_COMMAND
from aoass_env.evaluation.store import (
    BLAS_KERNELS,
    COLUMNS,
    NO_LOCALIZER,
    EpisodeStore,
    blas_kernels,
    comparable_lines,
    config_input,
    read_episodes,
    read_runs,
)
from aoass_env.evaluation.sweep import PRESETS, robustness_seed
from aoass_env.localization import METHODS as LOCALIZERS
from aoass_env.planning import AdaptiveConfig


def _usage_error(capsys, argv: list[str]) -> str:
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    assert exc.value.code == 2
    return capsys.readouterr().err


@pytest.fixture(scope="module")
def smoke_run(tmp_path_factory):
    """The smoke preset for the spiral, DV-Hop only, logs saved: (out folder, exit status)."""
    out = tmp_path_factory.mktemp("smoke")
    status = cli.main(["--preset", "smoke", "--methods", "spiral", "--localizers", "dvhop",
                       "--workers", "1", "--out", str(out), "--save-logs", "--no-progress"])
    return out, status


def test_smoke_preset_writes_csvs_table_and_logs(smoke_run, capsys):
    out, status = smoke_run
    assert status == 0
    with (out / "episodes.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 1 and tuple(rows[0]) == COLUMNS
    row = rows[0]
    assert (row["method"], row["map"], row["n_nodes"], row["localizer"]) == (
        "spiral", "test/d0.10_f100_s500", "60", "dvhop")
    assert 0.9 <= float(row["coverage"]) <= 1.0
    assert float(row["localized"]) == pytest.approx(float(row["coverage"]))
    assert row["safety_intervention"] == ""
    with (out / "summary.csv").open() as f:
        summary = list(csv.DictReader(f))
    assert summary[0]["n"] == "1" and float(summary[0]["rmse_mean"]) == float(row["rmse"])
    assert "Square spiral" in (out / "summary.md").read_text()
    assert len(list((out / "logs" / "spiral").glob("*.npz"))) == 1
    [run] = read_runs(out)
    assert (run["preset"], run["seeds"], run["finished"], run["skipped"], run["failed"]) == (
        "smoke", 1, 1, 0, 0)
    assert 0 < run["wall_seconds"] < 600


def test_save_logs_refuses_finished_episodes_without_their_logs(smoke_run, tmp_path, capsys):
    """Episodes already in episodes.csv are not played again: --save-logs used to exit 0
    without their logs, saying nothing."""
    out, _ = smoke_run
    argv = ["--preset", "smoke", "--methods", "spiral", "--localizers", "dvhop", "--workers",
            "1", "--save-logs", "--no-progress"]
    full = tmp_path / "full"
    shutil.copytree(out, full)
    assert cli.main([*argv, "--out", str(full)]) == 0           # every log there: all skipped
    # what a killed run's atomic writes leave is removed (it used to pile up)
    stale = [full / ".summary.md.0123abcd.tmp", full / "logs" / "spiral" / ".x.npz.4567ef.tmp"]
    for path in stale:
        path.write_bytes(b"half")
    assert cli.main([*argv, "--out", str(full)]) == 0
    assert not any(path.exists() for path in stale)
    assert f"removed {stale[1]}, left by an interrupted write" in capsys.readouterr().err
    bare = tmp_path / "bare"
    shutil.copytree(out, bare, ignore=shutil.ignore_patterns("logs"))
    err = _usage_error(capsys, [*argv, "--out", str(bare)])
    assert (f"--save-logs: 1 episode(s) are already in {bare / 'episodes.csv'} without a saved "
            f"log (e.g. {bare / 'logs' / 'spiral'}") in err
    assert not (bare / "logs").exists()


def test_the_tables_do_not_depend_on_the_order_episodes_finished_in(smoke_run, tmp_path):
    """The summaries and figures read the rows in file order, which is the order the episodes
    finished in (workers, resumes): their means are sums in that order and the bootstrap
    resamples rows by position, so --workers 2 printed other last digits and other figures."""
    out, _ = smoke_run
    base = read_episodes(out / "episodes.csv")[0]
    # RMSEs whose mean in file order depends on the order (checked here, so that the test
    # has teeth): summed forward and backward they round differently
    rng = np.random.default_rng(551060)
    while True:
        values = np.round(rng.uniform(0.1, 3.0, 4), 2).tolist()
        if (np.mean([base["rmse"], *values]) != np.mean([base["rmse"], *values[::-1]])):
            break
    extra = [{**base, "seed": 101 + k, "rmse": v} for k, v in enumerate(values)]
    outputs = []
    for order in (extra, extra[::-1]):
        folder = tmp_path / f"order{len(outputs)}"
        shutil.copytree(out, folder, ignore=shutil.ignore_patterns("logs"))
        with EpisodeStore(folder / "episodes.csv") as store:
            store.append(order)
        assert cli.main(["--preset", "smoke", "--methods", "spiral", "--localizers", "dvhop",
                         "--workers", "1", "--out", str(folder), "--no-progress"]) == 0
        outputs.append([(folder / name).read_bytes() for name in ("summary.csv", "summary.md")])
    assert outputs[0] == outputs[1]


def test_logs_mode_localizes_saved_logs(smoke_run, tmp_path):
    out, _ = smoke_run
    assert cli.main(["--logs", str(out / "logs"), "--localizers", "dvhop", "consensus",
                     "--out", str(tmp_path), "--workers", "1", "--no-progress"]) == 0
    original = read_episodes(out / "episodes.csv")[0]
    rows = read_episodes(tmp_path / "episodes.csv")
    assert [r["localizer"] for r in rows] == ["dvhop", "consensus"]
    for name in ("method", "map", "seed", "coverage", "eta_traj", "energy_total"):
        assert rows[0][name] == original[name]           # the episode part, from the log
    assert rows[0]["rmse"] == pytest.approx(original["rmse"])
    assert math.isfinite(rows[1]["rmse"])


@pytest.mark.parametrize("argv, valid", [
    (["--methods", "spiral,nope"], list(METHODS)),
    (["--preset", "huge"], list(PRESETS)),
    (["--localizers", "trilateration"], list(LOCALIZERS)),
])
def test_unknown_names_list_the_valid_ones(capsys, tmp_path, argv, valid):
    err = _usage_error(capsys, [*argv, "--out", str(tmp_path / "out")])
    assert all(name in err for name in valid)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("argv", [
    ["--methods", "spiral", "aoass-adaptive", "--policy", "any.zip"],
    ["--methods", "aoass-rule", "--policy", "any.zip"],
    ["--methods", "spiral", "--policy-run", "any.yml"],
    ["--logs", "any", "--policy", "any.zip"],
])
def test_a_policy_that_no_method_runs_is_refused(capsys, tmp_path, argv):
    """--policy and --policy-run without a method that runs the policy (or with --logs) used
    to be ignored: the run went ahead without the policy the user named."""
    err = _usage_error(capsys, [*argv, "--out", str(tmp_path / "out")])
    last = err.strip().splitlines()[-1]
    assert last.startswith("evaluate.py: error: ") and "--policy and --policy-run" in last
    assert not (tmp_path / "out").exists()


def test_missing_policy_checkpoint_names_file_and_command(capsys, tmp_path):
    missing = tmp_path / "none.zip"
    err = _usage_error(capsys, ["--methods", "aoass", "--policy", str(missing),
                                "--out", str(tmp_path / "out")])
    assert str(missing) in err and POLICY_COMMAND in err
    assert not (tmp_path / "out").exists()


def test_a_bad_run_record_is_named_by_its_own_flag(capsys, tmp_path):
    # "--policy: .../bad.yml: ..." named the flag of the policy, not of the record at fault
    bad = tmp_path / "bad.yml"
    bad.write_text("a: 1\n")
    err = _usage_error(capsys, ["--methods", "aoass", "--policy-run", str(bad),
                                "--out", str(tmp_path / "out")])
    assert err.strip().splitlines()[-1].startswith(f"evaluate.py: error: --policy-run: {bad}")


def test_a_methods_own_checkpoint_is_loaded_before_any_episode(capsys, tmp_path, monkeypatch):
    """The adaptive policy's checkpoint was first read by each episode: a damaged one failed
    every episode with its own traceback (exit 1) instead of one error before any work."""
    junk = tmp_path / "adaptive" / "best.zip"
    junk.parent.mkdir()
    junk.write_bytes(b"not a zip")
    shutil.copy(methods.ADAPTIVE_POLICY.with_name("run.yml"), junk.with_name("run.yml"))
    monkeypatch.setitem(methods.METHODS, "aoass-adaptive",
                        replace(methods.METHODS["aoass-adaptive"], checkpoint=junk))
    err = _usage_error(capsys, ["--preset", "smoke", "--methods", "aoass-adaptive",
                                "--out", str(tmp_path / "out")])
    assert err.strip().splitlines()[-1].startswith(
        f"evaluate.py: error: method aoass-adaptive: its checkpoint: {junk}")
    assert not (tmp_path / "out" / "episodes.csv").exists()


def test_a_resume_with_other_blas_kernels_is_refused(smoke_run, capsys, tmp_path):
    """The episodes depend on the BLAS kernels' summation order (docs/evaluation.md): a folder
    records this machine's kernels, and a resume where OpenBLAS picked others (another CPU, or
    OPENBLAS_CORETYPE) would have mixed two kernels' episodes in one table unseen."""
    out, _ = smoke_run
    assert json.loads((out / "inputs.json").read_text())[BLAS_KERNELS] == blas_kernels()
    folder = tmp_path / "blas"
    shutil.copytree(out, folder, ignore=shutil.ignore_patterns("logs"))
    inputs = folder / "inputs.json"
    inputs.write_text(json.dumps({**json.loads(inputs.read_text()),
                                  BLAS_KERNELS: "openblas Prescott"}))
    before = (folder / "episodes.csv").read_bytes()
    argv = ["--preset", "smoke", "--methods", "spiral", "--localizers", "dvhop", "--workers",
            "1", "--out", str(folder), "--no-progress"]
    err = _usage_error(capsys, argv)
    assert "episodes of spiral produced with other BLAS kernels than this run's" in err
    assert (folder / "episodes.csv").read_bytes() == before
    assert cli.main([*argv, "--discard-changed"]) == 0          # run again, here
    assert json.loads(inputs.read_text())[BLAS_KERNELS] == blas_kernels()
    assert len(read_episodes(folder / "episodes.csv")) == 1


def test_a_refused_save_logs_run_drops_no_row(smoke_run, capsys, tmp_path):
    """--save-logs --discard-changed refused the run (finished episodes without logs) after it
    had dropped the changed method's rows and rewritten inputs.json."""
    out, _ = smoke_run
    folder = tmp_path / "sl"
    shutil.copytree(out, folder, ignore=shutil.ignore_patterns("logs"))
    base = read_episodes(folder / "episodes.csv")[0]
    with EpisodeStore(folder / "episodes.csv") as store:
        store.append([{**base, "method": "scan"}])
    inputs = folder / "inputs.json"
    record = json.loads(inputs.read_text())
    record[config_input("spiral")] = "0" * 64                     # spiral's defaults changed
    record[config_input("scan")] = METHODS["scan"].defaults_digest  # scan's as they are
    inputs.write_text(json.dumps(record))
    before = [(folder / name).read_bytes() for name in ("episodes.csv", "inputs.json")]
    err = _usage_error(capsys, ["--preset", "smoke", "--methods", "spiral", "scan",
                                "--localizers", "dvhop", "--save-logs", "--discard-changed",
                                "--out", str(folder), "--no-progress"])
    assert "--save-logs: 1 episode(s) are already in" in err
    assert [(folder / name).read_bytes() for name in ("episodes.csv", "inputs.json")] == before


def _policy_copy(folder, *, stored: bool = False):
    """A copy of the shipped policy with its run.yml in ``folder`` (re-zipped uncompressed when
    ``stored``: the same model in a file of another digest)."""
    folder.mkdir()
    shutil.copy(DEFAULT_POLICY.with_name("run.yml"), folder / "run.yml")
    with zipfile.ZipFile(DEFAULT_POLICY) as src, zipfile.ZipFile(
            folder / "policy.zip", "w",
            zipfile.ZIP_STORED if stored else zipfile.ZIP_DEFLATED) as dst:
        for name in src.namelist():
            dst.writestr(name, src.read(name))
    return folder / "policy.zip"


def test_resuming_with_another_policy_fails_before_any_work(smoke_run, capsys, tmp_path,
                                                              monkeypatch):
    out, _ = smoke_run
    for name in ("episodes.csv", "inputs.json"):     # the spiral's rows and their record
        shutil.copy(out / name, tmp_path / name)
    first = _policy_copy(tmp_path / "first")
    second = _policy_copy(tmp_path / "second", stored=True)
    argv = ["--preset", "smoke", "--methods", "aoass", "--localizers", "dvhop",
            "--out", str(tmp_path), "--no-progress"]

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    # records first.zip's digest before any episode (the run is then cut short)
    monkeypatch.setattr(cli, "run_jobs", interrupted)
    assert cli.main([*argv, "--policy", str(first)]) == 130
    # the folder holds no aoass episode yet: another policy has nothing to mix with
    assert cli.main([*argv, "--policy", str(second)]) == 130
    assert cli.main([*argv, "--policy", str(first)]) == 130
    capsys.readouterr()
    # aoass episodes made with first.zip (the spiral's rows, relabelled)
    text = (tmp_path / "episodes.csv").read_text()
    (tmp_path / "episodes.csv").write_text(text.replace("\nspiral,", "\naoass,"))
    before = (tmp_path / "episodes.csv").read_text()
    assert before != text
    err = _usage_error(capsys, [*argv, "--policy", str(second)])
    assert "another policy checkpoint" in err and str(tmp_path / "episodes.csv") in err
    assert (tmp_path / "episodes.csv").read_text() == before


def test_an_interrupted_run_records_its_finished_episodes_and_time(smoke_run, tmp_path,
                                                                      monkeypatch, capsys):
    out, _ = smoke_run
    for name in ("episodes.csv", "inputs.json"):
        shutil.copy(out / name, tmp_path / name)
    [first, *_] = read_episodes(out / "episodes.csv")

    def one_then_interrupted(jobs, store, **kwargs):
        store.append([{**first, "seed": 12345}])       # one episode finishes, then Ctrl-C
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "run_jobs", one_then_interrupted)
    assert cli.main(["--preset", "smoke", "--methods", "spiral", "--localizers",
                     first["localizer"], "--out", str(tmp_path), "--no-progress"]) == 130
    capsys.readouterr()
    # it used to write no line: the page's wall time left the run out
    run = read_runs(tmp_path)[-1]
    assert run["interrupted"] is True and run["finished"] == 1 and run["wall_seconds"] >= 0
    assert run["preset"] == "smoke"


def test_resuming_with_other_config_defaults_is_refused_for_the_methods_built_on_them(
        smoke_run, monkeypatch, capsys, tmp_path):
    """A default tuned since the rows were made: resuming would mix two settings for the
    methods built on that config, and --discard-changed runs their episodes again."""
    out, _ = smoke_run
    for name in ("episodes.csv", "inputs.json"):
        shutil.copy(out / name, tmp_path / name)
    spec = METHODS["spiral"]
    assert spec.defaults_digest == methods.config_defaults_digest((AOASSConfig,))
    assert METHODS["aoass-rule"].defaults_digest != spec.defaults_digest
    assert AdaptiveConfig not in spec.configs and AdaptiveConfig in METHODS["aoass-rule"].configs
    argv = ["--preset", "smoke", "--methods", "spiral", "--localizers", "dvhop",
            "--out", str(tmp_path), "--no-progress"]
    before = (tmp_path / "episodes.csv").read_text()

    def tuned_rule() -> AdaptiveConfig:
        return AdaptiveConfig(dense_above=AdaptiveConfig().dense_above / 2)

    tuned_rule.__name__ = "AdaptiveConfig"
    monkeypatch.setitem(METHODS, "aoass-rule",
                        replace(METHODS["aoass-rule"], configs=(AOASSConfig, tuned_rule)))
    assert cli.main(argv) == 0                     # the rule's defaults: not the spiral's
    assert (tmp_path / "episodes.csv").read_text() == before

    def tuned() -> AOASSConfig:
        return AOASSConfig(edge_margin=AOASSConfig().edge_margin / 2)

    tuned.__name__ = "AOASSConfig"
    monkeypatch.setitem(METHODS, "spiral", replace(spec, configs=(tuned,)))
    err = _usage_error(capsys, argv)
    assert "episodes of spiral produced with other config defaults of spiral than" in err
    assert "--discard-changed" in err
    assert (tmp_path / "episodes.csv").read_text() == before
    assert cli.main([*argv, "--discard-changed", "--workers", "1"]) == 0
    # the same episodes again (the tuned default never reached them)
    assert comparable_lines(tmp_path / "episodes.csv") == comparable_lines(out / "episodes.csv")
    assert (tmp_path / "episodes.csv").read_text() != before       # timings are new


def test_the_zero_action_ablations_rows_are_tied_to_the_stack_they_played_in(capsys, tmp_path):
    """aoass-scripted plays in the stack of --policy's run record, aoass-rule in the shipped
    adaptive policy's: a record whose safety filter differs used to leave their old rows in
    place (nothing recorded what they were played in), two stacks in one table; and --policy
    with aoass-scripted alone was refused as if it did not read it."""
    folder = tmp_path / "policy"
    folder.mkdir()
    shutil.copy(DEFAULT_POLICY, folder / "best.zip")
    record = yaml.safe_load(DEFAULT_POLICY.with_name("run.yml").read_text())
    (folder / "run.yml").write_text(yaml.safe_dump(record))
    out = tmp_path / "out"
    argv = ["--preset", "smoke", "--methods", "aoass-scripted", "--localizers", "none",
            "--workers", "1", "--out", str(out), "--no-progress", "--policy",
            str(folder / "best.zip")]
    assert cli.main(argv) == 0
    inputs = json.loads((out / "inputs.json").read_text())
    assert "aoass-scripted stack" in inputs and "policy" not in inputs   # no weights read
    before = (out / "episodes.csv").read_text()
    record["hyperparameters"]["env"]["safety"] = {"margin": 1.5}
    (folder / "run.yml").write_text(yaml.safe_dump(record))
    err = _usage_error(capsys, argv)
    assert ("episodes of aoass-scripted produced with another aoass-scripted stack (the "
            "tracker, safety filter or action type of its run record)") in err
    assert (out / "episodes.csv").read_text() == before
    assert cli.main([*argv, "--discard-changed"]) == 0
    assert json.loads((out / "inputs.json").read_text())["aoass-scripted stack"] != \
        inputs["aoass-scripted stack"]
    # the rule's stack is the adaptive policy's record, read the same way
    shipped = methods.RunOptions()
    assert methods.zero_action_stack("aoass-rule", shipped) == {"action_type": "adaptive"}
    adaptive = tmp_path / "adaptive"
    adaptive.mkdir()
    shutil.copy(methods.ADAPTIVE_POLICY, adaptive / "best.zip")
    other = yaml.safe_load(methods.ADAPTIVE_POLICY.with_name("run.yml").read_text())
    other["hyperparameters"]["env"]["tracker"] = {"gate": 0.95}
    (adaptive / "run.yml").write_text(yaml.safe_dump(other))
    moved = replace(shipped, adaptive_policy=str(adaptive / "best.zip"))
    assert methods.zero_action_stack("aoass-rule", moved)["tracker"] == {"gate": 0.95}
    assert (methods.zero_action_stack_digest("aoass-rule", moved)
            != methods.zero_action_stack_digest("aoass-rule", shipped))


def test_unwritable_output_folder_fails_before_any_work(capsys, tmp_path):
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    err = _usage_error(capsys, ["--preset", "smoke", "--out", str(blocker / "out")])
    assert "cannot write the output folder" in err and str(blocker) in err


@pytest.mark.parametrize("argv, message", [
    (["--seeds", "0"], "--seeds must be in [1, 10000]"),
    (["--workers", "0"], "--workers must be at least 1"),
    (["--logs", "/nonexistent-folder"], "no such folder"),
    (["--logs", ".", "--seeds", "2"], "do not apply"),
    (["--logs", ".", "--preset", "robustness"],                  # it was ignored, exit 0
     "--logs localizes every log in its folder; --preset, --methods"),
    (["--address", "auto"], "--address names a Ray cluster; it needs --backend ray"),
])
def test_bad_values_are_usage_errors(capsys, tmp_path, argv, message):
    assert message in _usage_error(capsys, [*argv, "--out", str(tmp_path)])


def test_a_file_that_is_no_beacon_log_is_a_usage_error(capsys, tmp_path):
    (tmp_path / "logs").mkdir()
    (tmp_path / "logs" / "broken.npz").write_bytes(b"not a zip")
    err = _usage_error(capsys, ["--logs", str(tmp_path / "logs"), "--out", str(tmp_path)])
    assert "broken.npz" in err and "not an .npz archive" in err


def test_a_ray_address_that_is_no_address_names_the_flag(capsys, tmp_path, monkeypatch):
    """Ray's own ValueError ('Invalid address format: foo') ended in a traceback."""
    ray = pytest.importorskip("ray", reason="the Ray backend needs the extra")
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    err = _usage_error(capsys, ["--preset", "smoke", "--methods", "spiral", "--backend", "ray",
                                "--address", "foo", "--out", str(tmp_path / "out")])
    assert err.strip().splitlines()[-1] == (
        "evaluate.py: error: --address 'foo' (or $RAY_ADDRESS) is not a Ray cluster address "
        "(Invalid address format: foo): give 'auto' or HOST:PORT")
    assert not ray.is_initialized() and not (tmp_path / "out").exists()


def test_backend_ray_without_ray_says_how_to_install(capsys, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)           # `import ray` fails
    err = _usage_error(capsys, ["--preset", "smoke", "--methods", "spiral", "--backend", "ray",
                                "--out", str(tmp_path / "out")])
    assert "--backend ray needs Ray: pip install -e '.[ray]'" in err
    assert not (tmp_path / "out").exists()


def test_robustness_preset_runs_unlocalized_on_generated_maps(monkeypatch, capsys, tmp_path):
    """A one-density, 30-node version of the preset: one row per episode (localizer none), the
    robustness tables in summary.md, and a rerun that skips the finished episode."""
    small = replace(PRESETS["robustness"], densities=(0.1,), n_nodes=(30,))
    monkeypatch.setitem(PRESETS, "robustness", small)
    argv = ["--preset", "robustness", "--seeds", "1", "--methods", "spiral", "--workers", "1",
            "--out", str(tmp_path), "--no-progress"]
    assert cli.main(argv) == 0
    [row] = read_episodes(tmp_path / "episodes.csv")
    assert (row["method"], row["map"], row["seed"], row["localizer"]) == (
        "spiral", "generated/d0.10_f100_r0", robustness_seed(0.1, 0), NO_LOCALIZER)
    assert math.isnan(row["rmse"]) and 0.0 < row["coverage"] <= 1.0
    summary = (tmp_path / "summary.md").read_text()
    assert "## Robustness by obstacle density" in summary and "20261117" in summary
    assert f"| Square spiral | {row['path_complete']:.0%} | {row['coverage']:.1%} |" in summary
    assert cli.main(argv) == 0
    assert read_runs(tmp_path)[-1]["skipped"] == 1
    capsys.readouterr()
    err = _usage_error(capsys, [*argv, "--localizers", "none", "dvhop"])
    assert "does not go with other localizers" in err
