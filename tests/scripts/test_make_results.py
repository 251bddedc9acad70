"""scripts/make_results.py: the page's values from episodes, and the paper table's verdicts."""

import importlib.util
import json
import math
import string
from collections import Counter
from pathlib import Path

import pytest

from aoass_env.evaluation.episode import run_episode
from aoass_env.evaluation.methods import RunOptions
from aoass_env.evaluation.store import (
    BLAS_KERNELS,
    COLUMNS,
    INPUTS_FILE,
    NO_LOCALIZER,
    EpisodeStore,
    blas_kernels,
    comparable_lines,
    read_episodes,
    read_inputs,
)
from aoass_env.evaluation.sweep import PRESETS, episode_jobs

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "make_results.py"
spec = importlib.util.spec_from_file_location("make_results", SCRIPT)
make_results = importlib.util.module_from_spec(spec)
spec.loader.exec_module(make_results)

METHODS = ("aoass", "aoass-scripted", "aoass-rule", "aoass-adaptive", "spiral", "fdpp", "ohm",
           "m-anchoro", "otpp")


def preset_rows(preset: str, energy: dict[str, float], rmse: dict[str, float]) -> list[dict]:
    """Two seeds of every grid point of ``preset`` for METHODS: E_total and OLSTM-DV-Hop RMSE
    per method from the dicts (seed 1 adds 10 % to both), DV-Hop 10 m."""
    p = PRESETS[preset]
    out = []
    for f in p.field_sizes:
        for n in p.n_nodes:
            for d in p.densities:
                for s in range(2):
                    for m in METHODS:
                        for loc in ("dvhop", "olstm-dvhop"):
                            row = dict.fromkeys(COLUMNS, 1.0)
                            row.update(
                                method=m, map=f"test/d{d}_f{f:g}", field_size=f, n_nodes=n,
                                obstacle_density=d, seed=s, localizer=loc, coverage=0.98,
                                localized=0.98, path_length=energy[m] / 0.8,
                                rmse=10.0 if loc == "dvhop" else rmse[m] * (1 + 0.1 * s),
                                energy_total=energy[m] * (1 + 0.1 * s), wall_seconds=2.0,
                                localize_seconds=0.5, path_complete=1)
                            out.append(row)
    return out


ENERGY = {"aoass-adaptive": 1000.0, "aoass-rule": 800.0, "aoass": 1300.0,
          "aoass-scripted": 900.0, "spiral": 900.0, "fdpp": 600.0, "ohm": 1200.0,
          "m-anchoro": 1500.0, "otpp": 1600.0}
RMSE = {"aoass-adaptive": 0.9, "aoass-rule": 0.8, "aoass": 1.1, "aoass-scripted": 0.9,
        "spiral": 1.0, "fdpp": 1.2, "ohm": 0.8, "m-anchoro": 1.0, "otpp": 1.0}


def robustness_rows(seeds: int) -> list[dict]:
    """The robustness preset's episodes, unlocalized: the spiral covers 90 %, OHM 80 % + 1 % per
    seed index, the residual AOASS 95 %, the adaptive policy 95 % and the rule 96 %; every sweep
    ends by itself but OHM's first. E_total: the spiral 1000 J, the adaptive policy 700 J, the
    rule 800 J at densities up to 0.5 and 2000 J at 0.6, the others 1 J."""
    out = []
    methods = ("spiral", "ohm", "aoass", "aoass-rule", "aoass-adaptive")
    for job in episode_jobs(PRESETS["robustness"], methods, (NO_LOCALIZER,), seeds):
        k = job.key
        index = k.seed % 1000
        row = dict.fromkeys(COLUMNS, 1.0)
        row.update(method=k.method, map=k.map, field_size=k.field_size, n_nodes=k.n_nodes,
                   obstacle_density=k.obstacle_density, seed=k.seed, localizer=NO_LOCALIZER,
                   rmse=math.nan, localized=math.nan, localize_seconds=0.0,
                   coverage={"spiral": 0.9, "ohm": 0.8 + 0.01 * index, "aoass": 0.95,
                             "aoass-adaptive": 0.95, "aoass-rule": 0.96}[k.method],
                   path_complete=int(k.method != "ohm" or index > 0), collisions_static=2,
                   collisions_moving=1,
                   energy_total={"spiral": 1000.0, "aoass-adaptive": 700.0,
                                 "aoass-rule": 800.0 if k.obstacle_density <= 0.5 else 2000.0
                                 }.get(k.method, 1.0))
        out.append(row)
    return out


@pytest.fixture(scope="module")
def values():
    rows = {name: preset_rows("fig2" if name == "quick" else name, ENERGY, RMSE)
            for name in make_results.FIGURE}
    rows["robustness"] = robustness_rows(2)
    runs = {name: [{"finished": 10, "wall_seconds": 30.0, "backend": "2 local processes"}]
            for name in make_results.SEEDS}
    figures = {name: f"figures/results_{name}.png" for name in make_results.FIGURE}
    seeds = {"quick": 1, "fig2": 2, "fig3": 2, "fig4": 2, "robustness": 2}
    return make_results.page_values(rows, runs, seeds, figures)


def test_the_template_gets_every_value(values):
    page = string.Template(make_results.TEMPLATE.read_text()).substitute(values)
    assert "$" not in page.replace("$$", "")
    assert values["table_fig3_200"] in page and values["table_fig4_60"] in page
    assert "## Robustness on freshly generated maps" in page
    assert values["robustness_tables"] in page


def test_the_page_names_the_blas_kernels_its_presets_record(tmp_path):
    """The episodes' last bits depend on the BLAS kernels (docs/evaluation.md): the page says
    which ones its presets ran with, per preset when they differ."""
    def record(name, **inputs):
        (tmp_path / name).mkdir(exist_ok=True)
        (tmp_path / name / INPUTS_FILE).write_text(json.dumps(inputs))

    record("fig2", **{BLAS_KERNELS: "openblas SkylakeX", "policy": "aaa"})
    record("fig4", **{BLAS_KERNELS: "openblas SkylakeX"})
    assert make_results.kernels_text(tmp_path, ["fig2", "fig4"]) == "`openblas SkylakeX`"
    record("fig3", policy="aaa")                            # an older evaluate.py's folder
    record("quick", **{BLAS_KERNELS: "openblas Haswell"})
    assert make_results.kernels_text(tmp_path, ["fig2", "fig3", "quick"]) == (
        "`fig2` `openblas SkylakeX`; `fig3` `not recorded`; `quick` `openblas Haswell`")
    (tmp_path / "fig4" / INPUTS_FILE).write_text("{")
    with pytest.raises(SystemExit, match=r"fig4/inputs.json is unreadable"):
        make_results.kernels_text(tmp_path, ["fig4"])


def test_robustness_section_is_computed_from_its_episodes(values):
    text = values["robustness_text"]
    assert "5 methods, each on 2 freshly generated maps per density" in text
    assert "(0.1, 0.2, 0.3, 0.4, 0.5, 0.6; 12 maps in all), 100 m field, N = 100" in text
    assert "20261117" in text and "710000" in text and "s = 0 … 1" in text
    # the methods without episodes are named (the rows hold the spiral, OHM and the AOASS
    # policies and rule only)
    assert "**Not run for this page:** AOASS, zero action (ablation), SCAN," in text
    assert "Square spiral," not in text and "OHM," not in text and "adaptive rule," not in text
    tables = values["robustness_tables"]
    ohm = [line for line in tables.splitlines() if line.startswith("| OHM")]
    assert len(ohm) == 1 + 6                         # the overview and one row per density
    # OHM: 80 % and 81 % against the spiral's 90 %: gaps -10 and -9 points; 1 of 2 ended
    assert "| 50% | 80.5% ± 6.4% | -9.5 ± 6.4 | 80.0% | 2.0 ± 0.0 | 1.0 ± 0.0 | 2 |" in ohm[1]
    assert ohm[0].count("-9.5 ± 6.4 (50%)") == 6


def test_robustness_not_run_says_so(values):
    rows = {name: preset_rows("fig2" if name == "quick" else name, ENERGY, RMSE)
            for name in make_results.FIGURE}
    rows["robustness"] = None
    figures = {name: f"figures/results_{name}.png" for name in make_results.FIGURE}
    page_values = make_results.page_values(rows, {name: [] for name in make_results.SEEDS},
                                           make_results.SEEDS, figures)
    assert "Not run for this page" in page_values["robustness_text"]
    assert "--presets robustness" in page_values["robustness_text"]
    assert page_values["robustness_tables"] == ""
    page = string.Template(make_results.TEMPLATE.read_text()).substitute(page_values)
    assert "Not run for this page" in page


def test_only_the_chosen_presets_run(monkeypatch, tmp_path):
    ran = []
    monkeypatch.setattr(make_results, "run_presets",
                        lambda out, seeds, workers: ran.append(dict(seeds)))
    with pytest.raises(SystemExit, match="quick"):       # the other folders are missing
        make_results.main(["--presets", "fig4", "robustness", "--out", str(tmp_path)])
    assert ran == [{"fig4": 30, "robustness": make_results.SEEDS["robustness"]}]


def test_robustness_alone_rebuilds_only_its_section(monkeypatch, tmp_path):
    """With only --presets robustness and the other presets' episodes missing, the page of
    --out keeps everything but the robustness section, which names --out."""
    monkeypatch.setattr(make_results, "run_presets", lambda out, seeds, workers: None)
    out = tmp_path / "out"
    argv = ["--presets", "robustness", "--out", str(out)]
    with pytest.raises(SystemExit, match="results.md is missing"):
        make_results.main(argv)            # no page of that folder to rebuild a section of
    out.mkdir()
    page = out / "results.md"
    begin, end = make_results.SECTION
    page.write_text(f"# Results\nfig2 numbers\n{begin}\nold section\n{end}\ntail\n")
    assert make_results.main(argv) == 0
    text = page.read_text()
    assert text.startswith("# Results\nfig2 numbers\n") and text.endswith(f"{end}\ntail\n")
    assert "old section" not in text and "Not run for this page" in text
    assert f"{out.resolve().as_posix()}/robustness/episodes.csv" in text
    assert f"--presets robustness --out {out.resolve().as_posix()}" in text


def test_a_page_of_another_folder_is_written_there_and_names_it(values, tmp_path):
    """The committed page names docs/results-data; a page built from another --out is written
    into that folder with its figures, and every path and command on it names that folder."""
    data = make_results.DATA
    assert make_results.page_file(data) == make_results.PAGE
    assert make_results.figure_file("fig2", data).parent == make_results.FIGURES
    assert values["data"] == "docs/results-data" and values["out_flag"] == ""
    out = tmp_path / "mine"
    assert make_results.page_file(out) == out / "results.md"
    assert make_results.figure_file("fig2", out) == out / "figures" / "results_fig2.png"
    rows = {name: preset_rows("fig2" if name == "quick" else name, ENERGY, RMSE)
            for name in make_results.FIGURE}
    rows["robustness"] = None
    runs = {name: [] for name in make_results.SEEDS}
    page = make_results.page_text(rows, runs, out)
    shown = out.resolve().as_posix()
    assert "docs/results-data" not in page
    assert f"make_results.py --out {shown}\n" in page and f"`{shown}/<preset>/`" in page
    assert f"--presets robustness --out {shown}" in page
    assert "![Figure 2](figures/results_fig2.png)" in page


def test_replace_section_fills_the_template_part(values):
    begin, end = make_results.SECTION
    page = make_results.replace_section(f"head {begin} old {end} tail",
                                        make_results.TEMPLATE.read_text(), values)
    assert page.startswith(f"head {begin}") and page.endswith(f"{end} tail")
    assert values["robustness_tables"] in page and " old " not in page
    with pytest.raises(ValueError, match="page has no"):
        make_results.replace_section("no markers", make_results.TEMPLATE.read_text(), values)


def test_paper_table_verdicts_follow_the_numbers(values):
    lines = {line.split(" | ")[0].lstrip("| "): line for line in
             values["paper_table"].splitlines()[2:]}
    # AOASS RMSE: seeds 0.9 and 0.99 -> mean 0.945: target and stretch met
    assert "0.94 ± " in lines["AOASS RMSE, `fig2` grid"] or "0.95 ± " in lines[
        "AOASS RMSE, `fig2` grid"]
    assert "target met, stretch met" in lines["AOASS RMSE, `fig2` grid"]
    # coverage 98 %: target met, stretch missed
    assert "target met, stretch **missed**" in lines["AOASS coverage, `fig2` grid"]
    # energy 1050 J against FDPP 630 J (67 % more: missed) and OHM 1260 J (17 % less: met)
    fdpp = lines["AOASS energy against FDPP (reconstructed)"]
    assert "1050 J against 630 J: 67 % more" in fdpp and "**missed**" in fdpp
    ohm = lines["AOASS energy against OHM (reconstructed)"]
    assert "17 % less" in ohm and "target (lower E_total) met" in ohm
    # OHM's RMSE (0.8) is below AOASS's: the paper's ranking does not hold there
    assert "AOASS lower RMSE: **no**" in lines["OHM (reconstructed) RMSE / coverage"]
    assert "AOASS lower RMSE: yes" in lines["FDPP (reconstructed) RMSE / coverage"]
    path = lines["AOASS path against M-ANCHORO"]
    assert "33 % shorter" in path and "target (shorter) met" in path
    assert "AOASS lowest of the four: **no**" in lines["RMSE at 50 % obstacles"]
    assert any(k.startswith("AOASS RMSE at N = 600–1000, 200 m") for k in lines)


def test_values_count_episodes_and_wall_time(values):
    assert values["per_method_fig4"] == str(2 * 2)          # 2 densities x 2 seeds
    assert values["wall_fig4"].startswith(
        "36 episodes; 30 s of wall time on 2 local processes for 10 episode runs (the others")
    assert values["fig2_fdpp_energy_total"] == "630"
    assert math.isclose(float(values["fig2_aoass_dvhop"]), 10.0)
    # 3 s per episode (2 s simulation + 2 x 0.5 s localization); at 30 seeds instead of 2:
    # (360 fig2 + 180 fig3 + 36 fig4 episodes) x 3 s x 15 = 25920 s = 7.2 h
    assert values["cpu_hours_30"] == "7"


def test_issue_table_verdicts_follow_the_numbers(values):
    lines = values["issue_table"].splitlines()[2:]
    rows = {line.split(" | ")[0].lstrip("| "): line for line in lines}
    # fig2: every coverage 98 %: below 98.5 % for both
    assert "policy **missed**, rule **missed**" in rows["coverage ≥ 98.5 %, `fig2` grid"]
    # RMSE: policy 0.9 and 0.99 (mean 0.945), rule 0.8 and 0.88 (0.84)
    assert "policy **missed**, rule met" in rows["RMSE ≤ 0.9 m (OLSTM-DV-Hop), `fig2` grid"]
    # E_total: policy 1050 J, rule 840 J; FDPP 630 J
    energy = rows["E_total ≤ 900 J, `fig2` grid"]
    assert "| 1050 J | 840 J | policy **missed**, rule met |" in energy
    stretch = [line for key, line in rows.items() if key.startswith("stretch")]
    assert len(stretch) == 1 and "FDPP's (630 J here" in stretch[0]
    assert "policy **missed**, rule **missed**" in stretch[0]
    # paired: the policy spends 200 J more on seed 0 and 220 J on seed 1; same coverage
    paired = rows["learned against the rule, paired, `fig2`: E_total lower or equal"]
    assert "+210.0 ± " in paired and "**missed** (mean difference)" in paired
    assert "+0.00 ± 0.00 points" in rows["... and coverage within 0.5 point"]
    assert rows["... and coverage within 0.5 point"].endswith("| met |")
    # fig4: every sweep ended, 98 % coverage
    ended = rows["`fig4` (densities 0.5–0.6): ≥ 95 % of sweeps end by themselves"]
    assert "| 100.0 % | 100.0 % | policy met, rule met |" in ended
    # fresh maps at 0.1-0.5: the policy 700 J, the rule 800 J against the spiral's 1000 J
    fresh = [line for key, line in rows.items() if key.startswith("fresh maps (0.1–0.5): E")]
    assert len(fresh) == 1 and "| 0.700 × | 0.800 × | policy met, rule **missed** |" in fresh[0]
    # the policy covers 95 nodes of 100, the rule 96: one fewer per sweep
    nodes = [line for key, line in rows.items() if "no fewer nodes" in key]
    assert len(nodes) == 1 and "| -1.00 ± 0.00 |" in nodes[0] and "**missed**" in nodes[0]


@pytest.mark.parametrize(("value", "spec", "bounds", "shown"), [
    (98.496, ".1f", (98.5,), "98.496"),     # rounds onto the bound: more digits
    (98.55, ".1f", (98.5,), "98.55"),       # prints 98.5 (binary 98.5499...): above it
    (98.44, ".1f", (98.5,), "98.4"),        # already on its side
    (0.7304, ".3f", (0.73,), "0.7304"),
    (-0.004, "+.2f", (0.0,), "-0.004"),     # "-0.00" beside "lower or equal: met"
    (0.0, "+.1f", (0.0,), "+0.0"),          # on the bound itself: as it is
    (900.4, ".0f", (900.0,), "900.4"),
    (1.3, ".2f", (1.3, 1.0), "1.30"),
    (1.2999999999, ".2f", (1.3,), "1.2999999999"),  # past six decimals: the exact value
    (-0.5000000000000001, "+.2f", (-0.5,), "-0.5000000000000001"),
    (-0.49999999999999994, "+.2f", (-0.5,), "-0.49999999999999994"),
    (0.7304, ".1%", (0.73,), "73.0%"),      # not a fixed-point spec: as it is
])
def test_fmt_prints_a_verdicts_number_on_its_side_of_the_bound(value, spec, bounds, shown):
    assert make_results._fmt(value, spec, bounds) == shown
    assert make_results._fmt(value, spec) == format(value, spec)


def test_verdict_cells_never_show_a_rounded_bound(values):
    """A mean just short of a target prints with the digits that show it short (the page
    once could show 98.5 % beside "missed")."""
    rows = preset_rows("fig2", ENERGY, RMSE)
    for row in rows:
        if row["method"] in ("aoass-adaptive", "aoass-rule"):
            row["coverage"] = 0.98496
    issue = make_results.issue_table(make_results.Numbers(rows), make_results.Numbers(rows), None)
    cov = [line for line in issue.splitlines() if line.startswith("| coverage ≥ 98.5 %")]
    assert cov == ["| coverage ≥ 98.5 %, `fig2` grid | 98.496 ± 0.0 % | 98.496 ± 0.0 % | "
                   "policy **missed**, rule **missed** |"]


def test_paired_table_and_fresh_energy(values):
    paired = values["paired_table"].splitlines()
    fig2 = [line for line in paired if line.startswith(
        "| learned against the rule, its zero action: AOASS, adaptive policy − AOASS, adaptive "
        "rule | `fig2` |")]
    # 200 and 220 J more; path (1000 - 800) / 0.8 = 250 m on both seeds; RMSE 0.1 and 0.11 m
    assert len(fig2) == 1
    assert "| +210 ± 3 | +250 ± 0 |" in fig2[0] and "| +0.105 ± 0.002 |" in fig2[0]
    # the robustness preset has no RMSE, and its rows pair on every one of its episodes
    robust = [line for line in paired if "`robustness`" in line and "adaptive policy −" in line]
    assert len(robust) == 1 and "| – |" in robust[0] and robust[0].endswith("| 12 |")
    assert "| -1.00 ± 0.00 |" in robust[0]
    energy = values["robustness_energy"].splitlines()
    assert energy[0].endswith("| d = 0.6 | d = 0.1–0.5 |")
    rule = [line for line in energy if line.startswith("| AOASS, adaptive rule |")]
    # 0.8 at 0.1-0.5, 2.0 at 0.6; the span leaves 0.6 out
    assert rule == ["| AOASS, adaptive rule | 0.800 | 0.800 | 0.800 | 0.800 | 0.800 | 2.000 | "
                    "0.800 |"]
    assert not any(line.startswith("| Square spiral") for line in energy)


def test_a_preset_takes_its_grid_alone_and_stops_on_a_missing_point(tmp_path):
    from aoass_env.evaluation.store import EpisodeStore

    def rows_of(preset: str, seeds: int) -> list[dict]:
        out = []
        for job in episode_jobs(PRESETS[preset], ["spiral"], ("dvhop",), seeds):
            row = dict.fromkeys(COLUMNS, 1.0)
            row.update(vars(job.key), localizer="dvhop", path_complete=1, beacons=5,
                       collisions=0, collisions_static=0, collisions_moving=0,
                       safety_intervention=math.nan)
            out.append(row)
        return out

    fig4, quick = rows_of("fig4", 2), rows_of("quick", 1)
    with EpisodeStore(tmp_path / "episodes.csv") as store:
        store.append(fig4 + quick)          # quick's rows in fig4's folder (docs allow it)
    # they used to be kept by seed alone and pooled into the fig4 verdicts
    kept = make_results.preset_rows(tmp_path, "fig4", 2)
    assert sorted(r["obstacle_density"] for r in kept) == sorted(
        r["obstacle_density"] for r in fig4)
    # a grid point without an episode used to build the page as if the grid were whole
    with EpisodeStore(tmp_path / "short" / "episodes.csv") as store:
        store.append(fig4[1:])
    with pytest.raises(SystemExit, match=rf"1 of the {len(fig4)} grid points of preset fig4 "
                                         rf"\(2 seeds\) have no episode"):
        make_results.preset_rows(tmp_path / "short", "fig4", 2)


def test_a_method_or_localizer_missing_at_some_points_stops_the_page(tmp_path):
    """Rows of every grid point, but one method lacking some of them (an interrupted sweep
    rebuilt with --skip-runs), or one localizer at one point: the page used to be built, the
    methods' means over different episodes (helper-44's reproduction: the adaptive policy over
    40 fig4 sweeps against 60 for the others)."""
    from aoass_env.evaluation.store import EpisodeStore

    full = []
    for job in episode_jobs(PRESETS["fig4"], ["spiral", "fdpp"], (), 2):
        for localizer in ("dvhop", "olstm-dvhop"):
            row = dict.fromkeys(COLUMNS, 1.0)
            row.update(vars(job.key), localizer=localizer, path_complete=1, beacons=5,
                       collisions=0, collisions_static=0, collisions_moving=0,
                       safety_intervention=math.nan)
            full.append(row)
    with EpisodeStore(tmp_path / "whole" / "episodes.csv") as store:
        store.append(full)
    assert len(make_results.preset_rows(tmp_path / "whole", "fig4", 2)) == len(full)
    short_method = [r for r in full if not (r["method"] == "fdpp" and r["seed"] == 1)]
    short_localizer = full[:-1]                      # the last point's last localizer row
    for folder, rows, named in (("method", short_method, "method fdpp,"),
                                ("localizer", short_localizer, "method fdpp, .* localizer "
                                                               "olstm-dvhop")):
        with EpisodeStore(tmp_path / folder / "episodes.csv") as store:
            store.append(rows)
        with pytest.raises(SystemExit, match=rf"episode rows of preset fig4 \(2 seeds\) are "
                                             rf"missing .* e\.g\. {named}"):
            make_results.preset_rows(tmp_path / folder, "fig4", 2)


def test_the_largest_fig3_rmse_skips_a_method_without_one(values):
    """A method with no finite RMSE (NaN) listed first used to win max() (NaN compares
    false): the page named it, with '– m', as the largest mean RMSE."""
    rows = {name: preset_rows("fig2" if name == "quick" else name, ENERGY, RMSE)
            for name in make_results.FIGURE}
    first = rows["fig3"][0]["method"]                   # the first method max() sees
    for r in rows["fig3"]:
        if r["method"] == first:
            r["rmse"] = math.nan
    rows["robustness"] = robustness_rows(2)
    runs = {name: [{"finished": 10, "wall_seconds": 30.0, "backend": "2 local processes"}]
            for name in make_results.SEEDS}
    figures = {name: f"figures/results_{name}.png" for name in make_results.FIGURE}
    seeds = {"quick": 1, "fig2": 2, "fig3": 2, "fig4": 2, "robustness": 2}
    got = make_results.page_values(rows, runs, seeds, figures)["fig3_worst_rmse"]
    assert got.startswith(make_results.label("fdpp")) and "–" not in got, got
    assert values["fig3_worst_rmse"].startswith(make_results.label("fdpp"))


def test_a_paired_cell_without_a_scale_prints_no_number():
    """Fresh maps of mixed node counts leave the nodes-per-sweep scale NaN: the cell printed
    '– ± nan'."""
    assert make_results._signed((2, 0.025, 0.035, 0.318), "+.2f", math.nan,
                                bounds=(0.0,)) == "–"
    assert make_results._signed((2, 0.025, 0.035, 0.318), "+.2f", 100.0) == "+2.50 ± 31.80"


def test_the_committed_page_is_what_its_committed_episodes_give():
    """docs/results.md is the template filled from the episodes committed beside it
    (docs/results-data): no number on the page was typed or edited by hand, and the template
    was not changed without rebuilding the page (``make_results.py --skip-runs``)."""
    rows, runs = make_results.read_presets(make_results.DATA)
    for name in make_results.FIGURE:
        assert make_results.figure_file(name).is_file(), name
    built = make_results.page_text(rows, runs)
    committed = make_results.PAGE.read_text(encoding="utf-8")
    if built != committed:     # name the first line that differs, not a 40 kB diff
        new, old = built.splitlines(), committed.splitlines()
        at = next((i for i, (a, b) in enumerate(zip(new, old, strict=False)) if a != b),
                  min(len(new), len(old)))
        pytest.fail(f"docs/results.md line {at + 1} is not what its episodes give: "
                    f"{old[at:at + 1]} against {new[at:at + 1]}; rebuild it with "
                    f"`python3 scripts/make_results.py --skip-runs`")


@pytest.mark.parametrize(("method", "density"), [("aoass", 0.4), ("fdpp", 0.1)])
def test_the_committed_episodes_replay_to_the_last_bit(method, density, tmp_path):
    """An episode of the committed quick preset, played again here, writes its committed lines
    of episodes.csv (timings aside): the safety stack's on the test map of density 0.4 and
    FDPP's on 0.1 are quick episodes that other OpenBLAS kernels move (docs/evaluation.md), so
    this holds only because evaluate.py ran them with the kernels the tests pin (Haswell, on an
    x86-64 machine with AVX2), whichever kernels the CPU would have picked itself."""
    folder = make_results.DATA / "quick"
    recorded = read_inputs(folder)[BLAS_KERNELS]
    if recorded != blas_kernels():
        pytest.skip(f"the quick preset was run with {recorded}; this machine has {blas_kernels()}")
    (job,) = [job for job in episode_jobs(PRESETS["quick"], [method], ())
              if job.key.obstacle_density == density]
    localizers = tuple(row["localizer"] for row in read_episodes(folder / "episodes.csv")
                       if row["method"] == method and row["obstacle_density"] == density)
    with EpisodeStore(tmp_path / "episodes.csv") as store:
        store.append(run_episode(job.key, localizers, RunOptions()))
    replayed = comparable_lines(tmp_path / "episodes.csv")
    assert len(replayed) == 1 + len(localizers) == 3         # the header and a row per localizer
    assert replayed <= comparable_lines(folder / "episodes.csv")


def test_rerun_drops_the_methods_episodes_before_the_run(monkeypatch, tmp_path):
    """--rerun M drops M's rows from the chosen presets' folders (the other methods' stay), then
    runs the presets; an unknown method is refused in one line naming the flag."""
    rows = [{k: int(v) if isinstance(v, float) and v.is_integer() else v for k, v in r.items()}
            for r in preset_rows("fig4", ENERGY, RMSE)]     # whole numbers as the CSV has them
    for name in ("fig4", "quick"):
        with make_results.EpisodeStore(tmp_path / name / "episodes.csv") as store:
            store.append(rows)

    def methods(preset: str) -> Counter:
        return Counter(r["method"] for r in
                       make_results.read_episodes(tmp_path / preset / "episodes.csv"))

    seen = []
    monkeypatch.setattr(make_results, "run_presets",
                        lambda out, seeds, workers: seen.append((dict(seeds), methods("fig4"))))
    with pytest.raises(SystemExit, match="quick"):   # the page then needs the other presets
        make_results.main(["--presets", "fig4", "--rerun", "spiral", "--out", str(tmp_path)])
    per_method = len(rows) // len(METHODS)
    assert seen == [({"fig4": 30}, Counter({m: per_method for m in METHODS if m != "spiral"}))]
    assert methods("quick") == Counter({m: per_method for m in METHODS})    # not chosen: kept
    with pytest.raises(SystemExit, match="--rerun: unknown method.*'spirl'.*valid:"):
        make_results.main(["--rerun", "spirl", "--out", str(tmp_path)])
