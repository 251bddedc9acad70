"""benchmarks/keepout_search.py: the planner's keep-out graph is the masks' graph, timed."""

from __future__ import annotations

import numpy as np
import pytest

from aoass_env.planning.detour import DetourPlanner
from tests.benchmarks.conftest import load_benchmark


def test_the_reference_is_the_diagonal_products_and_the_line_reads_both(capsys):
    from scipy.sparse import diags

    from aoass_env.maps import generate_map

    bench = load_benchmark("keepout_search")
    planner = DetourPlanner(generate_map(40.0, 0.3, np.random.default_rng(2)), 0.55)
    cells = planner._near(np.array([[20.0, 20.0]]), 3.0)
    f = diags(np.where(cells, 5.0, 1.0))
    np.testing.assert_array_equal(bench.masked(planner, cells, 5.0).toarray(),
                                  (f @ planner._graph @ f).toarray())
    bench.MAPS = ((40.0, 0.3),)
    bench.main(["--repeat", "2"])          # raises when the two graphs differ
    out = capsys.readouterr().out
    assert "masks" in out and "planner" in out and " x)" in out


def test_a_bad_repeat_is_refused_in_one_line(capsys):
    with pytest.raises(SystemExit):
        load_benchmark("keepout_search").main(["--repeat", "0"])
    assert "--repeat must be an integer >= 1" in capsys.readouterr().err
