"""Summary statistics, tables and figures from the rows of ``episodes.csv``.

* :func:`write_summary_csv`: per (method, localizer, field size, N, density): the episode count
  and the mean, standard deviation and 95 % confidence half-width (Student t) of every metric.
* :func:`summary_markdown`: readable tables, methods as rows, mean ± 95 % CI: all episodes
  together, then per value of each grid dimension that varies.
* :func:`draw_figures`: the paper's Figures 2-4 as PNG, each drawn only when episodes of its
  preset's grid are in the rows.
* :func:`robustness_stats` / :func:`robustness_markdown`: per obstacle density and method, the
  share of sweeps that ended by themselves, coverage and its paired gap to the plain spiral on
  the same episode, the worst coverage, static and moving contacts (the ``robustness`` preset).
* :func:`paired_stats` / :func:`paired_ratio`: one method against another on the episodes both
  played (same map, N and seed): the mean paired difference of a metric with its 95 % CI, and
  the ratio of a metric's sums (E_total against the plain spiral's).

Statistics use the finite values only: an episode in which no node was localized has no RMSE
(its localized fraction, 0, is still counted).
"""

from __future__ import annotations

import csv
import dataclasses
import io
import math
from collections import defaultdict
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats as st

from aoass_env.atomic import save_figure_atomic, write_text_atomic
from aoass_env.evaluation.methods import METHODS
from aoass_env.evaluation.store import (
    EPISODE_FIELDS,
    KEY_FIELDS,
    NO_LOCALIZER,
    EpisodeKey,
    row_key,
)
from aoass_env.evaluation.sweep import PRESETS

__all__ = ["REFERENCE_METHOD", "SUMMARY_METRICS", "bootstrap_interval", "ci_stats",
           "draw_figures", "method_stats", "method_table", "paired_ratio", "paired_stats",
           "robustness_markdown",
           "robustness_stats", "seconds_per_episode", "summary_markdown", "summarize",
           "write_summary_csv"]

#: Metrics of summary.csv: the localization columns, then the episode columns.
SUMMARY_METRICS = ("rmse", "localized", "localize_seconds") + EPISODE_FIELDS
GROUP_FIELDS = ("method", "localizer", "field_size", "n_nodes", "obstacle_density")
PRIMARY_LOCALIZER = "olstm-dvhop"
#: The method every other one is compared with on the same episode in the robustness tables.
REFERENCE_METHOD = "spiral"


def ci_stats(values: Iterable[float], level: float = 0.95) -> tuple[int, float, float, float]:
    """(n, mean, std, CI half-width) of the finite values: std with n - 1 degrees of freedom,
    half-width ``t_{(1+level)/2, n-1} * std / sqrt(n)``; NaN where undefined (n = 0, or n = 1
    for std and CI)."""
    v = np.asarray([x for x in values if x is not None and math.isfinite(x)], dtype=np.float64)
    n = len(v)
    if n == 0:
        return 0, math.nan, math.nan, math.nan
    if n == 1:
        return 1, float(v[0]), math.nan, math.nan
    std = float(v.std(ddof=1))
    return n, float(v.mean()), std, float(st.t.ppf((1 + level) / 2, n - 1) * std / math.sqrt(n))


def bootstrap_interval(values: Iterable[float], groups: Iterable[Any] | None = None,
                       level: float = 0.95, n_boot: int = 2000,
                       seed: int = 0) -> tuple[float, float, float]:
    """(mean, low, high): the mean of the finite values and its percentile bootstrap interval
    at ``level``, resampling within each of ``groups`` (e.g. the obstacle density: the design's
    strata) when given. A resampled mean lies between the smallest and the largest value, so
    the interval stays inside the metric's range (a ratio in [0, 1] keeps its interval there);
    NaN for no value, a zero-width interval for one. Seeded: the same data give the same
    interval."""
    vals = list(values)
    keys = [None] * len(vals) if groups is None else list(groups)
    if len(keys) != len(vals):
        raise ValueError(f"groups has {len(keys)} entries for {len(vals)} values")
    strata: dict[Any, list[float]] = defaultdict(list)
    for v, k in zip(vals, keys, strict=True):
        if v is not None and math.isfinite(v):
            strata[k].append(float(v))
    if not strata:
        return math.nan, math.nan, math.nan
    rng = np.random.default_rng(seed)
    total = np.zeros(n_boot)
    n = 0
    for members in strata.values():
        v = np.asarray(members)
        total += v[rng.integers(len(v), size=(n_boot, len(v)))].sum(axis=1)
        n += len(v)
    mean = sum(sum(m) for m in strata.values()) / n
    low, high = np.quantile(total / n, [(1 - level) / 2, (1 + level) / 2])
    return mean, float(min(low, mean)), float(max(high, mean))


def _error_bars(intervals: list[tuple[float, float, float]]) -> tuple[list[float], np.ndarray]:
    """Means and matplotlib's asymmetric ``yerr`` (2, n) of :func:`bootstrap_interval`
    results (no bar where undefined)."""
    means = [t[0] for t in intervals]
    err = np.array([[t[0] - t[1] for t in intervals], [t[2] - t[0] for t in intervals]])
    return means, np.nan_to_num(err)


def label(method: str) -> str:
    """A method's name in tables and figures."""
    return METHODS[method].label if method in METHODS else method


def _method_order(methods: Iterable[str]) -> list[str]:
    present = set(methods)
    return [m for m in METHODS if m in present] + sorted(present - set(METHODS))


def summarize(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Rows of summary.csv (one per group of :data:`GROUP_FIELDS`, in method order)."""
    groups: dict[tuple, list[dict[str, Any]]] = defaultdict(list)
    for r in rows:
        groups[tuple(r[k] for k in GROUP_FIELDS)].append(r)
    order = {m: i for i, m in enumerate(_method_order(r["method"] for r in rows))}
    out = []
    for group in sorted(groups, key=lambda g: (order[g[0]], *g[1:])):
        members = groups[group]
        entry: dict[str, Any] = {**dict(zip(GROUP_FIELDS, group, strict=True)),
                                 "label": label(group[0]), "n": len(members)}
        for metric in SUMMARY_METRICS:
            _, mean, std, ci = ci_stats(r[metric] for r in members)
            entry.update({f"{metric}_mean": mean, f"{metric}_std": std, f"{metric}_ci95": ci})
        out.append(entry)
    return out


def write_summary_csv(rows: list[dict[str, Any]], path: Path) -> None:
    """summary.csv of ``rows`` (empty cells where a statistic is undefined)."""
    columns = [*GROUP_FIELDS, "label", "n"] + [f"{m}_{s}" for m in SUMMARY_METRICS
                                               for s in ("mean", "std", "ci95")]
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for entry in summarize(rows):
        writer.writerow({k: "" if isinstance(v, float) and math.isnan(v) else v
                         for k, v in entry.items()})
    write_text_atomic(path, buf.getvalue())


def _episodes(rows: list[dict[str, Any]]) -> dict[EpisodeKey, dict[str, Any]]:
    """One record per episode: its episode columns, ``rmse:<localizer>`` and
    ``localized:<localizer>`` per localizer, and ``seconds`` (simulation + localizers)."""
    out: dict[EpisodeKey, dict[str, Any]] = {}
    for r in rows:
        ep = out.setdefault(row_key(r)[0], {**{k: r[k] for k in KEY_FIELDS + EPISODE_FIELDS},
                                  "seconds": r["wall_seconds"]})
        ep[f"rmse:{r['localizer']}"] = r["rmse"]
        ep[f"localized:{r['localizer']}"] = r["localized"]
        ep["seconds"] += r["localize_seconds"]
    return out


def _localizers(rows: list[dict[str, Any]]) -> list[str]:
    """The localizers in ``rows`` (not :data:`NO_LOCALIZER`), the primary one first."""
    present = [n for n in dict.fromkeys(r["localizer"] for r in rows) if n != NO_LOCALIZER]
    return sorted(present, key=lambda n: n != PRIMARY_LOCALIZER)


def method_stats(rows: list[dict[str, Any]], metric: str,
                 localizer: str = PRIMARY_LOCALIZER) -> dict[str, tuple[int, float, float, float]]:
    """:func:`ci_stats` of ``metric`` per method over the episodes in ``rows``: an episode
    column (``coverage``, ``energy_total``, ...), ``seconds``, or ``rmse`` / ``localized`` of
    ``localizer``."""
    key = f"{metric}:{localizer}" if metric in ("rmse", "localized") else metric
    per: dict[str, list[float]] = defaultdict(list)
    for ep in _episodes(rows).values():
        per[ep["method"]].append(ep.get(key, math.nan))
    return {m: ci_stats(per[m]) for m in _method_order(per)}


def seconds_per_episode(rows: list[dict[str, Any]]) -> dict[str, float]:
    """Mean wall seconds per episode (simulation + every localizer) of each method."""
    return {m: stat[1] for m, stat in method_stats(rows, "seconds").items()}


def _interval(stat: tuple[int, float, float, float], fmt: Callable[[float], str],
              ci_fmt: Callable[[float], str] | None = None) -> str:
    """'mean ± CI' of a :func:`ci_stats` tuple ('–' without values, no CI for one); the CI in
    ``ci_fmt`` (default ``fmt``)."""
    n, mean, _, ci = stat
    if n == 0:
        return "–"
    return fmt(mean) if math.isnan(ci) else f"{fmt(mean)} ± {(ci_fmt or fmt)(ci)}"


def _cell(values: list[float], fmt: Callable[[float], str]) -> str:
    return _interval(ci_stats(values), fmt)


def _table(episodes: list[dict[str, Any]], localizers: list[str]) -> str:
    """Markdown table of ``episodes``: one row per method, mean ± 95 % CI."""
    columns: list[tuple[str, Callable[[list[dict[str, Any]]], str]]] = []
    for name in localizers:
        def rmse(eps: list[dict[str, Any]], name: str = name) -> str:
            shares = [e[f"localized:{name}"] for e in eps if f"localized:{name}" in e]
            if not shares:      # no episode of the method was localized by ``name``
                return "–"
            return (f"{_cell([e.get(f'rmse:{name}', math.nan) for e in eps], '{:.2f}'.format)}"
                    f" ({np.mean(shares):.0%})")
        columns.append((f"RMSE {name} [m] (localized)", rmse))
    for title, key, fmt in (
            ("coverage", "coverage", "{:.1%}"), ("EER [1/J]", "eer", "{:.3f}"),
            ("E_total [J]", "energy_total", "{:.0f}"), ("η_traj", "eta_traj", "{:.3f}"),
            ("path [m]", "path_length", "{:.0f}"), ("time [s]", "travel_time", "{:.0f}"),
            ("beacons", "beacons", "{:.0f}"), ("contacts", "collisions", "{:.1f}"),
            ("complete", "path_complete", "{:.0%}"),
            ("s/episode", "seconds", "{:.1f}")):
        columns.append((title, lambda eps, key=key, fmt=fmt:
                        _cell([e[key] for e in eps], fmt.format)))
    by_method: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for e in episodes:
        by_method[e["method"]].append(e)
    lines = ["| method | " + " | ".join(c[0] for c in columns) + " | n |",
             "|---|" + "---|" * (len(columns) + 1)]
    for method in _method_order(by_method):
        eps = by_method[method]
        lines.append(f"| {label(method)} | " + " | ".join(f(eps) for _, f in columns)
                     + f" | {len(eps)} |")
    return "\n".join(lines)


def method_table(rows: list[dict[str, Any]]) -> str:
    """The table of summary.md's "All episodes" section for ``rows``: a row per method,
    mean ± 95 % CI of every metric."""
    return _table(list(_episodes(rows).values()), _localizers(rows))


def summary_markdown(rows: list[dict[str, Any]], title: str, notes: str = "",
                     lead: str = "") -> str:
    """summary.md: ``lead`` (Markdown put before the tables, e.g. :func:`robustness_markdown`),
    a table of all episodes, then one per value of each grid dimension that varies (field size,
    node count, obstacle density)."""
    episodes = list(_episodes(rows).values())
    localizers = _localizers(rows)
    parts = [f"# {title}", notes, "Mean ± 95 % confidence half-width (Student t) over "
             "episodes; RMSE (Eq. 15) over the localized nodes, their share in brackets.",
             lead, "## All episodes", _table(episodes, localizers)]
    for dim, name, fmt in (("field_size", "field", "{:g} m"), ("n_nodes", "N", "{:d}"),
                           ("obstacle_density", "obstacle density", "{:.2f}")):
        values = sorted({e[dim] for e in episodes})
        if len(values) < 2:
            continue
        parts.append(f"## By {name}")
        for v in values:
            parts += [f"### {name} {fmt.format(v)}",
                      _table([e for e in episodes if e[dim] == v], localizers)]
    return "\n\n".join(p for p in parts if p) + "\n"


# --- robustness --------------------------------------------------------------------------------
def _paired(key: EpisodeKey) -> EpisodeKey:
    """The episode of ``key`` without its method: the same map, nodes and seed."""
    return dataclasses.replace(key, method="")


def _partners(episodes: dict[EpisodeKey, dict[str, Any]], reference: str, key: str
              ) -> dict[EpisodeKey, float]:
    """``reference``'s value of ``key`` per episode without its method (:func:`_paired`)."""
    return {_paired(k): ep.get(key, math.nan) for k, ep in episodes.items()
            if k.method == reference}


def _pairs(rows: list[dict[str, Any]], method: str, reference: str, metric: str,
           localizer: str) -> list[tuple[float, float]]:
    """(value of ``method``, value of ``reference``) of ``metric`` (as :func:`method_stats`)
    on every episode both played, in the rows' order."""
    key = f"{metric}:{localizer}" if metric in ("rmse", "localized") else metric
    episodes = _episodes(rows)
    theirs = _partners(episodes, reference, key)
    return [(ep.get(key, math.nan), theirs[_paired(k)]) for k, ep in episodes.items()
            if k.method == method and _paired(k) in theirs]


def paired_stats(rows: list[dict[str, Any]], method: str, reference: str, metric: str,
                 localizer: str = PRIMARY_LOCALIZER) -> tuple[int, float, float, float]:
    """:func:`ci_stats` of the paired differences ``method`` − ``reference`` of ``metric`` (an
    episode column, ``seconds``, or ``rmse`` / ``localized`` of ``localizer``) over the
    episodes both played (same map, N and seed); a pair with a missing value (an episode
    that localized no node has no RMSE) is left out."""
    return ci_stats(a - b for a, b in _pairs(rows, method, reference, metric, localizer))


def paired_ratio(rows: list[dict[str, Any]], method: str, reference: str,
                 metric: str = "energy_total") -> tuple[int, float]:
    """(pairs, sum of ``method``'s ``metric`` / sum of ``reference``'s) over the episodes both
    played: ``method``'s E_total as a share of the plain spiral's on the same episodes (NaN
    without a pair or with a zero sum)."""
    pairs = [(a, b) for a, b in _pairs(rows, method, reference, metric, PRIMARY_LOCALIZER)
             if math.isfinite(a) and math.isfinite(b)]
    total = sum(b for _, b in pairs)
    return len(pairs), (sum(a for a, _ in pairs) / total if total else math.nan)


def robustness_stats(rows: list[dict[str, Any]], reference: str = REFERENCE_METHOD
                     ) -> list[dict[str, Any]]:
    """Per obstacle density (over every field size and N in ``rows``) and method, in method
    order: ``n`` episodes; ``complete``, the share that ended by themselves (path_complete);
    ``coverage`` as :func:`ci_stats` (n, mean, std, CI); ``gap``, the same of the paired
    difference method − ``reference`` in coverage points (100 × fraction) over the episodes that
    ``reference`` played too (same map, N and seed); ``worst`` coverage; ``static`` and
    ``moving`` contacts per sweep (:func:`ci_stats`)."""
    episodes = _episodes(rows)
    baseline = _partners(episodes, reference, "coverage")
    groups: dict[tuple[float, str], list[tuple[EpisodeKey, dict[str, Any]]]] = defaultdict(list)
    for key, ep in episodes.items():
        groups[key.obstacle_density, key.method].append((key, ep))
    out = []
    for density in sorted({d for d, _ in groups}):
        for method in _method_order(m for d, m in groups if d == density):
            members = groups[density, method]
            coverage = [ep["coverage"] for _, ep in members]
            finite = [c for c in coverage if math.isfinite(c)]
            out.append({
                "obstacle_density": density, "method": method, "label": label(method),
                "n": len(members),
                "complete": ci_stats(ep["path_complete"] for _, ep in members)[1],
                "coverage": ci_stats(coverage),
                "gap": ci_stats(100.0 * (ep["coverage"] - baseline[_paired(k)])
                                for k, ep in members if _paired(k) in baseline),
                "worst": min(finite, default=math.nan),
                "static": ci_stats(ep["collisions_static"] for _, ep in members),
                "moving": ci_stats(ep["collisions_moving"] for _, ep in members)})
    return out


def robustness_markdown(rows: list[dict[str, Any]], reference: str = REFERENCE_METHOD,
                        level: int = 2) -> str:
    """The robustness tables of :func:`robustness_stats`: an overview (per method and density,
    the mean coverage gap to ``reference`` and the share of sweeps that ended by themselves),
    then one table per density; headings at Markdown ``level``. Empty without rows."""
    stats = robustness_stats(rows, reference)
    if not stats:
        return ""
    h = "#" * level
    pct, points, one = "{:.1%}".format, "{:+.1f}".format, "{:.1f}".format
    ref = label(reference).lower()

    def gap(s: dict[str, Any], mark: str) -> str:
        return mark if s["method"] == reference else _interval(s["gap"], points, one)

    densities = sorted({s["obstacle_density"] for s in stats})
    by_key = {(s["obstacle_density"], s["method"]): s for s in stats}
    overview = ["| method | " + " | ".join(f"d = {d:.1f}" for d in densities) + " |",
                "|---|" + "---|" * len(densities)]
    for m in _method_order(s["method"] for s in stats):
        cells = [f"{gap(by_key[d, m], 'ref.')} ({by_key[d, m]['complete']:.0%})"
                 if (d, m) in by_key else "–" for d in densities]
        overview.append(f"| {label(m)} | " + " | ".join(cells) + " |")
    parts = [f"{h} Robustness by obstacle density",
             f"Coverage gap to the {ref} on the same episode (same map, nodes and seed): mean "
             f"of the paired differences method − {ref}, in percentage points, ± 95 % CI; in "
             f"brackets the share of sweeps that ended by themselves.", "\n".join(overview)]
    for density in densities:
        lines = [f"| method | ended by itself | coverage | gap to {ref} [points] | "
                 "worst coverage | static contacts | moving contacts | n |",
                 "|---|---|---|---|---|---|---|---|"]
        for s in stats:
            if s["obstacle_density"] != density:
                continue
            worst = pct(s["worst"]) if math.isfinite(s["worst"]) else "–"
            lines.append(f"| {s['label']} | {s['complete']:.0%} | "
                         f"{_interval(s['coverage'], pct)} | {gap(s, 'reference')} | {worst} | "
                         f"{_interval(s['static'], one)} | {_interval(s['moving'], one)} | "
                         f"{s['n']} |")
        parts += [f"{h}# Obstacle density {density:.1f}", "\n".join(lines)]
    return "\n\n".join(parts)


# --- figures -----------------------------------------------------------------------------------
def _in_grid(preset: str, ep: dict[str, Any], any_density: bool = False) -> bool:
    p = PRESETS[preset]
    return (ep["field_size"] in p.field_sizes and ep["n_nodes"] in p.n_nodes
            and (any_density or ep["obstacle_density"] in p.densities))


def _colors(methods: list[str]) -> dict[str, Any]:
    import matplotlib.pyplot as plt
    cmap = plt.get_cmap("tab20")
    order = _method_order([*METHODS, *methods])
    return {m: cmap(order.index(m) % 20) for m in methods}


def _fig2(episodes: list[dict[str, Any]], localizers: list[str]) -> Any:
    """Figure 2: a bar per method for RMSE (per localizer), E_total, coverage and η_traj."""
    import matplotlib.pyplot as plt
    methods = _method_order(e["method"] for e in episodes)
    colors = _colors(methods)
    x = np.arange(len(methods))
    fig, axes = plt.subplots(2, 2, figsize=(max(10, 0.9 * len(methods) + 4), 8))
    # E_total, not EER: Eq. 17's EER came out the same for every method (0.625 beacons/J in the
    # quick preset, issue 22), so the panel said nothing; EER stays in the tables
    panels = (("(a) localization RMSE (Eq. 15) [m]", [f"rmse:{n}" for n in localizers]),
              ("(b) total energy E_total [J]", ["energy_total"]),
              ("(c) coverage ratio (Eq. 18)", ["coverage"]),
              ("(d) trajectory efficiency η_traj (Eq. 19)", ["eta_traj"]))
    for ax, (title, keys) in zip(axes.ravel(), panels, strict=True):
        width = 0.8 / len(keys)
        for k, key in enumerate(keys):
            means, err = _error_bars([bootstrap_interval(
                [e.get(key, math.nan) for e in episodes if e["method"] == m],
                [e["obstacle_density"] for e in episodes if e["method"] == m])
                for m in methods])
            ax.bar(x + (k - (len(keys) - 1) / 2) * width, means, width,
                   yerr=err, capsize=3, color=[colors[m] for m in methods],
                   edgecolor="black", linewidth=0.5, hatch="//" if k else None,
                   label=key.split(":")[-1])
        ax.set_title(title, fontsize=10)
        ax.set_xticks(x, [label(m) for m in methods], rotation=40, ha="right", fontsize=8)
        if len(keys) > 1:       # beside the axes, never over a bar
            ax.legend(fontsize=8, title="localizer", title_fontsize=8, loc="upper left",
                      bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    fig.suptitle(f"Figure 2: methods compared ({len(episodes)} episodes; mean, 95 % "
                 f"bootstrap interval, resampled within each obstacle density)")
    fig.tight_layout()
    return fig


def _lines(episodes: list[dict[str, Any]], localizer: str, x_key: str, x_label: str,
           panel_key: str | None, title: str, path: Path) -> None:
    """Figure 3 / 4 layout: RMSE, E_total and η_traj against ``x_key``, one line per method;
    with ``panel_key`` a row per metric and a column per value of it, else one row."""
    import matplotlib.pyplot as plt
    methods = _method_order(e["method"] for e in episodes)
    colors = _colors(methods)
    panels = sorted({e[panel_key] for e in episodes}) if panel_key else [None]
    metrics = ((f"rmse:{localizer}", f"RMSE ({localizer}) [m]"), ("energy_total",
               "E_total [J]"), ("eta_traj", "η_traj (Eq. 19)"))
    rows, cols = (len(metrics), len(panels)) if panel_key else (1, len(metrics))
    fig, axes = plt.subplots(rows, cols, squeeze=False,
                             figsize=(5 * cols + 3, max(3.4 * rows, 4.5)))
    for col, panel in enumerate(panels):
        sel = [e for e in episodes if panel_key is None or e[panel_key] == panel]
        xs = sorted({e[x_key] for e in sel})
        for row, (key, name) in enumerate(metrics):
            ax = axes[row][col] if panel_key else axes[0][row]
            for m in methods:
                means, err = _error_bars([bootstrap_interval(
                    [e.get(key, math.nan) for e in sel if e["method"] == m and e[x_key] == v])
                    for v in xs])
                ax.errorbar(xs, means, yerr=err, color=colors[m], marker="o", ms=3, capsize=3,
                            label=label(m))
            ax.set(xlabel=x_label, ylabel=name)
            if panel_key:
                ax.set_title(f"{panel:g} m × {panel:g} m field", fontsize=10)
    fig.legend(*axes[0][0].get_legend_handles_labels(), loc="center right", fontsize=8)
    fig.suptitle(f"{title} (mean, 95 % bootstrap interval)")
    fig.tight_layout(rect=(0, 0, 1 - 2.6 / fig.get_figwidth(), 1))
    save_figure_atomic(fig, path, dpi=110)
    plt.close(fig)


def draw_figures(rows: list[dict[str, Any]], out: Path) -> list[Path]:
    """fig2.png, fig3.png and fig4.png in ``out``, each when episodes of its preset's grid are
    in ``rows`` (fig4 shows every density at its N and field size); returns the paths."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    episodes = list(_episodes(rows).values())
    localizers = _localizers(rows)
    if not episodes or not localizers:     # the figures plot RMSE: not without a localizer
        return []
    written = []
    fig2 = [e for e in episodes if _in_grid("fig2", e)]
    if fig2:
        written.append(out / "fig2.png")
        figure = _fig2(fig2, localizers)
        save_figure_atomic(figure, written[-1], dpi=110)
        plt.close(figure)
    fig3 = [e for e in episodes if _in_grid("fig3", e)]
    if fig3:
        written.append(out / "fig3.png")
        _lines(fig3, localizers[0], "n_nodes", "number of nodes N", "field_size",
               "Figure 3: scalability", written[-1])
    if any(_in_grid("fig4", e) for e in episodes):
        written.append(out / "fig4.png")
        _lines([e for e in episodes if _in_grid("fig4", e, any_density=True)], localizers[0],
               "obstacle_density", "obstacle density", None,
               "Figure 4: robustness to obstacle density", written[-1])
    return written
