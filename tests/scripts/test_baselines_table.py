"""scripts/baselines_table.py: the tables of docs/baselines.md."""

from __future__ import annotations

from pathlib import Path

from aoass_env.config import AOASSConfig
from aoass_env.maps import load_map
from aoass_env.planning.square_spiral import episode_spiral
from tests.scripts.test_script_input import load, refused


def test_fdpp_spends_the_budget_it_is_given():
    """FDPP drives its budget, 1.0 x or 1.5 x the spiral, and at most one control period more
    (its table's point)."""
    script = load("baselines_table")
    name = script.first_test_map(0.1)
    assert name == "test/d0.10_f100_s500"
    config = AOASSConfig(field_size=100.0, n_nodes=100, map=name)
    spiral = episode_spiral(config, load_map(name)).length
    period = config.anchor_max_speed * config.dt
    paths = []
    for budget in script.BUDGETS:
        coverage, path, contacts, seconds = script.fdpp_episode(name, 0, budget)
        assert 0.0 < coverage <= 1.0 and contacts >= 0 and seconds > 0
        assert budget * spiral - 5.0 < path <= budget * spiral + period
        paths.append(path)
    assert paths[1] > paths[0]


def test_measured_row_names_the_map_and_the_planned_length():
    script = load("baselines_table")
    (row,) = script.measured_rows(["fdpp"], (0.1,))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[:3] == ["FDPP", "d0.10_f100_s500", "776"]     # its plan is the 776 m spiral
    assert len(cells) == 7


def test_the_committed_measured_table_has_the_scripts_row():
    """docs/baselines.md's table is typed in from the script's output: one of its rows, run
    again, must read the same but for the wall seconds (the table had gone stale unseen:
    M-ANCHORO's plan there was 1093 m, the script's 1097 m)."""
    script = load("baselines_table")
    (row,) = script.measured_rows(["m-anchoro"], (0.1,))
    cells = [c.strip() for c in row.strip("|").split("|")]
    page = (Path(__file__).parents[2] / "docs" / "baselines.md").read_text(encoding="utf-8")
    (committed,) = [line for line in page.splitlines()
                    if line.startswith(f"| {cells[0]} | {cells[1]} |")]
    assert [c.strip() for c in committed.strip("|").split("|")][:6] == cells[:6]


def test_the_committed_fdpp_budget_table_has_the_scripts_row():
    """The same for FDPP's budget table (typed in from ``--table fdpp-budget``): its density-0.1
    row, run again, reads the same but for the two wall-second cells."""
    script = load("baselines_table")
    (row,) = script.fdpp_budget_rows((0.1,))
    cells = [c.strip() for c in row.strip("|").split("|")]
    page = (Path(__file__).parents[2] / "docs" / "baselines.md").read_text(encoding="utf-8")
    (committed,) = [line.strip() for line in page.splitlines()
                    if line.strip().startswith(f"| {cells[0]} | ") and " / " in line]
    committed_cells = [c.strip() for c in committed.strip("|").split("|")]
    assert len(committed_cells) == len(cells) == 11
    seconds = (5, 10)
    assert [c for i, c in enumerate(committed_cells) if i not in seconds] == \
        [c for i, c in enumerate(cells) if i not in seconds]


def test_an_unknown_table_is_refused_in_one_line(capsys, monkeypatch):
    assert refused(capsys, monkeypatch, "baselines_table", "--table", "ohm").startswith(
        "argument --table: invalid choice: 'ohm'")


def test_otpp_row_names_the_map_and_counts_its_sub_squares():
    script = load("baselines_table")
    (row,) = script.otpp_rows((100.0,), (0.6,))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[:2] == ["d0.60_f100_s515", "0/36"]     # no sub-square of it has a reg
    assert len(cells) == 4 and float(cells[2]) > 0 and float(cells[3]) > 0   # wall seconds
