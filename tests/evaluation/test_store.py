"""episodes.csv: schema, appending, a half-written last line, other schemas, bad folders."""

import json
import math
import os

import pytest

from aoass_env.evaluation.store import (
    BLAS_KERNELS,
    COLUMNS,
    CONFIG_DEFAULTS,
    INPUTS_FILE,
    RUNS_FILE,
    TIMING_FIELDS,
    EpisodeKey,
    EpisodeStore,
    EvaluationError,
    apply_inputs,
    blas_kernels,
    comparable_lines,
    config_input,
    file_digest,
    read_episodes,
    read_runs,
    record_run,
    stale_rows,
)


def check_inputs(store, inputs, scope=None, discard=False, localizers=None):
    """What evaluate.py does with a folder's inputs: decide the stale rows (refusing without
    ``discard``), then drop them and record the inputs."""
    apply_inputs(store, inputs, stale_rows(store, inputs, scope, discard, localizers))


def row(seed: int = 0, localizer: str = "dvhop", **values) -> dict:
    base = {name: 1.0 for name in COLUMNS}
    base.update(method="spiral", map="test/d0.10_f100_s500", field_size=100.0, n_nodes=100,
                obstacle_density=0.1, seed=seed, localizer=localizer, beacons=5, collisions=0,
                collisions_static=0, collisions_moving=0, path_complete=1,
                safety_intervention=None)
    base.update(values)
    return base


def test_schema_holds_the_design_columns_key_first():
    design = ("method", "field_size", "n_nodes", "obstacle_density", "seed", "localizer",
              "rmse", "coverage", "eer", "energy_total", "path_length", "travel_time",
              "eta_traj", "collisions")
    assert set(design) <= set(COLUMNS)
    assert COLUMNS[:7] == ("method", "map", "field_size", "n_nodes", "obstacle_density", "seed",
                           "localizer")
    assert len(set(COLUMNS)) == len(COLUMNS)


def test_rows_round_trip_with_types_and_empty_cells(tmp_path):
    path = tmp_path / "out" / "episodes.csv"
    with EpisodeStore(path) as store:
        assert store.rows == [] and path.read_text() == ",".join(COLUMNS) + "\n"
        store.append([row(rmse=math.nan), row(localizer="olstm-dvhop", rmse=0.25)])
    lines = path.read_text().splitlines()
    assert len(lines) == 3 and ",,"in lines[1]               # NaN and None are empty cells
    back = read_episodes(path)
    assert [r["localizer"] for r in back] == ["dvhop", "olstm-dvhop"]
    assert math.isnan(back[0]["rmse"]) and back[1]["rmse"] == 0.25
    assert math.isnan(back[0]["safety_intervention"])
    assert back[0]["n_nodes"] == 100 and isinstance(back[0]["beacons"], int)
    again = EpisodeStore(path)
    key = EpisodeKey("spiral", "test/d0.10_f100_s500", 100.0, 100, 0.1, 0)
    assert again.done == {(key, "dvhop"), (key, "olstm-dvhop")}
    again.close()


def test_a_half_written_last_line_is_dropped_with_a_warning(tmp_path):
    path = tmp_path / "episodes.csv"
    with EpisodeStore(path) as store:
        store.append([row(seed=0), row(seed=1)])
    text = path.read_text()
    path.write_text(text + "spiral,test/d0.10_f100_s500,100.0,10")    # a crash mid-write
    with pytest.warns(UserWarning, match="half-written last line"):
        store = EpisodeStore(path)
    assert len(store.rows) == 2 and path.read_text() == text       # removed from the file
    store.append([row(seed=2)])
    store.close()
    assert [r["seed"] for r in read_episodes(path)] == [0, 1, 2]


def test_a_broken_row_inside_the_file_is_an_error(tmp_path):
    path = tmp_path / "episodes.csv"
    with EpisodeStore(path) as store:
        store.append([row(seed=0)])
    path.write_text(path.read_text() + "spiral,x\n" + path.read_text().splitlines()[1] + "\n")
    with pytest.raises(EvaluationError, match="line 3: broken row"):
        EpisodeStore(path)


BROKEN_VALUES = [
    ({"energy_total": -784.0}, r"energy_total='-784.0' must be a finite number >= 0"),
    ({"coverage": 5.0}, r"coverage='5.0' must be a finite number in \[0, 1\]"),
    ({"localized": 1.5}, r"localized='1.5' must be a finite number in \[0, 1\]"),
    ({"seed": -3}, r"seed='-3' must be a finite number >= -1"),
    ({"n_nodes": 0}, r"n_nodes='0' must be a finite number >= 1"),
    ({"path_complete": 2}, r"path_complete='2' must be a finite number in \[0, 1\]"),
    ({"obstacle_density": 1.2}, r"obstacle_density='1.2' must be a finite number in \[0, 1\]"),
    ({"path_length": math.inf}, r"path_length='inf' must be a finite number >= 0"),
    ({"rmse": "nan"}, r"rmse='nan' must be a finite number >= 0"),
    ({"e_norm": -1.0}, r"e_norm='-1.0' must be a number >= 0"),
    ({"method": ""}, "method is empty"),
    # a hand-edited name made a column of its own in summary.md
    ({"localizer": "dvhopX"}, "localizer='dvhopX' is not one of dvhop, consensus, olstm-dvhop, "
                              "none"),
]


@pytest.mark.parametrize(("values", "message"), BROKEN_VALUES)
def test_a_value_no_episode_writes_is_a_broken_row(tmp_path, values, message):
    """A row outside its column's range (hand-edited or another tool's) used to reach the
    tables: a negative energy was averaged in, a coverage of 5 printed as 500 %."""
    path = tmp_path / "episodes.csv"
    with EpisodeStore(path) as store:
        store.append([row(seed=0)])
    bad = tmp_path / "bad.csv"
    cells = {**row(seed=1), **values}
    bad.write_text(path.read_text().splitlines()[0] + "\n" + ",".join(
        "" if cells[name] is None else str(cells[name]) for name in COLUMNS) + "\n")
    with pytest.raises(EvaluationError, match=rf"line 2: broken row \({message}\)"):
        read_episodes(bad)


@pytest.mark.parametrize(("values", "message"), BROKEN_VALUES)
def test_a_row_the_file_could_not_read_back_is_not_appended(tmp_path, values, message):
    """append wrote any row: one outside its column's range made the whole file unreadable
    (every later read and resume failed on its line). It is refused, naming the column, and
    nothing of the episode is written."""
    path = tmp_path / "episodes.csv"
    with EpisodeStore(path) as store:
        store.append([row(seed=0)])
        before = path.read_text()
        with pytest.raises(ValueError, match=message):
            store.append([row(seed=1, localizer="consensus"), {**row(seed=1), **values}])
        assert path.read_text() == before and len(store.rows) == 1
    assert len(read_episodes(path)) == 1


def test_an_episode_stored_already_is_not_appended_again(tmp_path):
    """A second row of one (episode, localizer) made the file unreadable ("repeats the
    episode"); append refuses it, in the file or within the rows given, and writes nothing."""
    path = tmp_path / "episodes.csv"
    with EpisodeStore(path) as store:
        store.append([row(seed=0)])
        for rows in ([row(seed=0)], [row(seed=1), row(seed=1)]):
            with pytest.raises(ValueError, match="holds the episode .* with localizer 'dvhop' "
                                                 "already"):
                store.append(rows)
        store.append([row(seed=1), row(seed=1, localizer="consensus")])
    assert len(read_episodes(path)) == 3


def test_infinite_energy_ratios_and_empty_cells_read_back(tmp_path):
    """E_norm is inf without beacons and EER inf without energy; empty cells are NaN."""
    path = tmp_path / "episodes.csv"
    with EpisodeStore(path) as store:
        store.append([row(seed=0, e_norm=math.inf, eer=math.inf, beacons=0, rmse=None)])
    back = read_episodes(path)[0]
    assert back["e_norm"] == back["eer"] == math.inf and math.isnan(back["rmse"])


def test_another_schema_is_an_error(tmp_path):
    path = tmp_path / "episodes.csv"
    path.write_text("method,map,rmse\nspiral,x,1.0\n")
    with pytest.raises(EvaluationError, match="other columns"):
        EpisodeStore(path)


def test_a_folder_that_cannot_be_created_is_an_error(tmp_path):
    (tmp_path / "file").write_text("")
    with pytest.raises(EvaluationError, match="cannot write the output folder"):
        EpisodeStore(tmp_path / "file" / "sub" / "episodes.csv")


def test_comparable_lines_leave_out_the_timings(tmp_path):
    path = tmp_path / "episodes.csv"
    path.write_text("method,localize_seconds,rmse,wall_seconds\nscan,0.5,\"1,5\",2.0\n")
    assert TIMING_FIELDS == ("localize_seconds", "wall_seconds")
    assert comparable_lines(path) == {"method,rmse\n", 'scan,"1,5"\n'}


def test_file_digest_follows_the_bytes_and_treats_a_missing_file_as_empty(tmp_path):
    a, b = tmp_path / "a.zip", tmp_path / "run.yml"
    a.write_bytes(b"weights")
    first = file_digest(a, b)
    assert file_digest(a, b) == first
    b.write_text("env: {}")
    assert file_digest(a, b) != first                  # the run record counts too
    a.write_bytes(b"weights!")
    assert file_digest(a) != file_digest(tmp_path / "missing.zip")


def test_resuming_with_another_checkpoint_is_refused_and_nothing_is_lost(tmp_path):
    with EpisodeStore(tmp_path / "episodes.csv") as store:
        check_inputs(store, {"policy": "aaa", "olstm-dvhop": "bbb"})
        store.append([row()])
    record = (tmp_path / INPUTS_FILE).read_text()
    csv_text = (tmp_path / "episodes.csv").read_text()
    with EpisodeStore(tmp_path / "episodes.csv") as store:
        check_inputs(store, {"policy": "aaa"})             # same policy: resumes
        check_inputs(store, {"olstm-dvhop": "bbb"})
        with pytest.raises(EvaluationError, match="another policy checkpoint") as exc:
            check_inputs(store, {"policy": "ccc", "olstm-dvhop": "bbb"})
    assert "episodes.csv" in str(exc.value) and "--out" in str(exc.value)
    assert (tmp_path / INPUTS_FILE).read_text() == record   # the record is kept as it was
    own = {"aoass-adaptive checkpoint": ["aoass-adaptive"]}
    with EpisodeStore(tmp_path / "episodes.csv") as store:  # a method's own checkpoint
        check_inputs(store, {"aoass-adaptive checkpoint": "ddd"}, own)   # no rows of it yet
        with pytest.raises(EvaluationError) as exc:
            check_inputs(store, {"aoass-adaptive checkpoint": "eee"})   # every row its scope
    assert "another aoass-adaptive checkpoint than this run's" in str(exc.value)
    with EpisodeStore(tmp_path / "episodes.csv") as store:  # defaults never recorded for rows
        with pytest.raises(EvaluationError) as exc:
            check_inputs(store, {config_input("spiral"): "ggg", "policy": "ccc"})
    assert ("episodes of spiral produced with other config defaults of spiral and another "
            "policy checkpoint than" in str(exc.value))
    assert (tmp_path / "episodes.csv").read_text() == csv_text


def test_changed_inputs_concern_the_methods_of_their_scope_whose_rows_can_be_discarded(
        tmp_path):
    path = tmp_path / "episodes.csv"
    scope = {config_input("spiral"): ["spiral"], config_input("aoass-rule"): ["aoass-rule"],
             "aoass-adaptive checkpoint": ["aoass-adaptive"]}
    inputs = {config_input("spiral"): "s1", config_input("aoass-rule"): "r1",
              "aoass-adaptive checkpoint": "c1"}
    with EpisodeStore(path) as store:
        check_inputs(store, inputs, scope)
        store.append([row(0)])
        store.append([row(0, method="aoass-rule"), row(0, "olstm-dvhop", method="aoass-rule")])
        store.append([row(1)])
    spiral_rows = [line for line in path.read_text().splitlines(keepends=True)
                   if line.startswith("spiral,")]
    tuned = {**inputs, config_input("aoass-rule"): "r2"}
    with EpisodeStore(path) as store:
        with pytest.raises(EvaluationError) as exc:
            check_inputs(store, tuned, scope)
        check_inputs(store, {**inputs, "aoass-adaptive checkpoint": "c2"}, scope)  # no rows
    assert ("episodes of aoass-rule produced with other config defaults of aoass-rule than"
            in str(exc.value) and "--discard-changed" in str(exc.value))
    assert len(path.read_text().splitlines()) == 5
    with EpisodeStore(path) as store:
        check_inputs(store, tuned, scope, discard=True)
        assert {r["method"] for r in store.rows} == {"spiral"} and len(store.done) == 2
        store.append([row(0, method="aoass-rule")])               # runs again
    lines = path.read_text().splitlines(keepends=True)
    assert lines[1:3] == spiral_rows and lines[3].startswith("aoass-rule,")
    assert json.loads((tmp_path / INPUTS_FILE).read_text())[config_input("aoass-rule")] == "r2"
    with EpisodeStore(path) as store:                            # resumes with the new digest
        check_inputs(store, tuned, scope)
        assert len(store.rows) == 3


def test_a_localizer_s_checkpoint_concerns_that_localizer_s_rows_alone(tmp_path):
    """The OLSTM checkpoint's digest used to count as an input of every row: a folder of
    dvhop and consensus rows was refused when olstm-dvhop joined, and --discard-changed
    deleted its consensus rows for good and ran its dvhop rows again."""
    path = tmp_path / "episodes.csv"
    only = {"olstm-dvhop": "olstm-dvhop"}
    with EpisodeStore(path) as store:
        check_inputs(store, {}, localizers=only)
        store.append([row(0), row(0, "consensus")])
    with EpisodeStore(path) as store:          # no olstm-dvhop row yet: nothing changed
        check_inputs(store, {"olstm-dvhop": "k1"}, localizers=only)
        store.append([row(0, "olstm-dvhop")])
        store.append([row(1), row(1, "olstm-dvhop")])
    with EpisodeStore(path) as store:          # a retrained checkpoint
        with pytest.raises(EvaluationError, match="another olstm-dvhop checkpoint"):
            check_inputs(store, {"olstm-dvhop": "k2"}, localizers=only)
        check_inputs(store, {"olstm-dvhop": "k2"}, localizers=only, discard=True)
        assert sorted((r["seed"], r["localizer"]) for r in store.rows) == [
            (0, "consensus"), (0, "dvhop"), (1, "dvhop")]
    assert len(path.read_text().splitlines()) == 4


def test_a_record_of_one_digest_for_every_methods_defaults_is_not_resumed(tmp_path):
    """An older evaluate.py recorded one digest of every method's config defaults: which
    methods' rows it covered is unknown, so they count as changed."""
    with EpisodeStore(tmp_path / "episodes.csv") as store:
        check_inputs(store, {CONFIG_DEFAULTS: "old"})
        store.append([row()])
    with EpisodeStore(tmp_path / "episodes.csv") as store:
        with pytest.raises(EvaluationError, match="other config defaults of spiral"):
            check_inputs(store, {config_input("spiral"): "s1"},
                         {config_input("spiral"): ["spiral"]})


def test_blas_kernels_name_the_kernels_openblas_picked():
    """tests/conftest.py pins OpenBLAS's Haswell kernels where the CPU has them (through
    OPENBLAS_CORETYPE, before NumPy loads); what threadpoolctl reads back must name them."""
    kernels = blas_kernels().split(", ")
    assert kernels and all(k.strip() for k in kernels) and kernels != ["none"]
    forced = os.environ.get("OPENBLAS_CORETYPE")
    if forced:
        assert f"openblas {forced}" in kernels


def test_rows_of_other_blas_kernels_count_as_changed(tmp_path):
    """Every row depends on the kernels (no scope): a folder of one machine's episodes is not
    resumed with another's kernels, nor one made before they were recorded."""
    with EpisodeStore(tmp_path / "episodes.csv") as store:
        check_inputs(store, {})                         # an older evaluate.py: no kernels
        store.append([row(0), row(0, method="aoass-rule")])
    with EpisodeStore(tmp_path / "episodes.csv") as store:
        with pytest.raises(EvaluationError, match="aoass-rule, spiral produced with other "
                                                  "BLAS kernels than this run's"):
            check_inputs(store, {BLAS_KERNELS: "openblas Haswell"})
        check_inputs(store, {BLAS_KERNELS: "openblas Haswell"}, discard=True)
        assert store.rows == []
        store.append([row(1)])
    with EpisodeStore(tmp_path / "episodes.csv") as store:
        check_inputs(store, {BLAS_KERNELS: "openblas Haswell"})          # the same: resumes
        with pytest.raises(EvaluationError, match="other BLAS kernels"):
            check_inputs(store, {BLAS_KERNELS: "openblas SkylakeX"})
        assert len(store.rows) == 1


def test_a_new_or_empty_store_records_the_inputs_of_its_run(tmp_path):
    with EpisodeStore(tmp_path / "episodes.csv") as store:
        check_inputs(store, {"policy": "aaa"})
        check_inputs(store, {"policy": "ccc"})             # no rows yet: nothing to mix
        check_inputs(store, {"olstm-dvhop": "bbb"})        # merged with the earlier record
        store.append([row()])
        with pytest.raises(EvaluationError, match="another policy"):
            check_inputs(store, {"policy": "aaa"})


def test_run_records_append_and_a_torn_line_is_left_out(tmp_path):
    assert read_runs(tmp_path) == []
    with EpisodeStore(tmp_path / "episodes.csv") as store:
        record_run(store, {"finished": 3, "wall_seconds": 1.5})
        record_run(store, {"finished": 0, "wall_seconds": 0.25})
    with (tmp_path / RUNS_FILE).open("a") as f:
        f.write('{"finished": 7, "wall_')                   # a write cut short
    assert read_runs(tmp_path) == [{"finished": 3, "wall_seconds": 1.5},
                                   {"finished": 0, "wall_seconds": 0.25}]
    # the next run's record used to join the torn line and be lost with it
    with EpisodeStore(tmp_path / "episodes.csv") as store:
        record_run(store, {"finished": 2, "wall_seconds": 0.5})
    assert read_runs(tmp_path)[2:] == [{"finished": 2, "wall_seconds": 0.5}]


def test_a_repeated_episode_row_is_refused_with_both_lines(tmp_path):
    path = tmp_path / "episodes.csv"
    with EpisodeStore(path) as store:
        store.append([row(seed=0), row(seed=1)])
    text = path.read_text()
    path.write_text(text + text.splitlines(keepends=True)[1])   # line 2 again, as line 4
    # two runs appending to one folder used to count it twice in summary.csv
    with pytest.raises(EvaluationError, match=r"episodes.csv, line 4: repeats the episode and "
                                              r"localizer of line 2"):
        read_episodes(path)
    with pytest.raises(EvaluationError, match="line 4: repeats"):
        EpisodeStore(path)
    path.write_text(text)
    EpisodeStore(path).close()          # the failed store released its lock on the folder


def test_a_second_store_on_one_file_is_refused_while_the_first_is_open(tmp_path):
    path = tmp_path / "episodes.csv"
    with EpisodeStore(path):
        with pytest.raises(EvaluationError, match="being written by another evaluate.py run"):
            EpisodeStore(path)
    with EpisodeStore(path) as store:               # closed: free again
        store.append([row(seed=0)])
    assert len(read_episodes(path)) == 1


def test_a_file_that_is_not_utf8_is_named(tmp_path):
    path = tmp_path / "episodes.csv"
    path.write_bytes(b"\xff\xfe not text")
    for open_it in (read_episodes, EpisodeStore):
        with pytest.raises(EvaluationError, match=r"episodes.csv is not an episodes.csv of this "
                                                  r"evaluation \(not UTF-8 text"):
            open_it(path)


@pytest.mark.parametrize("odd", ["\u2028", "\x0c", "\x1c", "\x85", "\u2029"])
def test_a_text_cell_with_a_character_str_splitlines_breaks_at_reads_back(tmp_path, odd):
    """The reader split the file with str.splitlines, which also breaks at these (the csv
    writer leaves them unquoted): a map named with one was written, and every later read and
    resume of the folder failed on its "broken row"."""
    path = tmp_path / "episodes.csv"
    with EpisodeStore(path) as store:
        store.append([row(seed=0, map=f"test/d0.10_f100_s500{odd}copy"), row(seed=1)])
    back = read_episodes(path)
    assert [r["map"] for r in back] == [f"test/d0.10_f100_s500{odd}copy", "test/d0.10_f100_s500"]
    with EpisodeStore(path) as again:                   # a resume reads it too
        assert len(again.rows) == 2


@pytest.mark.parametrize(("values", "message"), [
    ({"map": "a\nb"}, r"map='a\\nb' holds a line break"),
    ({"method": "spiral\r"}, r"method='spiral\\r' holds a line break")])
def test_a_text_cell_with_a_line_break_is_not_appended(tmp_path, values, message):
    # the writer quoted it, and the line-by-line reader then broke the row in two
    path = tmp_path / "episodes.csv"
    with EpisodeStore(path) as store:
        with pytest.raises(ValueError, match=message):
            store.append([{**row(seed=1), **values}])
    assert read_episodes(path) == []
