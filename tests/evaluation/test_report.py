"""Summary statistics, summary.csv / summary.md and the figures."""

import csv
import math
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from aoass_env.evaluation.report import (
    bootstrap_interval,
    ci_stats,
    draw_figures,
    method_stats,
    method_table,
    paired_ratio,
    paired_stats,
    robustness_markdown,
    robustness_stats,
    seconds_per_episode,
    summarize,
    summary_markdown,
    write_summary_csv,
)
from aoass_env.evaluation.store import COLUMNS


def rows_for(methods, fields=(100.0,), nodes=(100,), densities=(0.1,), seeds=2,
             localizers=("dvhop", "olstm-dvhop")):
    """Synthetic episodes.csv rows; values depend on method and seed."""
    out = []
    for i, m in enumerate(methods):
        for f in fields:
            for n in nodes:
                for d in densities:
                    for s in range(seeds):
                        for loc in localizers:
                            row = dict.fromkeys(COLUMNS, 1.0)
                            row.update(method=m, map=f"test/m{d}", field_size=f, n_nodes=n,
                                       obstacle_density=d, seed=s, localizer=loc,
                                       rmse=(2.0 if loc == "dvhop" else 1.0) + s + i,
                                       coverage=0.9 + 0.01 * s, wall_seconds=2.0 + i,
                                       localize_seconds=0.5, path_complete=1,
                                       safety_intervention=math.nan)
                            out.append(row)
    return out


def test_ci_stats_by_hand():
    n, mean, std, ci = ci_stats([1.0, 2.0, 6.0, math.nan])
    assert (n, mean) == (3, 3.0)
    assert std == pytest.approx(math.sqrt(((1 - 3) ** 2 + (2 - 3) ** 2 + (6 - 3) ** 2) / 2))
    assert ci == pytest.approx(stats.t.ppf(0.975, 2) * std / math.sqrt(3))
    assert ci_stats([5.0])[1] == 5.0 and math.isnan(ci_stats([5.0])[3])
    assert ci_stats([])[0] == 0 and math.isnan(ci_stats([math.nan])[1])


def test_summary_groups_by_method_localizer_and_grid_point(tmp_path):
    rows = rows_for(["spiral", "scan"], densities=(0.1, 0.2))
    summary = summarize(rows)
    assert len(summary) == 2 * 2 * 2                      # methods x localizers x densities
    first = summary[0]
    assert (first["method"], first["localizer"], first["obstacle_density"], first["n"]) == (
        "spiral", "dvhop", 0.1, 2)
    assert first["rmse_mean"] == 2.5                      # seeds 0 and 1: 2 and 3 m
    assert first["label"] == "Square spiral"
    write_summary_csv(rows, tmp_path / "summary.csv")
    with (tmp_path / "summary.csv").open() as f:
        back = list(csv.DictReader(f))
    assert {"rmse_mean", "rmse_std", "rmse_ci95", "eta_traj_ci95", "n"} <= set(back[0])
    assert back[0]["safety_intervention_mean"] == ""      # undefined: empty cell


def test_markdown_has_methods_as_rows_and_a_table_per_varying_dimension():
    rows = rows_for(["spiral", "scan"], densities=(0.1, 0.2))
    text = summary_markdown(rows, "Title", "Notes.")
    assert text.startswith("# Title\n\nNotes.")
    assert "## By obstacle density" in text and "## By N" not in text
    assert "| Square spiral | 1.50 ± " in text           # olstm-dvhop first: 1 and 2 m
    assert "RMSE olstm-dvhop [m] (localized)" in text


def test_seconds_per_episode_add_the_localizers():
    rows = rows_for(["spiral", "scan"])
    assert seconds_per_episode(rows) == {"spiral": 3.0, "scan": 4.0}   # 2 + i + 2 x 0.5


@pytest.mark.parametrize("grid, expected", [
    (dict(nodes=(100,), densities=(0.1, 0.2)), ["fig2.png"]),                      # quick
    (dict(fields=(100.0, 200.0), nodes=(600, 700), densities=(0.2,)), ["fig3.png"]),
    (dict(nodes=(100,), densities=(0.4, 0.5, 0.6)), ["fig2.png", "fig4.png"]),
    (dict(nodes=(60,)), []),                                                       # smoke
])
def test_figures_are_drawn_when_their_grid_is_in_the_data(tmp_path, grid, expected):
    written = draw_figures(rows_for(["aoass", "spiral", "scan"], **grid), tmp_path)
    assert [p.name for p in written] == expected
    assert all(p.stat().st_size > 10_000 for p in written)


def test_method_stats_per_method_and_localizer():
    rows = rows_for(["spiral", "scan"], seeds=3)
    # olstm-dvhop RMSE = 1 + seed + method index: seeds 0..2 -> mean 2 (spiral), 3 (scan)
    rmse = method_stats(rows, "rmse")
    assert list(rmse) == ["spiral", "scan"]
    n, mean, std, ci = rmse["spiral"]
    assert (n, mean, std) == (3, pytest.approx(2.0), pytest.approx(1.0))
    assert ci == pytest.approx(stats.t.ppf(0.975, 2) / math.sqrt(3))
    assert method_stats(rows, "rmse", "dvhop")["scan"][1] == pytest.approx(4.0)
    assert method_stats(rows, "coverage")["scan"][1] == pytest.approx(0.91)
    # seconds: simulation (2 + index) plus 0.5 s per localizer
    assert method_stats(rows, "seconds")["scan"][1] == pytest.approx(4.0)


def test_method_table_is_the_all_episodes_table():
    rows = rows_for(["spiral", "scan"], nodes=(100, 200))
    table = method_table(rows)
    assert table.splitlines()[0].startswith("| method | RMSE olstm-dvhop [m] (localized)")
    assert len(table.splitlines()) == 4
    assert table in summary_markdown(rows, "t").split("## All episodes")[1]


def test_a_localizer_a_method_was_not_run_with_is_a_dash():
    rows = (rows_for(["spiral"], localizers=("dvhop",))
            + rows_for(["scan"], localizers=("olstm-dvhop",)))
    table = method_table(rows)
    assert "nan" not in table           # it used to read "– (nan%)"
    header, _, *body = table.splitlines()
    columns = [c.strip() for c in header.strip("|").split("|")]
    cells = {r.strip("|").split("|")[0].strip(): [c.strip() for c in r.strip("|").split("|")]
             for r in body}
    olstm, dvhop = (columns.index(f"RMSE {n} [m] (localized)") for n in ("olstm-dvhop", "dvhop"))
    assert cells["Square spiral" if "Square spiral" in cells else "spiral"][olstm] == "–"
    assert cells["SCAN" if "SCAN" in cells else "scan"][dvhop] == "–"


def test_robustness_gap_is_paired_with_the_spiral_of_the_same_episode():
    """Two seeds per density; the spiral covers 0.9 and 0.5 (seed 0, 1), scan 0.8 and 0.6: the
    per-method means differ by 0 points, the paired gaps are -10 and +10."""
    rows = _robustness_rows(
        complete=lambda method, d, s: int(method == "spiral" or s == 0),
        static=lambda method, d, s: 3 * s, moving=lambda method, d, s: 1)
    rows.append({**rows[-1], "method": "ohm", "seed": 999})      # no spiral on its episode
    stats = robustness_stats(rows)
    assert [(s["obstacle_density"], s["method"]) for s in stats] == [
        (0.1, "spiral"), (0.1, "scan"), (0.6, "spiral"), (0.6, "scan"), (0.6, "ohm")]
    scan = stats[1]
    assert scan["n"] == 2 and scan["complete"] == 0.5
    n, mean, std, ci = scan["gap"]
    assert (n, mean) == (2, pytest.approx(0.0)) and std == pytest.approx(math.sqrt(200))
    assert ci == pytest.approx(stats_t975(1) * math.sqrt(200) / math.sqrt(2))
    assert scan["coverage"][1] == pytest.approx(0.7) and scan["worst"] == pytest.approx(0.6)
    assert scan["static"][1] == 1.5 and scan["moving"][1] == 1.0
    assert stats[0]["gap"][1] == 0.0 and stats[4]["gap"][0] == 0        # ohm: no pair
    text = robustness_markdown(rows)
    assert "| SCAN | +0.0 ± 127.1 (50%) | +0.0 ± 127.1 (50%) |" in text
    assert "| Square spiral | 100% | 70.0% ± 254.1% | reference | 50.0% |" in text
    assert "| OHM (reconstructed) | 0% | 50.0% | – | 50.0% | 3.0 | 1.0 | 1 |" in text
    assert "### Obstacle density 0.6" in text and robustness_markdown([]) == ""
    # no localizer in the rows: no RMSE column, no figure
    assert "RMSE" not in method_table(rows) and draw_figures(rows, Path("/nonexistent")) == []


def _robustness_rows(complete=lambda method, d, s: 1, static=lambda method, d, s: 0,
                     moving=lambda method, d, s: 1 if d == 0.1 else 2):
    """Two densities, spiral and scan, two seeds: coverage 0.9 / 0.5 (spiral) and 0.8 / 0.6
    (scan) at density 0.1, 0.1 lower at 0.6; by default every sweep complete, no static
    contact, at 0.6 2 moving contacts (else 1); ``complete``, ``static``, ``moving`` of
    (method, density, seed index) set them."""
    rows = []
    for method, coverage in (("spiral", (0.9, 0.5)), ("scan", (0.8, 0.6))):
        for d in (0.1, 0.6):
            for s in range(2):
                row = dict.fromkeys(COLUMNS, 1.0)
                row.update(method=method, map=f"generated/d{d:.2f}_f100_r{s}", field_size=100.0,
                           n_nodes=100, obstacle_density=d, seed=700 + s, localizer="none",
                           rmse=math.nan, localized=math.nan, localize_seconds=0.0,
                           coverage=coverage[s] if d == 0.1 else coverage[s] - 0.1,
                           path_complete=complete(method, d, s),
                           collisions_static=static(method, d, s),
                           collisions_moving=moving(method, d, s))
                rows.append(row)
    return rows


def test_robustness_tables_per_density_hold_that_density_only():
    """Each "Obstacle density" table lists each method once, with that density's values
    (worst coverage 50 % / 60 % at 0.1, 40 % / 50 % at 0.6; 1 / 2 moving contacts)."""
    text = robustness_markdown(_robustness_rows())
    assert text.startswith("## Robustness by obstacle density\n")       # level 2 by default
    assert robustness_markdown(_robustness_rows(), level=3).startswith("### Robustness")
    tables = {}
    for part in text.split("### Obstacle density ")[1:]:
        density, _, table = part.partition("\n\n")
        tables[density] = table.strip().splitlines()[2:]
    assert list(tables) == ["0.1", "0.6"]
    for density, worst, moving in (("0.1", ("50.0%", "60.0%"), "1.0 ± 0.0"),
                                   ("0.6", ("40.0%", "50.0%"), "2.0 ± 0.0")):
        body = tables[density]
        assert [r.split("|")[1].strip() for r in body] == ["Square spiral", "SCAN"]
        assert [r.split("|")[5].strip() for r in body] == list(worst)
        assert [r.split("|")[7].strip() for r in body] == [moving, moving]


def test_robustness_markdown_tables_have_as_many_cells_in_every_line():
    text = robustness_markdown(_robustness_rows())
    tables = [b for b in text.split("\n\n") if b.startswith("| method")]
    assert len(tables) == 3                             # overview, density 0.1 and 0.6
    for table in tables:
        lines = table.strip().splitlines()
        assert set(lines[1].strip("|").split("|")) == {"---"}
        assert len({line.count("|") for line in lines}) == 1
    assert tables[0].splitlines()[0] == "| method | d = 0.1 | d = 0.6 |"


def test_paired_stats_and_ratio_use_the_episodes_both_played():
    """scan's E_total is 2x the spiral's on seeds 0 and 1 (the spiral spends 100 and 300 J);
    seed 2 has no spiral episode, so it is left out of both; the RMSE pairs of OLSTM-DV-Hop
    (1 + s + i) differ by exactly 1 m (scan is the second method)."""
    rows = rows_for(["spiral", "scan"], seeds=3)
    for r in rows:
        r["energy_total"] = (100.0 + 200.0 * r["seed"]) * (2.0 if r["method"] == "scan" else 1.0)
    rows = [r for r in rows if not (r["method"] == "spiral" and r["seed"] == 2)]
    n, mean, std, ci = paired_stats(rows, "scan", "spiral", "energy_total")
    assert (n, mean) == (2, pytest.approx(200.0)) and std == pytest.approx(math.sqrt(2e4))
    assert ci == pytest.approx(stats_t975(1) * math.sqrt(2e4) / math.sqrt(2))
    assert paired_stats(rows, "scan", "spiral", "rmse")[:3] == (2, 1.0, 0.0)
    assert paired_stats(rows, "scan", "spiral", "rmse", "dvhop")[1] == 1.0
    assert paired_ratio(rows, "scan", "spiral") == (2, pytest.approx(2.0))
    # the ratio of sums, not the mean of ratios: 1.5x on a 100 J episode, 1x on a 300 J one
    for r in rows:
        if r["method"] == "scan":
            r["energy_total"] = 150.0 if r["seed"] == 0 else 300.0
    assert paired_ratio(rows, "scan", "spiral")[1] == pytest.approx(450.0 / 400.0)
    # no pair: nothing to compare
    assert paired_stats(rows, "scan", "ohm", "energy_total")[0] == 0
    n, ratio = paired_ratio(rows, "scan", "ohm")
    assert n == 0 and math.isnan(ratio)


def stats_t975(dof: int) -> float:
    return stats.t.ppf(0.975, dof)


def test_bootstrap_interval_stays_inside_the_values_range():
    """A ratio near its bound (coverage up to 1, η_traj down to 0): the t interval leaves the
    range, the bootstrap percentile interval cannot."""
    values = [1.0] * 9 + [0.4]
    _, mean, _, half = ci_stats(values)
    assert mean + half > 1.0                                    # what the figure used to show
    m, low, high = bootstrap_interval(values)
    assert m == pytest.approx(0.94) and 0.4 <= low < m < high <= 1.0
    assert bootstrap_interval(values) == (m, low, high)          # seeded
    # within strata: a density whose episodes all agree adds no spread
    strat = bootstrap_interval([0.2, 0.2, 0.9, 0.9], groups=[0.1, 0.1, 0.4, 0.4])
    assert strat == (pytest.approx(0.55), pytest.approx(0.55), pytest.approx(0.55))
    pooled = bootstrap_interval([0.2, 0.2, 0.9, 0.9])
    assert pooled[1] < 0.55 < pooled[2]
    assert bootstrap_interval([0.3]) == (0.3, 0.3, 0.3)
    assert all(math.isnan(v) for v in bootstrap_interval([math.nan]))
    with pytest.raises(ValueError, match="groups has 1 entries for 2 values"):
        bootstrap_interval([1.0, 2.0], groups=[0.1])


def test_fig2_bars_stay_in_range_show_e_total_and_keep_the_legend_clear(tmp_path):
    import matplotlib
    matplotlib.use("Agg")
    from matplotlib.patches import Rectangle

    from aoass_env.evaluation.report import _fig2
    rows = rows_for(["aoass", "spiral", "scan"], densities=(0.1, 0.2, 0.3, 0.4), seeds=3)
    for r in rows:                      # skewed ratios at their bounds, as OHM's coverage was
        odd = r["seed"] == 0 and r["obstacle_density"] == 0.1
        r["coverage"] = 0.3 if odd else 1.0
        r["eta_traj"] = 0.9 if odd else 0.02
    episodes = [r for r in rows if r["localizer"] == "olstm-dvhop"]
    for key in ("coverage", "eta_traj"):  # the t interval of 12 episodes leaves [0, 1]
        _, mean, _, half = ci_stats(e[key] for e in episodes if e["method"] == "aoass")
        assert mean + half > 1.0 or mean - half < 0.0
    for e in episodes:
        e["rmse:olstm-dvhop"] = e["rmse:dvhop"] = e["rmse"]
    fig = _fig2(episodes, ["olstm-dvhop", "dvhop"])
    axes = fig.axes
    assert [ax.get_title() for ax in axes][1] == "(b) total energy E_total [J]"
    for ax in axes[2:]:                 # coverage and η_traj: error bars inside [0, 1]
        assert ax.lines                 # the caps of the error bars
        for line in ax.lines:
            ys = np.asarray(line.get_ydata(), dtype=float)
            assert np.all((ys >= 0.0) & (ys <= 1.0)), (ax.get_title(), ys)
    fig.canvas.draw()
    legend = axes[0].get_legend().get_window_extent()
    bars = [p.get_window_extent() for p in axes[0].patches if isinstance(p, Rectangle)]
    assert bars and not any(legend.overlaps(b) for b in bars)


def test_bootstrap_interval_matches_the_normal_interval_of_a_symmetric_sample():
    """The percentile bootstrap of the mean of 0, 1, ..., 99: its bootstrap distribution is
    close to normal with the plug-in standard error sqrt((100^2 - 1) / 12) / 10, so the 95 %
    interval is 49.5 -+ 1.96 x that (and the 50 % one 49.5 -+ 0.674 x that), to the bootstrap's
    sampling noise."""
    values = np.arange(100.0)
    se = math.sqrt((100**2 - 1) / 12) / 10
    for level in (0.95, 0.5):
        z = stats.norm.ppf((1 + level) / 2)
        mean, low, high = bootstrap_interval(values, level=level, n_boot=20_000, seed=550_001)
        assert mean == 49.5
        assert low == pytest.approx(49.5 - z * se, abs=0.3)
        assert high == pytest.approx(49.5 + z * se, abs=0.3)


def test_bootstrap_interval_leaves_out_missing_values():
    """NaN and None (an episode without an RMSE) are not values: the mean and interval are
    those of the finite values alone."""
    m, low, high = bootstrap_interval([0.2, math.nan, 0.4, None, 0.6])
    assert m == pytest.approx(0.4) and 0.2 <= low < m < high <= 0.6
    strat = bootstrap_interval([0.2, math.nan, 0.2, 0.9], groups=[0.1, 0.1, 0.1, 0.4])
    assert strat == (pytest.approx(1.3 / 3), pytest.approx(1.3 / 3), pytest.approx(1.3 / 3))


def test_error_bars_are_the_distances_from_the_mean_to_the_interval_ends():
    from aoass_env.evaluation.report import _error_bars

    means, err = _error_bars([(2.0, 1.5, 3.0), (0.5, 0.5, 0.5), (math.nan,) * 3])
    assert means[:2] == [2.0, 0.5] and math.isnan(means[2])
    np.testing.assert_array_equal(err, [[0.5, 0.0, 0.0], [1.0, 0.0, 0.0]])


def test_methods_outside_the_registry_keep_their_rows_after_the_known_ones():
    """A method name the registry does not know (an experiment's own) still gets its
    statistics and its table row, after the registered methods, in name order."""
    rows = rows_for(["zz-custom", "spiral", "aa-custom"])
    assert list(method_stats(rows, "coverage")) == ["spiral", "aa-custom", "zz-custom"]
    body = method_table(rows).splitlines()[2:]
    assert [r.split("|")[1].strip() for r in body] == ["Square spiral", "aa-custom",
                                                       "zz-custom"]
    assert [s["method"] for s in summarize(rows)][::2] == ["spiral", "aa-custom", "zz-custom"]


def test_summary_rows_are_in_method_then_localizer_order():
    """summary.csv's rows: methods in registry order, then localizer, field, N and density in
    sorted order, whatever the order of the episodes."""
    rows = rows_for(["scan", "spiral"], densities=(0.2, 0.1), localizers=("olstm-dvhop", "dvhop"))
    keys = [(s["method"], s["localizer"], s["obstacle_density"]) for s in summarize(rows)]
    assert keys == [(m, loc, d) for m in ("spiral", "scan") for loc in ("dvhop", "olstm-dvhop")
                    for d in (0.1, 0.2)]


def test_markdown_tables_have_as_many_cells_in_every_line():
    """A Markdown table renders only when its header, separator and rows have the same
    number of cells."""
    rows = rows_for(["spiral", "scan"], densities=(0.1, 0.2))
    text = summary_markdown(rows, "t")
    assert text.endswith(" |\n")                       # a text file ends its last line
    tables = [b for b in text.split("\n\n") if b.startswith("| method")]
    assert len(tables) == 3                             # all episodes, density 0.1 and 0.2
    for table, n in zip(tables, ("4", "2", "2"), strict=True):   # episodes per method
        lines = table.strip().splitlines()
        assert set(lines[1].strip("|").split("|")) == {"---"}
        assert len({line.count("|") for line in lines}) == 1
        assert lines[0].endswith("| n |")
        assert [line.split("|")[-2].strip() for line in lines[2:]] == [n, n]


def test_markdown_tables_per_dimension_hold_that_value_s_episodes_only():
    """"### obstacle density 0.10" is the table of the density-0.1 episodes alone (the
    methods' values differ by density, so the wrong episodes would show)."""
    rows = rows_for(["spiral", "scan"], densities=(0.1, 0.2))
    for r in rows:
        r["coverage"] = 0.5 if r["obstacle_density"] == 0.1 else 0.8
    text = summary_markdown(rows, "t")
    for d in (0.1, 0.2):
        part = text.split(f"### obstacle density {d:.2f}\n\n")[1].split("\n\n")[0]
        assert part.strip() == method_table([r for r in rows if r["obstacle_density"] == d])


def test_paired_ratio_leaves_out_pairs_with_a_missing_value():
    """A pair where either side has no value (NaN) is not summed: the ratio is that of the
    complete pairs."""
    rows = rows_for(["spiral", "scan"], seeds=3)
    for r in rows:
        r["energy_total"] = {("spiral", 0): 100.0, ("scan", 0): 150.0, ("spiral", 1): 200.0,
                             ("scan", 1): math.nan, ("spiral", 2): math.nan,
                             ("scan", 2): 50.0}[r["method"], r["seed"]]
    assert paired_ratio(rows, "scan", "spiral") == (1, pytest.approx(1.5))
    assert paired_stats(rows, "scan", "spiral", "energy_total")[:2] == (1, pytest.approx(50.0))
