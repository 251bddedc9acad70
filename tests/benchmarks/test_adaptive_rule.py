"""benchmarks/adaptive_rule.py: the rule's coverage against its path, beside the spiral's."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import stats

from aoass_env.config import AOASSConfig, config_for_map
from aoass_env.maps import load_map
from aoass_env.planning import AdaptiveConfig
from aoass_env.planning.adaptive import site_radio
from aoass_env.simulator import Simulator
from tests.benchmarks.conftest import load_benchmark


@pytest.fixture(scope="module")
def bench():
    """``benchmarks/adaptive_rule.py`` loaded as a module."""
    return load_benchmark("adaptive_rule")


def test_variants_change_the_named_fields_and_refuse_bad_ones(bench):
    rules = bench.parse_variants([["cells", "cell_need=0.2", "wide_passes=false"]])
    assert rules["rule"] == AdaptiveConfig()
    assert rules["cells"] == AdaptiveConfig(cell_need=0.2, wide_passes=False)
    with pytest.raises(bench.ConfigError, match="did you mean 'skip_need'"):
        bench.parse_variants([["typo", "skip_needs=0.1"]])
    with pytest.raises(bench.ConfigError, match="cell_need='x' is not a number"):
        bench.parse_variants([["bad", "cell_need=x"]])
    with pytest.raises(bench.ConfigError, match="is not key=value"):
        bench.parse_variants([["bad", "cell_need"]])
    for taken in ("rule", "plain spiral"):      # a variant must not replace a row silently
        with pytest.raises(bench.ConfigError, match="that row name is taken"):
            bench.parse_variants([[taken, "cell_need=0.2"]])


@pytest.mark.parametrize("flag", ["--seeds", "--nodes", "--limit", "--maps"])
def test_counts_below_one_are_refused(bench, capsys, flag):
    with pytest.raises(SystemExit):
        bench.main([flag, "0"])
    assert f"{flag} must be at least 1, got 0" in capsys.readouterr().err


def test_rows_share_episodes_and_account_for_every_uncovered_node(bench, capsys):
    table = bench.main(["--densities", "0.1", "--seeds", "1", "--nodes", "40", "--limit", "1",
                        "--variant", "no plan", "prune=false"])
    assert list(table) == ["plain spiral", "rule", "no plan"]
    out = capsys.readouterr().out
    assert "| plain spiral |" in out and "| 1.000 |" in out
    for outcomes in table.values():
        (o,) = outcomes
        assert 0.0 < o.coverage <= 1.0 and o.path > 0.0
        assert o.in_covered + o.in_open + o.outside == round((1.0 - o.coverage) * 40)
    # the pruned plan makes the rule's spiral shorter
    assert table["rule"][0].path < table["no plan"][0].path


def test_a_split_without_maps_of_the_density_is_refused(bench, capsys):
    with pytest.raises(SystemExit):
        bench.main(["--densities", "0.05"])
    assert "no maps/train map of field 100 m at densities [0.05]" in capsys.readouterr().err


def test_localizer_adds_each_sweeps_rmse_of_its_own_log(bench, capsys):
    train_map = load_map("train/d0.10_f100_s000")
    outcome = bench.sweep(train_map, 0, 40, None, "consensus")
    assert outcome.rmse is not None and 0.0 < outcome.rmse < 5.0
    assert bench.sweep(train_map, 0, 40, None).rmse is None
    table = bench.main(["--densities", "0.1", "--seeds", "1", "--nodes", "40", "--limit", "1",
                        "--localizer", "consensus"])
    out = capsys.readouterr().out
    assert "RMSE consensus [m]" in out
    assert all(o.rmse is not None for outcomes in table.values() for o in outcomes)
    assert f"| {table['rule'][0].rmse:.3f} |" in out


def test_fresh_maps_are_generated_from_the_seed_per_density(bench, capsys):
    args = ["--fresh", "987", "--maps", "1", "--densities", "0.1", "0.4", "--seeds", "1",
            "--nodes", "30"]
    table = bench.main(args)
    out = capsys.readouterr().out
    assert "2 freshly generated maps (seed 987, 1 per density) x 1 seeds" in out
    assert "d = 0.1" in out and "d = 0.4" in out
    assert len(table["rule"]) == 2
    assert bench.main(args) == table            # the same seed, the same maps and sweeps
    capsys.readouterr()
    for flags, message in ((["--split", "fit"], "--split and --limit apply to maps/train"),
                           (["--limit", "1"], "--split and --limit apply to maps/train")):
        with pytest.raises(SystemExit):
            bench.main(["--fresh", "987", *flags])
        assert message in capsys.readouterr().err
    with pytest.raises(SystemExit):
        bench.main(["--maps", "2"])
    assert "--maps applies to --fresh only" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        bench.main(["--fresh", "987", "--densities", "0.7"])
    assert "--densities 0.7: a generated map's density must lie in [0, 0.6]" in \
        capsys.readouterr().err


def test_the_bound_is_eq18_of_beacons_from_every_reachable_lattice_point(bench, capsys):
    """``coverage_bound`` against Eq. 18 by its definition (at least three heard beacons whose
    root-sum-square distance to their best line, by SVD, is at least the tolerance), with the
    heard points collected node by node from the nodes' radio."""
    obstacle_map = load_map("train/d0.40_f100_s015")
    config = config_for_map(AOASSConfig(n_nodes=40), obstacle_map)
    sim = Simulator(config, np.random.default_rng(3), obstacle_map=obstacle_map, seed=3)
    sites = site_radio(sim.planner, sim.coverage_map).nodes
    heard = [[] for _ in sim.nodes]
    for point in sites:
        for node in sim.radio.receivers(point):
            heard[node].append(point)
    covered = 0
    for points in heard:
        if len(points) >= 3:
            centred = np.array(points) - np.mean(points, axis=0)
            covered += np.linalg.svd(centred, compute_uv=False)[-1] >= config.collinearity_tol
    bound = bench.coverage_bound(obstacle_map, 3, 40)
    assert bound == covered / 40
    table = bench.main(["--densities", "0.1", "--seeds", "1", "--nodes", "40", "--limit", "1",
                        "--bound"])
    out = capsys.readouterr().out
    assert "| reachable bound (coverage) |" in out and "reachable bound over all sweeps" in out
    (b,) = table[bench.BOUND]
    assert b.coverage >= max(o.coverage for name, (o,) in table.items() if name != bench.BOUND)
    with pytest.raises(bench.ConfigError, match="that row name is taken"):
        bench.parse_variants([[bench.BOUND, "cell_need=0.2"]])


def test_noting_the_cells_phase_leaves_the_sweep_as_it_was(bench):
    """--cells steps the sweep itself: the same sweep as Simulator.run, and its visits add up
    (a dense training map, where the cells phase goes beyond the reference)."""
    obstacle_map = load_map("train/d0.50_f100_s020")
    plain = bench.sweep(obstacle_map, 0, 40, AdaptiveConfig())
    noted = bench.sweep(obstacle_map, 0, 40, AdaptiveConfig(), cells=True)
    assert plain.cells is None and noted.cells is not None
    assert dataclasses.replace(noted, cells=None) == plain
    c = noted.cells
    assert c.visits > 0 and 0 <= c.covered_then <= c.covered_at_end <= c.visits
    assert c.coverable <= c.visits and 0.0 <= c.path_uncoverable <= c.path < plain.path
    assert bench.sweep(obstacle_map, 0, 40, None, cells=True).cells is None    # the spiral


def test_paired_differences_are_the_variants_minus_the_rule_on_each_episode(bench, capsys):
    """The paired table: the mean of the per-episode differences and its t interval; a sweep
    without an RMSE is left out of the RMSE's pairs only."""
    rule = [bench.Outcome(0.90, 100.0, True, 0, 0, 0, 1.0),
            bench.Outcome(0.80, 200.0, True, 0, 0, 0, 2.0),
            bench.Outcome(0.70, 300.0, True, 0, 0, 0, 3.0)]
    variant = [bench.Outcome(0.91, 90.0, True, 0, 0, 0, 1.5),
               bench.Outcome(0.83, 150.0, True, 0, 0, 0, None),
               bench.Outcome(0.70, 330.0, True, 0, 0, 0, 3.1)]
    n, mean, half = bench.paired(variant, rule, "path")
    d = np.array([-10.0, -50.0, 30.0])
    assert n == 3 and mean == pytest.approx(d.mean())
    assert half == pytest.approx(stats.t.ppf(0.975, 2) * d.std(ddof=1) / np.sqrt(3))
    n, mean, half = bench.paired(variant, rule, "rmse")
    assert n == 2 and mean == pytest.approx(0.3)
    bench._print_paired({"plain spiral": rule, "rule": rule, "v": variant}, True)
    out = capsys.readouterr().out
    assert "| v | +1.33 ±" in out and "| -10 ±" in out and "+0.300 ±" in out and "(n = 2)" in out
    assert "| rule |" not in out and "| plain spiral |" not in out


def test_variants_print_their_paired_differences_to_the_rule(bench, capsys):
    table = bench.main(["--densities", "0.1", "--seeds", "1", "--nodes", "40", "--limit", "1",
                        "--variant", "no plan", "prune=false"])
    out = capsys.readouterr().out
    gap = table["no plan"][0].path - table["rule"][0].path
    assert f"| no plan | {100 * (table['no plan'][0].coverage - table['rule'][0].coverage):+.2f}" \
        f" ± nan | {gap:+.0f} ± nan |" in out


@pytest.mark.parametrize("value", ["nan", "0", "-5"])
def test_a_field_size_that_is_no_size_is_refused(bench, capsys, value):
    # it was a MapError traceback from list_maps or generate_map
    with pytest.raises(SystemExit):
        bench.main(["--field", value])
    err = capsys.readouterr().err
    assert f"argument --field: must be a finite number > 0, got '{value}'" in err


def test_a_negative_fresh_seed_is_refused(bench, capsys):
    with pytest.raises(SystemExit):
        bench.main(["--fresh", "-1"])
    assert "argument --fresh: must be an integer >= 0, got '-1'" in capsys.readouterr().err
