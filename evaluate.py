"""Benchmark runner: episodes over maps, seeds and node counts; tables and figures.

The anchor follows the square spiral with the nominal follower (the zero action of the
environment, with detours around static obstacles), and every episode's beacon log is localized
with classical DV-Hop and OLSTM-DV-Hop (the shipped checkpoint). The learned policy, the safety
stack and the baselines join it in later releases.

    python3 evaluate.py                       # preset "quick": a few minutes on 2 cores
    python3 evaluate.py --seeds 5 --out out/run1 --save-logs

Outputs in ``--out`` (default out/<preset>): episodes.csv (one row per episode), summary.md
(means per density), trajectories.png, metrics.png and, with --save-logs, one beacon log (.npz)
per episode.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch

from aoass_env.atomic import write_text_atomic
from aoass_env.config import AOASSConfig
from aoass_env.localization import localize
from aoass_env.maps import list_maps, load_map
from aoass_env.metrics import energy_efficiency_ratio, localization_rmse, trajectory_efficiency
from aoass_env.simulator import Simulator

PRESETS = {
    # field size, densities, node counts, maps per density ("smoke": the test suite's run)
    "smoke": dict(field_size=100.0, densities=(0.1,), n_nodes=(60,), maps=1),
    "quick": dict(field_size=100.0, densities=(0.1, 0.2, 0.3, 0.4), n_nodes=(100, 300), maps=1),
    "core": dict(field_size=100.0, densities=(0.1, 0.2, 0.3, 0.4, 0.5, 0.6),
                 n_nodes=(100, 300, 500), maps=3),
}


@dataclass
class EpisodeRow:
    method: str
    map: str
    field_size: float
    n_nodes: int
    obstacle_density: float
    seed: int
    coverage: float
    beacons: int
    path_length: float
    ideal_length: float
    travel_time: float
    ideal_time: float
    eta_traj: float
    collisions: int
    collisions_static: int
    collisions_moving: int
    energy_total: float
    eer: float
    rmse_dvhop: float
    rmse_olstm: float
    localized: float
    wall_seconds: float


def run_episode(map_name: str, n_nodes: int, seed: int,
                out: Path | None) -> tuple[EpisodeRow, Simulator]:
    """One episode of the nominal spiral follower on a shipped test map."""
    t0 = time.perf_counter()
    obstacle_map = load_map(map_name)
    config = AOASSConfig(field_size=obstacle_map.width, n_nodes=n_nodes, map=map_name)
    sim = Simulator(config, np.random.default_rng(seed), obstacle_map=obstacle_map, seed=seed,
                    method="spiral")
    log = sim.run()
    if out is not None:
        log.save(out / "logs" / f"{Path(map_name).name}_n{n_nodes}_s{seed}.npz")
    net = sim.network
    ideal_time = sim.spiral.nominal_time(config.anchor_nominal_speed)
    rmse_dvhop, _ = localization_rmse(log.nodes, localize(log, "dvhop"))
    rmse_olstm, localized = localization_rmse(log.nodes, localize(log, "olstm-dvhop"))
    return EpisodeRow(
        method="spiral", map=map_name, field_size=obstacle_map.width, n_nodes=n_nodes,
        obstacle_density=round(obstacle_map.density, 4), seed=seed,
        coverage=net.coverage_ratio, beacons=net.beacons_sent,
        path_length=net.distance_travelled, ideal_length=sim.spiral.length,
        travel_time=sim.world.time, ideal_time=ideal_time,
        eta_traj=trajectory_efficiency(sim.spiral.length, net.distance_travelled, ideal_time,
                                       sim.world.time),
        collisions=sim.collisions,
        collisions_static=sim.world.static_contacts + sim.world.wall_contacts,
        collisions_moving=sim.world.moving_contacts, energy_total=net.energy_total,
        eer=energy_efficiency_ratio(net.energy_total, net.beacons_sent),
        rmse_dvhop=rmse_dvhop, rmse_olstm=rmse_olstm, localized=localized,
        wall_seconds=time.perf_counter() - t0), sim


def write_csv(rows: list[EpisodeRow], path: Path) -> None:
    import io
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(asdict(rows[0])))
    writer.writeheader()
    writer.writerows(asdict(r) for r in rows)
    write_text_atomic(path, buf.getvalue())


COLUMNS = (("density", "obstacle_density", "{:.2f}"), ("N", "n_nodes", "{:d}"),
           ("coverage %", "coverage", "{:.1%}"), ("beacons", "beacons", "{:.0f}"),
           ("L / L_ideal", None, "{:.2f}"), ("eta_traj", "eta_traj", "{:.3f}"),
           ("contacts static", "collisions_static", "{:.1f}"),
           ("contacts moving", "collisions_moving", "{:.1f}"),
           ("E_total [J]", "energy_total", "{:.1f}"), ("EER [1/J]", "eer", "{:.3f}"),
           ("RMSE DV-Hop [m]", "rmse_dvhop", "{:.2f}"),
           ("RMSE OLSTM-DV-Hop [m]", "rmse_olstm", "{:.2f}"),
           ("localized %", "localized", "{:.1%}"))


def summary_table(rows: list[EpisodeRow]) -> str:
    """Markdown table of means per (density, N)."""
    groups: dict[tuple[float, int], list[EpisodeRow]] = {}
    for r in rows:
        groups.setdefault((r.obstacle_density, r.n_nodes), []).append(r)
    lines = ["| " + " | ".join(c[0] for c in COLUMNS) + " | episodes |",
             "|" + "---|" * (len(COLUMNS) + 1)]
    for _, grp in sorted(groups.items()):
        cells = []
        for _, key, fmt in COLUMNS:
            if key is None:
                value = np.mean([r.path_length / r.ideal_length for r in grp])
            elif key == "n_nodes":
                value = grp[0].n_nodes
            else:
                value = np.mean([getattr(r, key) for r in grp])
            cells.append(fmt.format(value))
        lines.append("| " + " | ".join(cells) + f" | {len(grp)} |")
    return "\n".join(lines)


def plot(rows: list[EpisodeRow], shown: dict[float, Simulator], out: Path) -> list[Path]:
    """Trajectory panels (one finished episode per density) and metric-vs-density bars."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon as PolygonPatch

    written = []
    fig, axes = plt.subplots(1, len(shown), figsize=(4.2 * len(shown), 4.4), squeeze=False)
    for ax, (density, sim) in zip(axes[0], sorted(shown.items()), strict=True):
        obstacle_map, log = sim.map, sim.finish()
        for poly in obstacle_map.polygons:
            ax.add_patch(PolygonPatch(poly, closed=True, color="0.55"))
        ax.plot(sim.spiral.waypoints[:, 0], sim.spiral.waypoints[:, 1], color="tab:blue",
                lw=0.6, ls="--", alpha=0.6, label="square spiral")
        ax.plot(log.anchor_path[:, 1], log.anchor_path[:, 2], color="tab:red", lw=0.9,
                label="anchor path")
        cov = sim.network.covered
        ax.scatter(*log.nodes[cov].T, s=6, color="tab:green", label="covered node")
        ax.scatter(*log.nodes[~cov].T, s=10, color="black", marker="x", label="not covered")
        ax.set(xlim=(0, obstacle_map.width), ylim=(0, obstacle_map.height), aspect="equal",
               title=f"density {density:.2f}: coverage {sim.network.coverage_ratio:.1%}")
    axes[0][0].legend(loc="lower left", fontsize=7, framealpha=0.9)
    fig.tight_layout()
    path = out / "trajectories.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    written.append(path)

    densities = sorted({r.obstacle_density for r in rows})
    x = np.arange(len(densities))
    fig, axes = plt.subplots(1, 4, figsize=(16, 3.4))
    panels = (("coverage ratio (Eq. 18)", (("coverage", None),)),
              ("trajectory efficiency (Eq. 19)", (("eta_traj", None),)),
              ("EER (Eq. 17) [beacons/J]", (("eer", None),)),
              ("localization RMSE (Eq. 15) [m]",
               (("rmse_dvhop", "DV-Hop"), ("rmse_olstm", "OLSTM-DV-Hop"))))
    for ax, (label, series) in zip(axes, panels, strict=True):
        width = 0.8 / len(series)
        for k, (key, name) in enumerate(series):
            values = [[getattr(r, key) for r in rows if r.obstacle_density == d]
                      for d in densities]
            ax.bar(x + (k - (len(series) - 1) / 2) * width, [np.mean(v) for v in values],
                   width, yerr=[np.std(v) for v in values], capsize=3, label=name)
        ax.set(xlabel="obstacle density", title=label, xticks=x,
               xticklabels=[f"{d:.2f}" for d in densities])
        if len(series) > 1:
            ax.legend(fontsize=7)
    fig.tight_layout()
    path = out / "metrics.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    written.append(path)
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--preset", choices=sorted(PRESETS), default="quick")
    parser.add_argument("--seeds", type=int, default=2, help="episodes per map and node count")
    parser.add_argument("--out", type=Path, default=None, help="output folder (out/<preset>)")
    parser.add_argument("--save-logs", action="store_true", help="save each beacon log (.npz)")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)        # small models: one thread is fastest on a shared machine
    if args.seeds < 1:
        parser.error(f"--seeds must be >= 1, got {args.seeds}")
    preset = PRESETS[args.preset]
    out = args.out or Path("out") / args.preset
    (out / "logs" if args.save_logs else out).mkdir(parents=True, exist_ok=True)

    size = int(preset["field_size"])
    maps = [m for d in preset["densities"]
            for m in [n for n in list_maps("test") if f"d{d:.2f}_f{size}_" in n][:preset["maps"]]]
    jobs = [(m, n, s) for m in maps for n in preset["n_nodes"] for s in range(args.seeds)]
    rows: list[EpisodeRow] = []
    shown: dict[float, Simulator] = {}
    t0 = time.perf_counter()
    for i, (m, n, s) in enumerate(jobs, 1):
        row, sim = run_episode(m, n, s, out if args.save_logs else None)
        rows.append(row)
        if n == max(preset["n_nodes"]):
            shown.setdefault(row.obstacle_density, sim)
        print(f"\r[{i}/{len(jobs)}] {m} N={n} seed={s}  ({time.perf_counter() - t0:.0f} s)",
              end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    write_csv(rows, out / "episodes.csv")
    table = summary_table(rows)
    write_text_atomic(out / "summary.md",
                  f"# AOASS core benchmark, preset {args.preset}\n\nMethod: square spiral with "
                  f"the nominal follower (zero action); logs localized with DV-Hop and "
                  f"OLSTM-DV-Hop (Eq. 15 RMSE over localized nodes). Means over "
                  f"{args.seeds} seed(s) per map and node count, maps from maps/test."
                  f"\n\n{table}\n")
    figures = plot(rows, shown, out)
    print(table)
    print(f"\nwrote {out / 'episodes.csv'}, {out / 'summary.md'}, "
          + ", ".join(str(f) for f in figures))
    return 0


if __name__ == "__main__":
    sys.exit(main())
