"""Regenerate docs/results.md: run the benchmark presets and fill the page's template.

Run: ``python3 scripts/make_results.py [--workers W] [--skip-runs | [--presets P ...]
[--rerun M ...]]``

1. Runs ``evaluate.py --preset P --seeds S`` for each preset of :data:`SEEDS` (or only those of
   ``--presets``) into ``docs/results-data/P`` (:data:`DATA`, committed with the page, so that
   the page can be checked and rebuilt without running an episode, and a regeneration that a
   session could not finish resumes on another machine whose OpenBLAS picks the same kernels,
   which ``inputs.json`` records: evaluate.py refuses to mix two kernels' episodes, and this
   script, which passes ``--discard-changed``, runs such a preset anew). The sweeps resume:
   episodes already in ``P/episodes.csv`` are not run again, so an interrupted regeneration
   continues where it stopped; the episodes of a method whose config defaults or checkpoints
   changed since they ran are dropped and run again (``--discard-changed``), those of the other
   methods kept; ``--rerun M ...`` drops the episodes of methods whose code changed (no
   digest sees that).
2. Reads the episodes back (only the seeds of :data:`SEEDS`, so a folder that holds more seeds
   gives the same page; the figures are drawn from the same rows) and the wall times that
   ``evaluate.py`` recorded in ``P/runs.jsonl``. The ``robustness`` preset is optional: a
   page built without its folder says that it was not run.
3. Draws the figures to ``docs/figures/results_<preset>.png`` and writes docs/results.md from
   ``scripts/results_template.md``: every ``$name`` there is a table, a figure's path or a
   number computed here (:func:`page_values`), so no number on the page is typed by hand
   (tests/scripts/test_make_results.py rebuilds the page's text from :data:`DATA` and checks
   that it is the committed page). With ``--out`` another folder, the page and its figures are
   written into that folder (``results.md``, ``figures/``) and name it: docs/results.md is
   only ever the page of :data:`DATA`.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import re
import string
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

# evaluate.py pins OpenBLAS's kernels on import, which must come before anything loads NumPy:
# the presets run in this process (cli.main), with the kernels evaluate.py runs them with
# (hence the late imports below)
_EVALUATE = importlib.util.spec_from_file_location(
    "aoass_evaluate_script", Path(__file__).resolve().parent.parent / "evaluate.py")
_EVALUATE.loader.exec_module(importlib.util.module_from_spec(_EVALUATE))

from aoass_env.atomic import atomic_open, write_text_atomic  # noqa: E402
from aoass_env.config import AOASSConfig  # noqa: E402
from aoass_env.evaluation import cli  # noqa: E402
from aoass_env.evaluation.episode import ROBUSTNESS_MAP_SEED  # noqa: E402
from aoass_env.evaluation.methods import METHODS, select_methods  # noqa: E402
from aoass_env.evaluation.report import (  # noqa: E402
    draw_figures,
    label,
    method_stats,
    method_table,
    paired_ratio,
    paired_stats,
    robustness_markdown,
)
from aoass_env.evaluation.store import (  # noqa: E402
    BLAS_KERNELS,
    EpisodeStore,
    EvaluationError,
    in_key_order,
    read_episodes,
    read_inputs,
    read_runs,
)
from aoass_env.evaluation.sweep import PRESETS, ROBUSTNESS_EPISODE_SEED_BASE, episode_jobs  # noqa: E402
from aoass_env.validators import argparse_number  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TEMPLATE = Path(__file__).with_name("results_template.md")
PAGE = ROOT / "docs" / "results.md"
FIGURES = ROOT / "docs" / "figures"
#: The presets' episodes behind the page, one folder per preset (``evaluate.py``'s output).
DATA = ROOT / "docs" / "results-data"


def _shown(path: Path) -> str:
    """``path`` as the page names it: relative to the repository's root when inside it."""
    path = path.resolve()
    return path.relative_to(ROOT).as_posix() if path.is_relative_to(ROOT) else path.as_posix()


def page_file(out: Path) -> Path:
    """The page built from the presets' folder ``out``: docs/results.md for :data:`DATA`,
    ``out/results.md`` for any other folder (the committed page names its data; a page built
    from other episodes is written beside them, naming them)."""
    return PAGE if out.resolve() == DATA else out / "results.md"


def figure_file(name: str, out: Path = DATA) -> Path:
    """Where the figure of preset ``name`` (:data:`FIGURE`) of the page of ``out`` is drawn:
    docs/figures for :data:`DATA`, ``out/figures`` for any other folder."""
    folder = FIGURES if out.resolve() == DATA else out / "figures"
    return folder / f"results_{name}.png"


def _out_flag(out: Path) -> str:
    """The ``--out`` a command on the page of ``out`` needs (none for :data:`DATA`)."""
    return "" if out.resolve() == DATA else f" --out {_shown(out)}"


#: Seeds per grid point of each preset on the page (the presets' default is 30 for the figures'
#: grids, 50 maps per density for robustness; see the page).
SEEDS = {"quick": 1, "fig2": 15, "fig3": 10, "fig4": 30, "robustness": 50}
#: The figure of each preset that the page shows (robustness has tables only).
FIGURE = {"quick": "fig2.png", "fig2": "fig2.png", "fig3": "fig3.png", "fig4": "fig4.png"}
#: Presets whose section says "not run" when their episodes are missing (the others are needed).
OPTIONAL = ("robustness",)
#: The markers around the robustness section in the template and on the page: with only
#: ``--presets robustness`` and the other presets' episodes missing, only that section of the
#: page is rebuilt.
SECTION = ("<!-- robustness: begin -->", "<!-- robustness: end -->")

Rows = list[dict[str, Any]]

#: The page's AOASS: the adaptive TD3-LSTM policy (issue 19), its zero action (the hand-written
#: rule), and the residual policy with its zero action, kept as the ablation.
AOASS, RULE, RESIDUAL, ZERO = "aoass-adaptive", "aoass-rule", "aoass", "aoass-scripted"
#: The paired comparisons of the page (method, reference, what the pair shows).
PAIRS = ((AOASS, RULE, "learned against the rule, its zero action"),
         (RULE, "spiral", "the rule against the plain spiral"),
         (RESIDUAL, ZERO, "the residual policy against its zero action"))
#: The densities of issue 19's fresh-map targets.
FRESH_DENSITIES = (0.1, 0.2, 0.3, 0.4, 0.5)


def run_presets(out: Path, seeds: dict[str, int], workers: int | None) -> None:
    """``evaluate.py`` for every preset (resumable); exits with its status if one fails."""
    for preset, n in seeds.items():
        argv = ["--preset", preset, "--seeds", str(n), "--out", str(out / preset),
                "--discard-changed", "--no-progress"] + (
                    ["--workers", str(workers)] if workers else [])
        print(f"== evaluate.py {' '.join(argv)}", flush=True)
        status = cli.main(argv)
        if status != 0:
            sys.exit(f"evaluate.py {' '.join(argv)} exited with {status}; fix it and run "
                     f"this script again (finished episodes are kept)")


def drop_methods(out: Path, presets: list[str], methods: list[str]) -> None:
    """Drop the episodes of ``methods`` from the folders of ``presets`` in ``out`` (each file
    rewritten atomically), so that the presets' next run plays them again after a change of
    the methods' code (``--discard-changed`` does it for a changed config default or
    checkpoint, which ``inputs.json`` records; no digest records the code); exits naming an
    unknown method."""
    try:
        select_methods(methods)
    except EvaluationError as exc:
        sys.exit(f"--rerun: {exc}")
    for preset in presets:
        path = out / preset / "episodes.csv"
        if not path.is_file():
            continue
        with EpisodeStore(path) as store:
            before = len(store.rows)
            store.discard(lambda row: row["method"] in methods)
        print(f"--rerun: dropped {before - len(store.rows)} rows of {', '.join(methods)} from "
              f"{path}", flush=True)


def _side(value: float, bound: float) -> int:
    return int(value > bound) - int(value < bound)


def _fmt(value: float, spec: str, bounds: tuple[float, ...] = ()) -> str:
    """``value`` formatted by ``spec`` ('–' when not finite); with ``bounds`` (the values a
    verdict beside it compares ``value`` with, in the printed unit), a fixed-point ``spec``
    (``.Nf`` or ``+.Nf``; other specs are printed as they are) gets more decimals, up to 6,
    until the printed number lies on the same side of each bound as ``value``, and past that
    the shortest text that reads back as ``value`` itself: 98.496 against 98.5 prints 98.496,
    never a 98.5 beside "missed"."""
    if not math.isfinite(value):
        return "–"
    text = format(value, spec)
    fixed = re.fullmatch(r"([+]?)\.(\d+)f", spec)
    if not fixed:
        return text
    sign, digits = fixed.group(1), int(fixed.group(2))

    def wrong(shown: str) -> bool:
        return any(_side(float(shown), b) != _side(value, b) for b in bounds)

    while wrong(text) and digits < 6:
        digits += 1
        text = format(value, f"{sign}.{digits}f")
    if wrong(text):
        text = repr(float(value))
        if sign and not text.startswith("-"):
            text = "+" + text
    return text


class Numbers:
    """Per-method means and 95 % CIs of one preset's rows (optionally filtered)."""

    def __init__(self, rows: Rows) -> None:
        self.rows = rows

    def where(self, **match: Any) -> Numbers:
        return Numbers([r for r in self.rows if all(r[k] == v for k, v in match.items())])

    def stat(self, method: str, metric: str) -> tuple[int, float, float, float]:
        return method_stats(self.rows, metric).get(method, (0, math.nan, math.nan, math.nan))

    def mean(self, method: str, metric: str) -> float:
        return self.stat(method, metric)[1]

    def rmse(self, method: str, bounds: tuple[float, ...] = ()) -> str:
        """'mean ± CI m over P % of nodes' (OLSTM-DV-Hop); ``bounds`` (m) as :func:`_fmt`."""
        _, mean, _, ci = self.stat(method, "rmse")
        share = self.mean(method, "localized")
        ci_text = "" if not math.isfinite(ci) else f" ± {ci:.2f}"
        return (f"{_fmt(mean, '.2f', bounds)}{ci_text} m over {_fmt(100 * share, '.0f')} % of "
                f"nodes")

    def coverage(self, method: str, bounds: tuple[float, ...] = ()) -> str:
        """'mean ± CI %'; ``bounds`` (fractions) as :func:`_fmt`."""
        _, mean, _, ci = self.stat(method, "coverage")
        ci_text = "" if not math.isfinite(ci) else f" ± {100 * ci:.1f}"
        return f"{_fmt(100 * mean, '.1f', tuple(100 * b for b in bounds))}{ci_text} %"


def _relative(a: float, b: float, less: str = "less", more: str = "more") -> str:
    """'x % less' / 'x % more' of a against b (or the words given)."""
    change = 100.0 * (a / b - 1.0)
    return f"{abs(change):.0f} % {less if change < 0 else more}"


def _met(ok: bool) -> str:
    return "met" if ok else "**missed**"


def _yes(ok: bool) -> str:
    return "yes" if ok else "**no**"


def paper_table(fig2: Numbers, fig3: Numbers, fig4: Numbers) -> str:
    """The paper's claims beside this project's measurements, with a verdict per row (AOASS:
    the adaptive policy, :data:`AOASS`)."""
    a = AOASS
    lines = ["| quantity | paper | this project (measured, OLSTM-DV-Hop) | agree? |",
             "|---|---|---|---|"]

    def row(quantity: str, paper: str, measured: str, verdict: str) -> None:
        lines.append(f"| {quantity} | {paper} | {measured} | {verdict} |")

    rmse = fig2.mean(a, "rmse")
    row("AOASS RMSE, `fig2` grid", "≈ 1.3 m (target ≤ 1.3 m, stretch 1.0 m)",
        f"{fig2.rmse(a, (1.3, 1.0))} (rule {fig2.rmse(RULE)}; residual policy "
        f"{fig2.rmse(RESIDUAL)})",
        f"target {_met(rmse <= 1.3)}, stretch {_met(rmse <= 1.0)}")
    cov = fig2.mean(a, "coverage")
    row("AOASS coverage, `fig2` grid", "≈ 97 % (target ≥ 97 %, stretch 99 %)",
        f"{fig2.coverage(a, (0.97, 0.99))} (rule {fig2.coverage(RULE)}; residual policy "
        f"{fig2.coverage(RESIDUAL)})",
        f"target {_met(cov >= 0.97)}, stretch {_met(cov >= 0.99)}")
    for method, paper in (("fdpp", "≈ 1.9 m / 91 %"), ("m-anchoro", "≈ 1.8 m / 93 %"),
                          ("ohm", "≈ 2.35 m / 90 %")):
        better_rmse = rmse < fig2.mean(method, "rmse")
        better_cov = cov > fig2.mean(method, "coverage")
        row(f"{label(method)} RMSE / coverage", paper,
            f"{fig2.rmse(method)} / {fig2.coverage(method)}",
            f"AOASS lower RMSE: {_yes(better_rmse)}; higher coverage: {_yes(better_cov)}")
    energy = fig2.mean(a, "energy_total")
    for method, paper in (("fdpp", "25–30 % less than FDPP"), ("ohm", "≈ 40 % less than OHM")):
        other = fig2.mean(method, "energy_total")
        row(f"AOASS energy against {label(method)}", paper,
            f"{energy:.0f} J against {other:.0f} J: {_relative(energy, other)}",
            f"target (lower E_total) {_met(energy < other)}")
    path, other = fig2.mean(a, "path_length"), fig2.mean("m-anchoro", "path_length")
    row("AOASS path against M-ANCHORO", "14 % shorter",
        f"{path:.0f} m against {other:.0f} m: {_relative(path, other, 'shorter', 'longer')}",
        f"target (shorter) {_met(path < other)}")
    for size in sorted({r["field_size"] for r in fig3.rows}):
        part = fig3.where(field_size=size)
        rm = part.mean(a, "rmse")
        row(f"AOASS RMSE at N = 600–1000, {size:g} m field", "1.5–1.7 m", part.rmse(a, (1.7,)),
            f"within or below the paper's: {_yes(rm <= 1.7)}")
    for density in sorted({r["obstacle_density"] for r in fig4.rows}):
        part = fig4.where(obstacle_density=density)
        rm = part.mean(a, "rmse")
        others = ", ".join(f"{label(m).split(' ')[0]} {_fmt(part.mean(m, 'rmse'), '.2f')} m"
                           for m in ("fdpp", "m-anchoro", "ohm"))
        lowest = all(rm < part.mean(m, "rmse") for m in ("fdpp", "m-anchoro", "ohm"))
        row(f"RMSE at {100 * density:.0f} % obstacles",
            "AOASS 1.6–1.8 m; FDPP, M-ANCHORO 2.5–3.0 m; OHM ≈ 3.2 m",
            f"AOASS {part.rmse(a)}; {others}",
            f"AOASS lowest of the four: {_yes(lowest)}")
    e4, f4 = fig4.mean(a, "energy_total"), fig4.mean("fdpp", "energy_total")
    row("AOASS energy against FDPP at 50–60 % obstacles", "20–25 % less",
        f"{e4:.0f} J against {f4:.0f} J: {_relative(e4, f4)}", _yes(e4 < f4))
    return "\n".join(lines)


def _signed(stat: tuple[int, float, float, float], spec: str, scale: float = 1.0,
            bounds: tuple[float, ...] = ()) -> str:
    """'+mean ± CI' of a :func:`paired_stats` tuple, times ``scale`` ('–' without a pair);
    ``bounds`` (scaled) as :func:`_fmt`."""
    n, mean, _, ci = stat
    if n == 0 or not math.isfinite(scale * mean):
        return "–"
    ci_text = ("" if not math.isfinite(scale * ci)
               else f" ± {format(scale * ci, spec.lstrip('+'))}")
    return f"{_fmt(scale * mean, spec, bounds)}{ci_text}"


def paired_table(presets: dict[str, Rows | None]) -> str:
    """The paired comparisons of :data:`PAIRS` on every preset's episodes: the mean difference
    method − reference over the episodes both played, ± 95 % CI."""
    lines = ["| comparison | preset | E_total [J] | path [m] | time [s] | coverage [points] | "
             "RMSE OLSTM-DV-Hop [m] | contacts | n |", "|---|---|---|---|---|---|---|---|---|"]
    for method, reference, what in PAIRS:
        for name, rows in presets.items():
            if not rows:
                continue
            cells = [_signed(paired_stats(rows, method, reference, metric), spec, scale)
                     for metric, spec, scale in (
                         ("energy_total", "+.0f", 1.0), ("path_length", "+.0f", 1.0),
                         ("travel_time", "+.0f", 1.0), ("coverage", "+.2f", 100.0),
                         ("rmse", "+.3f", 1.0), ("collisions", "+.2f", 1.0))]
            n = paired_stats(rows, method, reference, "energy_total")[0]
            lines.append(f"| {what}: {label(method)} − {label(reference)} | `{name}` | "
                         + " | ".join(cells) + f" | {n} |")
    return "\n".join(lines)


def fresh_energy(rows: Rows, method: str, densities: tuple[float, ...] = FRESH_DENSITIES
                 ) -> tuple[int, float]:
    """(pairs, ``method``'s E_total / the plain spiral's) on the episodes of ``densities``."""
    return paired_ratio([r for r in rows if r["obstacle_density"] in densities], method,
                        "spiral")


def energy_table(rows: Rows) -> str:
    """E_total of every method as a share of the plain spiral's on the same episodes (ratio of
    the sums), per density and over :data:`FRESH_DENSITIES` (issue 19's fresh-map target)."""
    densities = sorted({r["obstacle_density"] for r in rows})
    methods = [m for m in dict.fromkeys(r["method"] for r in rows) if m != "spiral"]
    span = f"{FRESH_DENSITIES[0]:.1f}–{FRESH_DENSITIES[-1]:.1f}"
    lines = ["| method | " + " | ".join(f"d = {d:.1f}" for d in densities)
             + f" | d = {span} |", "|---|" + "---|" * (len(densities) + 1)]
    for method in [m for m in METHODS if m in methods]:
        cells = [_fmt(fresh_energy(rows, method, (d,))[1], ".3f") for d in densities]
        lines.append(f"| {label(method)} | " + " | ".join(cells)
                     + f" | {_fmt(fresh_energy(rows, method)[1], '.3f')} |")
    return "\n".join(lines)


def issue_table(fig2: Numbers, fig4: Numbers, robustness: Rows | None) -> str:
    """Issue 19's targets (docs/adaptive.md) against the adaptive policy and the rule, with a
    verdict per row."""
    lines = ["| target (issue 19) | adaptive policy | adaptive rule | verdict |",
             "|---|---|---|---|"]

    def row(target: str, policy: str, rule: str, verdict: str) -> None:
        lines.append(f"| {target} | {policy} | {rule} | {verdict} |")

    def both(values: dict[str, float], ok: Callable[[float], bool]) -> str:
        return f"policy {_met(ok(values[AOASS]))}, rule {_met(ok(values[RULE]))}"

    def means(numbers: Numbers, metric: str) -> dict[str, float]:
        return {m: numbers.mean(m, metric) for m in (AOASS, RULE)}

    row("coverage ≥ 98.5 %, `fig2` grid", fig2.coverage(AOASS, (0.985,)),
        fig2.coverage(RULE, (0.985,)),
        both(means(fig2, "coverage"), lambda v: v >= 0.985))
    row("RMSE ≤ 0.9 m (OLSTM-DV-Hop), `fig2` grid", fig2.rmse(AOASS, (0.9,)),
        fig2.rmse(RULE, (0.9,)),
        both(means(fig2, "rmse"), lambda v: v <= 0.9))
    energy = {m: fig2.mean(m, "energy_total") for m in (AOASS, RULE, "fdpp")}
    row("E_total ≤ 900 J, `fig2` grid", f"{_fmt(energy[AOASS], '.0f', (900.0,))} J",
        f"{_fmt(energy[RULE], '.0f', (900.0,))} J",
        both(energy, lambda v: v <= 900.0))
    row(f"stretch: E_total ≤ FDPP's ({energy['fdpp']:.0f} J here; 621 J in the issue)",
        f"{_fmt(energy[AOASS], '.0f', (energy['fdpp'],))} J",
        f"{_fmt(energy[RULE], '.0f', (energy['fdpp'],))} J",
        both(energy, lambda v: v <= energy["fdpp"]))
    d_energy = paired_stats(fig2.rows, AOASS, RULE, "energy_total")
    d_cov = paired_stats(fig2.rows, AOASS, RULE, "coverage")
    row("learned against the rule, paired, `fig2`: E_total lower or equal",
        f"{_signed(d_energy, '+.1f', bounds=(0.0,))} J", "–",
        f"{_met(d_energy[1] <= 0.0)} (mean difference)")
    row("... and coverage within 0.5 point",
        f"{_signed(d_cov, '+.2f', 100.0, bounds=(-0.5,))} points", "–",
        _met(d_cov[1] >= -0.005))
    for metric, target, bound in (("path_complete", "≥ 95 % of sweeps end by themselves", 0.95),
                                  ("coverage", "coverage ≥ 90 %", 0.90)):
        values = means(fig4, metric)
        row(f"`fig4` (densities 0.5–0.6): {target}",
            f"{_fmt(100 * values[AOASS], '.1f', (100 * bound,))} %",
            f"{_fmt(100 * values[RULE], '.1f', (100 * bound,))} %",
            both(values, lambda v, b=bound: v >= b))
    span = f"{FRESH_DENSITIES[0]:.1f}–{FRESH_DENSITIES[-1]:.1f}"
    if not robustness:
        row(f"fresh maps, densities {span}", "not run", "not run", "–")
        return "\n".join(lines)
    fresh = [r for r in robustness if r["obstacle_density"] in FRESH_DENSITIES]
    ratio = {m: fresh_energy(robustness, m)[1] for m in (AOASS, RULE)}
    row(f"fresh maps ({span}): E_total ≤ 0.73 × the plain spiral's (ratio of sums, paired)",
        f"{_fmt(ratio[AOASS], '.3f', (0.73,))} ×", f"{_fmt(ratio[RULE], '.3f', (0.73,))} ×",
        both(ratio, lambda v: v <= 0.73))
    nodes = [r["n_nodes"] for r in fresh]
    scale = float(nodes[0]) if len(set(nodes)) == 1 else math.nan
    d_nodes = paired_stats(fresh, AOASS, RULE, "coverage")
    row(f"fresh maps ({span}): the policy covers no fewer nodes than its zero action (the "
        f"rule), nodes per sweep", _signed(d_nodes, "+.2f", scale, bounds=(0.0,)), "–",
        f"{_met(d_nodes[1] >= 0.0)} (mean difference)")
    return "\n".join(lines)


def _wall(name: str, rows: Rows, runs: list[dict[str, Any]], data: Path = DATA) -> str:
    """How long the preset took: the episodes on the page, and the wall time and episode runs
    that evaluate.py recorded for its folder in ``data`` (`runs.jsonl`)."""
    episodes = len({(r["method"], r["map"], r["n_nodes"], r["seed"]) for r in rows})
    timed = sum(r.get("finished", 0) for r in runs)
    seconds = sum(r.get("wall_seconds", 0.0) for r in runs)
    where = " / ".join(sorted({str(r.get("backend")) for r in runs if r.get("finished")}))
    if not timed:
        return f"{episodes} episodes (no wall time recorded)"
    text = f"{episodes} episodes; {seconds:.0f} s of wall time on {where} for {timed} episode runs"
    if timed < episodes:
        text += (f" (the others ran before evaluate.py recorded its runs in "
                 f"`{_shown(data / name / 'runs.jsonl')}`)")
    return text


def robustness_values(rows: Rows | None, runs: list[dict[str, Any]], seeds: int,
                      data: Path = DATA) -> dict[str, str]:
    """``$robustness_text`` (how the maps and seeds were made, the preset's wall time) and
    ``$robustness_tables`` of the page of the presets' folder ``data``; ``rows`` None or
    empty: the preset was not run."""
    name = "robustness"
    command = f"python3 scripts/make_results.py --presets robustness{_out_flag(data)}"
    if not rows:
        return {"robustness_text": f"**Not run for this page**: "
                                   f"`{_shown(data / name / 'episodes.csv')}` was "
                                   f"missing when it was built. `{command}` runs the preset "
                                   f"({seeds} maps per density) and rebuilds the page.",
                "robustness_tables": "", "robustness_energy": ""}
    maps = {(r["obstacle_density"], r["map"]) for r in rows}
    densities = sorted({d for d, _ in maps})
    per_density = sorted({sum(1 for d, _ in maps if d == density) for density in densities})
    count = (f"{per_density[0]}" if len(per_density) == 1
             else f"{per_density[0]}–{per_density[-1]}")
    methods = len({r["method"] for r in rows})
    sizes = " / ".join(f"{f:g}" for f in sorted({r["field_size"] for r in rows}))
    nodes = " / ".join(str(n) for n in sorted({r["n_nodes"] for r in rows}))
    text = (f"`python3 evaluate.py --preset {name} --seeds {seeds}` (`{command}` reruns it "
            f"alone and rebuilds this page): {_wall(name, rows, runs, data)}. {methods} methods, "
            f"each on {count} freshly generated maps per density "
            f"({', '.join(f'{d:.1f}' for d in densities)}; {len(maps)} maps in all), "
            f"{sizes} m field, N = {nodes}, not localized. Map s of density d is "
            f"`generate_map({sizes}, d, default_rng([{ROBUSTNESS_MAP_SEED}, round(100 d), s]), "
            f"clearance={AOASSConfig().map_clearance:g})` and the episode's random generator is "
            f"seeded with {ROBUSTNESS_EPISODE_SEED_BASE} + 1000 · round(100 d) + s, "
            f"s = 0 … {seeds - 1}: seeds used nowhere else in the project (not by the shipped "
            f"maps, the other presets or training). All methods play the same map with the "
            f"same nodes for the same (d, s), so the gap to the plain spiral is a paired "
            f"difference.")
    missing = [label(m) for m in select_methods(None) if m not in {r["method"] for r in rows}]
    if missing:
        text += (f" **Not run for this page:** {', '.join(missing)} (`{command}` runs them "
                 f"too; the preset resumes, so the episodes above are kept).")
    return {"robustness_text": text, "robustness_tables": robustness_markdown(rows, level=3),
            "robustness_energy": energy_table(rows)}


def kernels_text(data: Path, presets: list[str]) -> str:
    """The BLAS kernels the ``presets``' folders in ``data`` record in ``inputs.json``
    (evaluate.py's :data:`~aoass_env.evaluation.store.BLAS_KERNELS`), as the page states them:
    one name when every preset agrees, else each preset's; "not recorded" for a folder of an
    evaluate.py from before 2026-12-01. Exits naming an unreadable record."""
    found = {}
    for name in presets:
        try:
            found[name] = read_inputs(data / name).get(BLAS_KERNELS, "not recorded")
        except EvaluationError as exc:
            sys.exit(str(exc))
    if len(set(found.values())) == 1:
        return f"`{next(iter(found.values()))}`"
    return "; ".join(f"`{name}` `{kernels}`" for name, kernels in found.items())


def page_values(rows: dict[str, Rows | None], runs: dict[str, list[dict[str, Any]]],
                seeds: dict[str, int], figures: dict[str, str], data: Path = DATA
                ) -> dict[str, str]:
    """Every ``$name`` of the template from the presets' rows and recorded runs (the rows of
    an :data:`OPTIONAL` preset may be None: not run) in the presets' folder ``data``."""
    values: dict[str, str] = {
        "data": _shown(data), "out_flag": _out_flag(data),
        "paper_table": paper_table(Numbers(rows["fig2"]), Numbers(rows["fig3"]),
                                   Numbers(rows["fig4"])),
        "issue_table": issue_table(Numbers(rows["fig2"]), Numbers(rows["fig4"]),
                                   rows.get("robustness")),
        "paired_table": paired_table({name: rows.get(name) for name in
                                      ("fig2", "fig3", "fig4", "robustness")}),
        "blas_kernels": kernels_text(data, [n for n in SEEDS if rows.get(n) is not None])}
    values.update(robustness_values(rows.get("robustness"), runs.get("robustness", []),
                                    seeds.get("robustness", SEEDS["robustness"]), data))
    for name in FIGURE:
        values[f"seeds_{name}"] = str(seeds[name])
        values[f"wall_{name}"] = _wall(name, rows[name], runs[name], data)
        values[f"table_{name}"] = method_table(rows[name])
        values[f"figure_{name}"] = figures[name]
        per_method = Numbers(rows[name]).stat("spiral", "coverage")[0]
        values[f"per_method_{name}"] = str(per_method)
    splits: dict[str, tuple[str, Callable[[float], str]]] = {
        "fig3": ("field_size", lambda v: f"{v:g}"), "fig4": ("obstacle_density",
                                                           lambda v: f"{100 * v:.0f}")}
    for name, (column, key) in splits.items():
        for v in sorted({r[column] for r in rows[name]}):
            values[f"table_{name}_{key(v)}"] = method_table(
                [r for r in rows[name] if r[column] == v])
    cpu_seconds = 0.0
    for name in ("fig2", "fig3", "fig4"):     # the episode-seconds of 30 seeds, at this rate
        per = method_stats(rows[name], "seconds").values()
        cpu_seconds += sum(n * mean for n, mean, _, _ in per) * 30 / seeds[name]
    values["cpu_hours_30"] = f"{cpu_seconds / 3600:.0f}"
    fig2 = Numbers(rows["fig2"])
    seconds = method_stats(rows["fig2"], "seconds")
    values["fig2_seconds"] = ", ".join(f"{label(m)} {s[1]:.1f}" for m, s in seconds.items())
    for method in (AOASS, RULE, RESIDUAL, ZERO, "spiral", "fdpp", "ohm", "m-anchoro", "otpp"):
        key = method.replace("-", "_")
        values[f"fig2_{key}_rmse"] = fig2.rmse(method)
        values[f"fig2_{key}_contacts"] = _fmt(fig2.mean(method, "collisions"), ".1f")
        for metric, spec in (("energy_total", ".0f"), ("path_length", ".0f"),
                             ("travel_time", ".0f"), ("ideal_length", ".0f")):
            values[f"fig2_{key}_{metric}"] = _fmt(fig2.mean(method, metric), spec)
        values[f"fig2_{key}_coverage"] = f"{_fmt(100 * fig2.mean(method, 'coverage'), '.1f')} %"
        values[f"fig2_{key}_dvhop"] = _fmt(method_stats(rows["fig2"], "rmse", "dvhop").get(
            method, (0, math.nan))[1], ".1f")
    sizes = sorted({r["field_size"] for r in rows["fig3"]})
    # a method without a finite RMSE (NaN compares false) would win max() by coming first
    worst = max(((stat[1], method, size) for size in sizes for method, stat in method_stats(
        [r for r in rows["fig3"] if r["field_size"] == size], "rmse").items()
        if math.isfinite(stat[1])), default=(math.nan, "–", math.nan))
    values["fig3_worst_rmse"] = (f"{label(worst[1])}, {_fmt(worst[0], '.2f')} m on the "
                                 f"{worst[2]:g} m field")
    fig4 = Numbers(rows["fig4"])
    for method in (AOASS, RULE, RESIDUAL, ZERO, "spiral"):
        key = method.replace("-", "_")
        values[f"fig4_{key}_complete"] = _fmt(100 * fig4.mean(method, "path_complete"), ".0f")
        values[f"fig4_{key}_coverage"] = _fmt(100 * fig4.mean(method, "coverage"), ".1f")
        values[f"fig4_{key}_contacts"] = _fmt(fig4.mean(method, "collisions"), ".1f")
    return values


def replace_section(page: str, template: str, values: dict[str, str]) -> str:
    """``page`` with the text between the :data:`SECTION` markers rebuilt from that part of
    ``template`` and ``values``.

    Raises:
        ValueError: the page or the template lacks the markers."""
    parts = []
    for name, text in (("page", page), ("template", template)):
        begin, end = text.find(SECTION[0]), text.find(SECTION[1])
        if begin < 0 or end < begin:
            raise ValueError(f"the {name} has no {SECTION[0]} ... {SECTION[1]} section")
        parts.append((begin + len(SECTION[0]), end))
    (p0, p1), (t0, t1) = parts
    return page[:p0] + string.Template(template[t0:t1]).substitute(values) + page[p1:]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--workers", type=argparse_number(int, 1),
                        help="evaluate.py --workers (default: all cores)")
    parser.add_argument("--out", type=Path, default=DATA,
                        help=f"the presets' folders (default: {_shown(DATA)}, whose page is "
                             f"{_shown(PAGE)}; another folder's page and figures are written "
                             f"into it: results.md, figures/)")
    parser.add_argument("--skip-runs", action="store_true",
                        help="only rebuild the page from the episodes already in --out")
    parser.add_argument("--presets", nargs="+", choices=list(SEEDS), metavar="P",
                        help=f"run only these presets ({', '.join(SEEDS)}; default: all), then "
                             f"rebuild the page from every preset's folder")
    parser.add_argument("--rerun", nargs="+", metavar="M",
                        help="first drop these methods' episodes from the presets' folders, so "
                             "that they run again (after a change of their code)")
    args = parser.parse_args(argv)
    if args.skip_runs and (args.presets or args.rerun):
        parser.error("--skip-runs runs no preset; --presets and --rerun do not go with it")
    if not args.skip_runs:
        presets = args.presets or list(SEEDS)
        if args.rerun:
            drop_methods(args.out, presets, args.rerun)
        run_presets(args.out, {p: SEEDS[p] for p in presets}, args.workers)
    only_optional = bool(args.presets) and set(args.presets) <= set(OPTIONAL)
    if only_optional and any(not (args.out / name / "episodes.csv").is_file()
                             for name in SEEDS if name not in OPTIONAL):
        return _rebuild_section(args.out)       # rebuild the robustness section alone
    rows, runs = read_presets(args.out)
    for name in FIGURE:
        with tempfile.TemporaryDirectory() as tmp:
            drawn = {p.name: p for p in draw_figures(rows[name], Path(tmp))}
            figure = figure_file(name, args.out)
            figure.parent.mkdir(parents=True, exist_ok=True)
            with atomic_open(figure, "wb") as f:     # a kill leaves the old figure
                f.write(drawn[FIGURE[name]].read_bytes())
    page = page_file(args.out)
    write_text_atomic(page, page_text(rows, runs, args.out))
    print(f"wrote {page}")
    return 0


def read_presets(out: Path) -> tuple[dict[str, Rows | None], dict[str, list[dict[str, Any]]]]:
    """The rows (:func:`preset_rows`; None for an :data:`OPTIONAL` preset without episodes)
    and the recorded runs of every preset of :data:`SEEDS` in ``out``; exits naming the file
    when a needed preset's episodes are missing."""
    rows: dict[str, Rows | None] = {}
    runs = {}
    for name, n in SEEDS.items():
        folder = out / name
        runs[name] = [r for r in read_runs(folder) if r.get("preset") == name]
        if (folder / "episodes.csv").is_file():
            rows[name] = preset_rows(folder, name, n)
        elif name in OPTIONAL:
            rows[name] = None
        else:
            sys.exit(f"{folder / 'episodes.csv'} is missing: run this script without "
                     f"--skip-runs")
    return rows, runs


def page_text(rows: dict[str, Rows | None], runs: dict[str, list[dict[str, Any]]],
              out: Path = DATA) -> str:
    """The page of the presets' folder ``out`` (docs/results.md for :data:`DATA`) from the
    template and the presets' rows and runs (:func:`read_presets`), its figures at
    :func:`figure_file`."""
    page = page_file(out)
    figures = {name: figure_file(name, out).relative_to(page.parent).as_posix()
               for name in FIGURE}
    text = string.Template(TEMPLATE.read_text(encoding="utf-8")).substitute(
        page_values(rows, runs, SEEDS, figures, out))
    return text.rstrip("\n") + "\n"         # an empty last table leaves no blank tail


def preset_rows(folder: Path, name: str, n: int) -> Rows:
    """The rows of ``folder``'s episodes.csv that are episodes of preset ``name`` at ``n`` seeds
    (map, field, N, density and seed of one of its jobs; another preset's rows in the same
    folder are left out); exits naming the file when it cannot be read, when a grid point
    of the preset has no row, or when a method of the rows lacks a grid point or a localizer
    of the rows at one (an incomplete grid would be reported as the whole, and the methods
    compared over different episodes)."""
    path = folder / "episodes.csv"
    try:
        every = in_key_order(read_episodes(path))
    except EvaluationError as exc:
        sys.exit(str(exc))

    def point(key: Any) -> tuple[Any, ...]:
        return (key["map"], key["field_size"], key["n_nodes"], key["obstacle_density"],
                key["seed"])

    grid = {point(vars(job.key)) for job in episode_jobs(PRESETS[name], ["spiral"], (), n)}
    rows = [r for r in every if point(r) in grid]
    missing = sorted(grid - {point(r) for r in rows})
    if missing:
        sys.exit(f"{path}: {len(missing)} of the {len(grid)} grid points of preset {name} "
                 f"({n} seeds) have no episode, e.g. map {missing[0][0]}, N = {missing[0][2]}, "
                 f"seed {missing[0][4]}: run this script without --skip-runs")
    localizers = sorted({r["localizer"] for r in rows})
    have = {(r["method"], point(r), r["localizer"]) for r in rows}
    lacking = [(m, p, loc) for m in dict.fromkeys(r["method"] for r in rows)
               for p in sorted(grid) for loc in localizers if (m, p, loc) not in have]
    if lacking:
        method, (map_, _, nodes, _, seed), localizer = lacking[0]
        sys.exit(f"{path}: {len(lacking)} episode rows of preset {name} ({n} seeds) are missing "
                 f"where other methods or localizers have theirs, e.g. method {method}, map "
                 f"{map_}, N = {nodes}, seed {seed}, localizer {localizer}: run this script "
                 f"without --skip-runs")
    return rows


def _rebuild_section(out: Path) -> int:
    """Rebuild only the robustness section of ``out``'s page (:func:`page_file`) from
    ``out``'s robustness folder."""
    name, n = "robustness", SEEDS["robustness"]
    folder = out / name
    rows = preset_rows(folder, name, n) if (folder / "episodes.csv").is_file() else None
    runs = [r for r in read_runs(folder) if r.get("preset") == name]
    path = page_file(out)
    if not path.is_file():
        sys.exit(f"{path} is missing, so its robustness section cannot be rebuilt alone: run "
                 f"the other presets into {out} too (this script without --presets)")
    try:
        page = replace_section(path.read_text(encoding="utf-8"),
                               TEMPLATE.read_text(encoding="utf-8"),
                               robustness_values(rows, runs, n, out))
    except ValueError as exc:
        sys.exit(f"{path}: {exc}; rebuild the whole page (run this script without --presets)")
    write_text_atomic(path, page)
    print(f"rebuilt the robustness section of {path} (the other presets' episodes are not in "
          f"{out}; the rest of the page is kept)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
