"""benchmarks/localization.py: the table of neighbour stages."""

from __future__ import annotations

import numpy as np

from aoass_env.config import AOASSConfig
from aoass_env.localization import consensus as module
from aoass_env.localization import localize
from aoass_env.localization.olstm import load_checkpoint
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
        est = localize(log, method, checkpoint=model)
        ok = np.all(np.isfinite(est), axis=1)
        rmse = np.sqrt(np.mean(np.sum((est[ok] - true[ok]) ** 2, axis=1)))
        assert cells[-1].split(" / ")[column] == f"{rmse:.3f}"     # the default's column
