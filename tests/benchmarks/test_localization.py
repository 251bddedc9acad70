"""benchmarks/localization.py: the tables of neighbour stages and of the true pattern's ceiling."""

from __future__ import annotations

import numpy as np
import pytest

from aoass_env.config import AOASSConfig
from aoass_env.localization import consensus as module
from aoass_env.localization import localize, prepare
from aoass_env.localization.consensus import node_consensus
from aoass_env.localization.olstm import load_checkpoint
from aoass_env.localization.training import EpisodeSpec, pattern_path
from aoass_env.simulator import Simulator
from tests.benchmarks.conftest import load_benchmark


def test_neighbour_rounds_table_matches_localize_and_restores_the_default(tmp_path):
    bench = load_benchmark("localization")
    config = AOASSConfig(field_size=40.0, n_nodes=40, obstacle_density=0.1,
                         n_moving_obstacles=0, doi=0.1)
    log = Simulator(config, np.random.default_rng(3), seed=3).run()
    log.save(tmp_path / "a.npz")
    model = load_checkpoint()
    table = bench.neighbour_rounds(tmp_path, model, rounds=(0, module.NEIGHBOUR_ROUNDS))
    assert module.NEIGHBOUR_ROUNDS == 2                       # the default is put back
    row = next(line for line in table.splitlines() if line.startswith("| 0.1 |"))
    cells = [c.strip() for c in row.strip("|").split("|")][1:]
    true = log.nodes
    for method, column in (("consensus", 0), ("olstm-dvhop", 1)):
        est = localize(log, method, **({"checkpoint": model} if method == "olstm-dvhop" else {}))
        ok = np.all(np.isfinite(est), axis=1)
        rmse = np.sqrt(np.mean(np.sum((est[ok] - true[ok]) ** 2, axis=1)))
        assert cells[-1].split(" / ")[column] == f"{rmse:.3f}"     # the default's column


def test_ceiling_table_is_the_consensus_with_the_true_pattern_beside_localize(tmp_path):
    bench = load_benchmark("localization")
    config = AOASSConfig(field_size=40.0, n_nodes=40, obstacle_density=0.1,
                         n_moving_obstacles=0, doi=0.1)
    sim = Simulator(config, np.random.default_rng(3), seed=3)
    log = sim.run()
    path = tmp_path / "a.npz"
    log.save(path)
    np.save(pattern_path(path), np.array(sim.radio.anchor_pattern), allow_pickle=False)
    zero = tmp_path / "b.npz"          # a DOI 0 log is left out of the table
    Simulator(config.replace(doi=0.0), np.random.default_rng(4), seed=4).run().save(zero)
    model = load_checkpoint()
    specs = [EpisodeSpec("test/d0.10_f100_s500", 40, 0.1, 3),
             EpisodeSpec("test/d0.10_f100_s500", 40, 0.0, 4)]
    table = bench.ceiling([path, zero], specs, model)
    rows = [line for line in table.splitlines() if line.startswith("| 0.")]
    assert len(rows) == 1
    cells = [c.strip() for c in rows[0].strip("|").split("|")]
    assert cells[:3] == ["0.1", "40", "0.1"]
    covered = np.flatnonzero(prepare(log).covered)
    true = log.nodes[covered]

    def rmse(est):
        return f"{np.sqrt(np.mean(np.sum((est - true) ** 2, axis=1))):.3f}"

    assert cells[3] == rmse(localize(log, "consensus")[covered])
    assert cells[4] == rmse(localize(log, "olstm-dvhop", checkpoint=model)[covered])
    pattern = np.array(sim.radio.anchor_pattern)
    assert cells[6] == rmse(node_consensus(prepare(log), covered,
                                           band=(pattern, pattern)).estimate)
    c, o = float(cells[3]), float(cells[4])
    assert abs(float(cells[5].rstrip(" %")) - 100 * (1 - o / c)) < 0.2


@pytest.mark.parametrize("argv, message", [
    (["--seeds", "0"], "argument --seeds: must be an integer >= 1, got '0'"),
    (["--repeats", "0"], "argument --repeats: must be an integer >= 1, got '0'"),
    (["--densities", "0.9"], "--densities: 0.9 is not the density of a shipped 100 m test map; "
                             "valid: 0.1 0.2 0.3 0.4 0.5 0.6"),
    (["--dois", "2"], "--dois: doi=2.0 must be a number in [0.0, 0.5]"),
    # a missing or empty log folder used to give an empty table and exit 0
    (["--ablation", "no_such_dir"], "--ablation no_such_dir: holds no beacon log (*.npz)"),
    (["--neighbour-rounds", "no_such_dir"],
     "--neighbour-rounds no_such_dir: holds no beacon log (*.npz)"),
])
def test_bad_flags_are_one_line_before_any_log(monkeypatch, capsys, tmp_path, argv, message):
    """These used to fail later: an IndexError, a ZeroDivisionError, a ConfigError traceback."""
    bench = load_benchmark("localization")
    monkeypatch.setattr("sys.argv", ["localization.py", "--out", str(tmp_path), *argv])
    with pytest.raises(SystemExit) as exit_:
        bench.main()
    assert exit_.value.code == 2
    line = capsys.readouterr().err.strip().splitlines()[-1]
    assert line.startswith(f"localization.py: error: {message}")
    assert not list(tmp_path.iterdir())


def test_an_output_folder_that_is_a_file_is_one_line_before_any_log(monkeypatch, capsys,
                                                                    tmp_path):
    # it was a NotADirectoryError traceback when the first log was written
    afile = tmp_path / "afile"
    afile.write_text("")
    bench = load_benchmark("localization")
    monkeypatch.setattr("sys.argv", ["localization.py", "--out", str(afile), "--seeds", "1",
                                     "--dois", "0", "--densities", "0.1", "--logs-only"])
    with pytest.raises(SystemExit) as exit_:
        bench.main()
    assert exit_.value.code == 2
    line = capsys.readouterr().err.strip().splitlines()[-1]
    assert line == f"localization.py: error: --out {afile}: {afile} is a file, not a folder"
