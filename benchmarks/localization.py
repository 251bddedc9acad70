"""Localization accuracy and speed: classical DV-Hop, the visibility consensus alone and
OLSTM-DV-Hop on the test maps.

Accuracy: square-spiral episodes on the shipped *test* maps (``maps/test``, never used in
training), 100 x 100 m, R = 25 m, N in {100, 300, 500}, obstacle density in {0.1, 0.2, 0.3, 0.4},
``--seeds`` seeds per cell (spread over the three test maps of each density), with the unit disk
(DOI 0) and with DOI 0.1 and 0.2 (``--dois``). Per cell: the RMSE of Eq. 15 pooled over all
localized nodes of its episodes and the localized fraction per method, the DV-Hop / OLSTM ratio
and the gain of OLSTM-DV-Hop over the consensus alone.

Ablation (``--ablation VAL_DIR``): on the validation logs of ``train.py localizer`` (held-out
training maps, never the test maps), the consensus alone, with the OLSTM's band, with a
non-learned counting band, with the true pattern, and without the map (range only) with the DOI
bound and with the OLSTM.

Ceiling (``--ceiling``): per cell with DOI > 0, the consensus with the anchor's true pattern
(saved beside each log, never available at inference) beside the consensus alone and
OLSTM-DV-Hop: the most a reception model can give the consensus's scoring.

Neighbour stages (``--neighbour-rounds LOG_DIR``): on logs of ``train.py localizer`` (training
maps only), the consensus alone and OLSTM-DV-Hop with 0-3 neighbour stages.

Speed: one episode with N = 1000 on a 200 x 200 m test map, with DOI 0 and with DOI 0.1,
localized from the saved log (hop counts, HopSize, coverage, consensus passes and model
included) on one core; the median of ``--repeats`` runs per method.

``python benchmarks/localization.py`` simulates the logs once into ``--out`` (cached), then
prints both tables and writes ``episodes.csv`` and ``localization.md`` there.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # one core: set before numpy / torch load their thread pools

import argparse  # noqa: E402
import csv  # noqa: E402
import dataclasses  # noqa: E402
import io  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import torch  # noqa: E402

from aoass_env.atomic import folder_problem, write_text_atomic  # noqa: E402
from aoass_env.beacon_log import BeaconLog, BeaconLogError  # noqa: E402
from aoass_env.config import AOASSConfig, ConfigError  # noqa: E402
from aoass_env.localization import localize, prepare  # noqa: E402
from aoass_env.localization.consensus import RELIABLE_SPREAD, node_consensus  # noqa: E402
from aoass_env.localization.dvhop import dvhop  # noqa: E402
from aoass_env.localization.olstm import (  # noqa: E402
    DEFAULT_CHECKPOINT,
    OLSTM,
    CheckpointError,
    load_checkpoint,
    olstm_dvhop,
    predict_pattern,
)
from aoass_env.localization.reception import (  # noqa: E402
    PairRecord,
    pair_histograms,
    pair_statistics,
    range_band,
)
from aoass_env.localization.training import (  # noqa: E402
    EpisodeSpec,
    generate_logs,
    map_density,
    pattern_path,
)
from aoass_env.maps import list_maps  # noqa: E402
from aoass_env.validators import argparse_number  # noqa: E402

NODES = (100, 300, 500)
DENSITIES = (0.1, 0.2, 0.3, 0.4)
DOIS = (0.0, 0.1, 0.2)
SPEED_MAP, SPEED_NODES, SPEED_SEED = "test/d0.20_f200_s521", 1000, 7
METHODS = ("dvhop", "consensus", "olstm-dvhop")
LABELS = {"dvhop": "DV-Hop", "consensus": "consensus", "olstm-dvhop": "OLSTM-DV-Hop"}


def accuracy_specs(seeds: int, dois: tuple[float, ...] = DOIS,
                   densities: tuple[float, ...] = DENSITIES) -> list[EpisodeSpec]:
    """The benchmark episodes, seed-major so that a partial run covers every cell evenly."""
    names = list_maps("test")
    specs = []
    for doi in dois:
        for seed in range(seeds):
            for n in NODES:
                for density in densities:
                    maps = [m for m in names if m.split("/")[1].startswith(f"d{density:.2f}_f100")]
                    specs.append(EpisodeSpec(maps[seed % len(maps)], n, doi, 10_000 + seed))
    return specs


def _density(spec: EpisodeSpec) -> float:
    """The obstacle density of a spec's map, from its name (``test/d0.30_...``)."""
    return float(spec.map_name.split("/")[1][1:5])


def estimates(path: Path, model: OLSTM) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """True node positions (N, 2) and every method's estimates (N, 2) [m] of one log; the
    consensus pass is computed once and shared with OLSTM-DV-Hop (same result as
    :func:`localize`)."""
    episode = prepare(BeaconLog.load(path))
    nodes = np.flatnonzero(episode.covered)
    first = node_consensus(episode, nodes)
    cons = np.full((episode.log.n_nodes, 2), np.nan)
    cons[nodes] = first.estimate
    return episode.log.nodes, {"dvhop": dvhop(episode), "consensus": cons,
                               "olstm-dvhop": olstm_dvhop(episode, model, first)}


def accuracy(paths: list[Path], specs: list[EpisodeSpec], model: OLSTM) -> list[dict]:
    rows = []
    for path, spec in zip(paths, specs, strict=True):
        true, est_of = estimates(path, model)
        row = {"map": spec.map_name, "n_nodes": spec.n_nodes, "doi": spec.doi, "seed": spec.seed,
               "density": _density(spec),
               "coverage": float(np.mean(np.all(np.isfinite(est_of["consensus"]), axis=1)))}
        for method in METHODS:
            est = est_of[method]
            ok = np.all(np.isfinite(est), axis=1)
            row[f"{method}_sq"] = float(np.sum((est[ok] - true[ok]) ** 2))
            row[f"{method}_n"] = int(ok.sum())
        rows.append(row)
    return rows


def accuracy_table(rows: list[dict], doi: float) -> str:
    out = io.StringIO()
    out.write(f"DOI {doi}: RMSE [m] pooled over localized nodes (localized fraction)\n\n")
    out.write(f"| N | density | episodes | {' | '.join(LABELS[m] for m in METHODS)} | ratio "
              f"| gain vs consensus | coverage |\n")
    out.write("|---" * (len(METHODS) + 6) + "|\n")
    for n in NODES:
        for density in DENSITIES:
            cell = [r for r in rows if r["doi"] == doi and r["n_nodes"] == n
                    and abs(r["density"] - density) < 1e-9]
            if not cell:
                continue
            total = sum(r["n_nodes"] for r in cell)
            rmse, frac = {}, {}
            for m in METHODS:
                k = sum(r[f"{m}_n"] for r in cell)
                rmse[m] = np.sqrt(sum(r[f"{m}_sq"] for r in cell) / max(k, 1))
                frac[m] = k / total
            cov = np.mean([r["coverage"] for r in cell])
            values = " | ".join(f"{rmse[m]:.2f} ({frac[m]:.3f})" for m in METHODS)
            gain = 1 - rmse["olstm-dvhop"] / rmse["consensus"]
            out.write(f"| {n} | {density} | {len(cell)} | {values} | "
                      f"{rmse['dvhop'] / rmse['olstm-dvhop']:.1f}x | {100 * gain:+.1f} % "
                      f"| {cov:.3f} |\n")
    return out.getvalue()


def speed(folder: Path, model: OLSTM, repeats: int) -> str:
    """Median time [s] per method on the N = 1000, 200 m log, with DOI 0 and DOI 0.1."""
    times: dict[float, dict[str, float]] = {}
    for doi in (0.0, 0.1):
        log = BeaconLog.load(generate_logs([EpisodeSpec(SPEED_MAP, SPEED_NODES, doi, SPEED_SEED)],
                                           folder)[0])
        times[doi] = {}
        for method in METHODS:
            kwargs = {"checkpoint": model} if method == "olstm-dvhop" else {}
            localize(log, method, **kwargs)  # warm-up
            runs = []
            for _ in range(repeats):
                start = time.perf_counter()
                localize(log, method, **kwargs)
                runs.append(time.perf_counter() - start)
            times[doi][method] = float(np.median(runs))
    rows = "".join(f"| {LABELS[m]} | {times[0.0][m]:.3f} | {times[0.1][m]:.3f} |\n"
                   for m in METHODS)
    return (f"Speed, one core, N = {log.n_nodes}, {log.n_beacons} beacons, "
            f"{int(log.field[0])} x {int(log.field[1])} m ({SPEED_MAP}), median of {repeats}:\n\n"
            f"| method | DOI 0 [s] | DOI 0.1 [s] |\n|---|---|---|\n{rows}")


ABLATION = ("consensus", "olstm", "counting", "oracle", "range DOI bound", "learned alone")
ABLATION_LABELS = ("consensus alone", "consensus + OLSTM band (olstm-dvhop)",
                   "consensus + counting band (no LSTM)", "consensus + true pattern",
                   "range only, DOI bound (no map)", "learned model alone (no map)")


def counting_band(record: PairRecord, doi: float, halfwidth: int = 3) -> tuple[np.ndarray,
                                                                              np.ndarray]:
    """Non-learned control: per degree, the threshold z in [-1, 1] (41 candidates) with the
    fewest heard pairs above plus unheard pairs at or below it, pairs within ``halfwidth``
    degrees; both band edges at 1 + DOI z."""
    grid = np.linspace(-1, 1, 41)
    edge = np.zeros(360)
    for d in range(360):
        near = np.abs((record.degree - d + 180) % 360 - 180) <= halfwidth
        z, heard = record.z[near], record.heard[near]
        cost = (heard[:, None] & (z[:, None] > grid)).sum(0) \
            + (~heard[:, None] & (z[:, None] <= grid)).sum(0)
        edge[d] = grid[cost == cost.min()].mean()
    return 1 + doi * edge, 1 + doi * edge


def ablation_row(path: Path, model: OLSTM) -> dict:
    """Squared errors and counts of every ablation variant on one validation log."""
    episode = prepare(BeaconLog.load(path))
    doi = episode.config.doi
    nodes = np.flatnonzero(episode.covered)
    true = episode.log.nodes[nodes]
    first = node_consensus(episode, nodes)
    est = {"consensus": first.estimate}
    if doi > 0:
        reliable = first.spread <= RELIABLE_SPREAD
        record = pair_statistics(episode, nodes[reliable], first.estimate[reliable])
        mean, std = predict_pattern(model, pair_histograms(record))
        pattern = np.load(pattern_path(path), allow_pickle=False)
        bands = {"olstm": range_band(mean, std, doi, model.band_width),
                 "counting": counting_band(record, doi), "oracle": (pattern, pattern)}
        for name, band in bands.items():
            est[name] = node_consensus(episode, nodes, band=band).estimate
    else:
        est["olstm"] = est["counting"] = est["oracle"] = first.estimate
    no_map = prepare(dataclasses.replace(episode.log, obstacle_vertices=np.zeros((0, 2)),
                                         obstacle_offsets=np.zeros(1, np.int64)))
    est["range DOI bound"] = localize(no_map, "consensus")[nodes]
    est["learned alone"] = olstm_dvhop(no_map, model)[nodes]
    row = {"log": path.name, "doi": doi, "n": len(nodes)}
    row.update({name: float(np.sum((e - true) ** 2)) for name, e in est.items()})
    return row


def ablation(folder: Path, model: OLSTM) -> str:
    """The ablation table (pooled RMSE [m] per DOI) over the logs of ``folder``."""
    rows = [ablation_row(p, model) for p in sorted(folder.glob("*.npz"))]
    out = io.StringIO()
    out.write(f"Ablation on {len(rows)} validation logs ({folder}): RMSE [m] pooled per DOI\n\n"
              f"| DOI | logs | {' | '.join(ABLATION_LABELS)} |\n" + "|---" * 8 + "|\n")
    for doi in sorted({r["doi"] for r in rows}):
        cell = [r for r in rows if r["doi"] == doi]
        n = sum(r["n"] for r in cell)
        values = " | ".join(f"{np.sqrt(sum(r[k] for r in cell) / n):.3f}" for k in ABLATION)
        out.write(f"| {doi} | {len(cell)} | {values} |\n")
    worse = [r for r in rows if r["doi"] > 0 and r["olstm"] > r["consensus"]]
    out.write(f"\nLogs with DOI > 0 where OLSTM-DV-Hop is worse than the consensus alone: "
              f"{len(worse)} of {sum(r['doi'] > 0 for r in rows)}"
              + "".join(f"\n* {r['log']}: {np.sqrt(r['consensus'] / r['n']):.2f} -> "
                        f"{np.sqrt(r['olstm'] / r['n']):.2f} m" for r in worse) + "\n")
    return out.getvalue()


def ceiling(paths: list[Path], specs: list[EpisodeSpec], model: OLSTM) -> str:
    """Per cell (N, density) of the logs with DOI > 0: the pooled RMSE [m] of the consensus
    alone, of OLSTM-DV-Hop and of the consensus with the anchor's *true* pattern K (saved
    beside each log by the simulation, never available at inference) as both band edges,
    each with its gain over the consensus alone: what a perfect reception model would give."""
    acc: dict[tuple[float, int, float], dict[str, float]] = {}
    for path, spec in zip(paths, specs, strict=True):
        if spec.doi <= 0:
            continue
        episode = prepare(BeaconLog.load(path))
        nodes = np.flatnonzero(episode.covered)
        true = episode.log.nodes[nodes]
        first = node_consensus(episode, nodes)
        pattern = np.load(pattern_path(path), allow_pickle=False)
        est = {"consensus": first.estimate,
               "olstm": olstm_dvhop(episode, model, first)[nodes],
               "true": node_consensus(episode, nodes, band=(pattern, pattern)).estimate}
        cell = acc.setdefault((spec.doi, spec.n_nodes, _density(spec)), {"n": 0.0})
        cell["n"] += len(nodes)
        for name, e in est.items():
            cell[name] = cell.get(name, 0.0) + float(np.sum((e - true) ** 2))
    out = io.StringIO()
    out.write("RMSE [m] pooled per cell; gain = 1 - method / consensus alone\n\n| DOI | N | "
              "density | consensus alone | OLSTM-DV-Hop | gain | consensus + true pattern | "
              "gain |\n" + "|---" * 8 + "|\n")
    for (doi, n, density), cell in sorted(acc.items()):
        c, o, t = (np.sqrt(cell[k] / cell["n"]) for k in ("consensus", "olstm", "true"))
        out.write(f"| {doi} | {n} | {density} | {c:.3f} | {o:.3f} | {100 * (1 - o / c):.1f} % | "
                  f"{t:.3f} | {100 * (1 - t / c):.1f} % |\n")
    return out.getvalue()


def neighbour_rounds(folder: Path, model: OLSTM, rounds: tuple[int, ...] = (0, 1, 2, 3)) -> str:
    """Pooled RMSE [m] per DOI of the consensus alone and of OLSTM-DV-Hop over the logs of
    ``folder`` with each number of neighbour stages (0: the beacons alone)."""
    from aoass_env.localization import consensus as module

    default = module.NEIGHBOUR_ROUNDS
    sq: dict[tuple[int, float, str], float] = {}
    count: dict[float, int] = {}
    try:
        for path in sorted(folder.glob("*.npz")):
            episode = prepare(BeaconLog.load(path))
            doi = episode.config.doi
            nodes = np.flatnonzero(episode.covered)
            true = episode.log.nodes[nodes]
            count[doi] = count.get(doi, 0) + len(nodes)
            for k in rounds:
                module.NEIGHBOUR_ROUNDS = k
                first = node_consensus(episode, nodes)
                for name, est in (("consensus", first.estimate),
                                  ("olstm-dvhop", olstm_dvhop(episode, model, first)[nodes])):
                    key = (k, doi, name)
                    sq[key] = sq.get(key, 0.0) + float(np.sum((est - true) ** 2))
    finally:
        module.NEIGHBOUR_ROUNDS = default
    out = io.StringIO()
    out.write(f"Neighbour stages on {folder}: RMSE [m] pooled per DOI, consensus alone / "
              f"OLSTM-DV-Hop (default {default})\n\n| DOI | "
              + " | ".join(f"{k} stage{'s' if k != 1 else ''}" for k in rounds)
              + " |\n" + "|---" * (len(rounds) + 1) + "|\n")
    for doi in sorted(count):
        cells = []
        for k in rounds:
            c, o = (np.sqrt(sq[(k, doi, m)] / count[doi]) for m in ("consensus", "olstm-dvhop"))
            cells.append(f"{c:.3f}" if doi == 0 else f"{c:.3f} / {o:.3f}")
        out.write(f"| {doi} | {' | '.join(cells)} |\n")
    return out.getvalue()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=argparse_number(int, 1), default=30,
                        help="episodes per cell (default 30)")
    parser.add_argument("--out", type=Path, default=Path("out/bench_localization"))
    parser.add_argument("--checkpoint", type=Path, default=DEFAULT_CHECKPOINT)
    parser.add_argument("--repeats", type=argparse_number(int, 1), default=5,
                        help="speed runs per method")
    parser.add_argument("--logs-only", action="store_true", help="only simulate the logs")
    parser.add_argument("--cached-only", action="store_true",
                        help="only use logs already simulated (a partial run)")
    parser.add_argument("--dois", type=float, nargs="+", default=list(DOIS),
                        help=f"radio irregularities to run (default {' '.join(map(str, DOIS))})")
    parser.add_argument("--logs", type=Path, default=None,
                        help="folder of the simulated logs (default OUT/logs)")
    parser.add_argument("--no-speed", action="store_true", help="skip the speed table")
    parser.add_argument("--neighbour-rounds", type=Path, default=None, metavar="LOG_DIR",
                        help="only the table of neighbour stages (0-3), on the logs of `train.py "
                             "localizer` (e.g. out/localizer_logs/val)")
    parser.add_argument("--densities", type=float, nargs="+", default=list(DENSITIES),
                        help="obstacle densities of the cells (default "
                             f"{' '.join(map(str, DENSITIES))})")
    parser.add_argument("--ceiling", action="store_true",
                        help="only the table of what the anchor's true pattern gives the "
                             "consensus, beside OLSTM-DV-Hop, per cell with DOI > 0")
    parser.add_argument("--ablation", type=Path, default=None, metavar="VAL_DIR",
                        help="only the ablation table, on the validation logs of `train.py "
                             "localizer` (e.g. out/localizer_logs/val)")
    args = parser.parse_args()
    shipped = sorted({d for d, field in map(map_density, list_maps("test")) if field == 100})
    for density in args.densities:
        if round(density, 2) not in shipped:
            parser.error(f"--densities: {density:g} is not the density of a shipped 100 m test "
                         f"map; valid: {' '.join(f'{d:g}' for d in shipped)}")
    for doi in args.dois:
        try:
            AOASSConfig(doi=doi)
        except ConfigError as err:
            parser.error(f"--dois: {err}")

    def checkpoint() -> OLSTM:
        try:
            return load_checkpoint(args.checkpoint)
        except CheckpointError as err:
            parser.error(f"--checkpoint: {err}")

    torch.set_num_threads(1)
    for flag, table, name in (("--neighbour-rounds", neighbour_rounds, "neighbour_rounds.md"),
                              ("--ablation", ablation, "ablation.md")):
        folder = getattr(args, flag[2:].replace("-", "_"))
        if folder is None:
            continue
        # a missing or empty folder used to print an empty table and exit 0
        if not folder.is_dir() or not any(folder.glob("*.npz")):
            parser.error(f"{flag} {folder}: holds no beacon log (*.npz); give the logs of "
                         f"`train.py localizer`, e.g. out/localizer_logs/val")
        try:
            report = table(folder, checkpoint())
        except BeaconLogError as err:
            parser.error(f"{flag}: {err}")
        print(report)
        write_text_atomic(args.out / name, report)
        return
    dois = tuple(args.dois)
    specs = accuracy_specs(args.seeds, dois, tuple(args.densities))
    logs = args.out / "logs" if args.logs is None else args.logs
    for flag, folder in (("--out", args.out), ("--logs", logs)):
        problem = folder_problem(folder)     # refused now, not in a traceback after the work
        if problem is not None:
            parser.error(f"{flag} {folder}: {problem}")
    if args.cached_only:
        specs = [s for s in specs if (logs / s.file_name).is_file()]
        if not specs:
            parser.error(f"--cached-only: no log of these cells in {logs}")
    paths = generate_logs(specs, logs, lambda line: print(line, flush=True))
    if args.logs_only:
        return
    model = checkpoint()
    if args.ceiling:
        report = ceiling(paths, specs, model)
        print(report)
        write_text_atomic(args.out / "ceiling.md", report)
        return
    rows = accuracy(paths, specs, model)
    report = "\n".join(accuracy_table(rows, doi) for doi in dois)
    if not args.no_speed:
        report += "\n" + speed(args.out / "speed", model, args.repeats)
    print(report)
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
    write_text_atomic(args.out / "episodes.csv", buf.getvalue())
    write_text_atomic(args.out / "localization.md", report)


if __name__ == "__main__":
    main()
