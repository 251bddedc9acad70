"""The adaptive rule's coverage against its path, beside the plain spiral's, on training maps:
where the rule's settings put it on the coverage/energy trade-off (issue 19).

Every variant sweeps the same maps, nodes and seeds in the simulator alone (moving obstacles on,
no safety stack, so the sweeps are cheap and deterministic): the plain spiral with its nominal
follower (evaluate.py's ``spiral``), and the adaptive sweep with the rule as configured and
with each ``--variant``'s fields changed. The maps are the shipped ``maps/train`` maps of the
chosen split (``fit`` or ``validation``, :func:`~aoass_env.maps.registry.validation_split`),
never maps/test, or with ``--fresh SEED`` ``--maps`` freshly generated maps per density (map k of
density d from ``default_rng([SEED, round(100 d), k])``: seeds used nowhere else check a choice
made on the training maps). Motion costs ``anchor_motion_energy`` J/m, so the path is the energy.

The script prints, per variant, the mean Eq. 18 coverage (share of nodes), the mean path (m),
the path as a share of the spiral's on the same episodes, the share of sweeps that ended by
themselves (before the time limit), and the share of uncovered nodes that
lie in cells the anchor's coverage map counts as covered, in cells it lacks, and in cells it
does not keep (inside obstacles); then, with variants, each one's mean paired difference to
the configured rule on the same episodes (coverage, path and RMSE, ± the 95 % t interval:
single-split RMSE gaps under about 0.1 m are often noise, so read the interval); then
coverage and path share by density. With
``--localizer``, every sweep's beacon log is also localized and the Eq. 15 RMSE (m, over the
localized nodes) is printed beside the coverage, overall and by density. With ``--bound``, a
last row gives the coverage no sweep of these nodes can much exceed: Eq. 18 on the same nodes
with a beacon sent from every point of a 1 m lattice of the free field the anchor can reach
(:func:`~aoass_env.planning.adaptive.site_radio`'s points: the detour planner's free cells of
its main region), each heard by the nodes' own radio. With ``--cells``, a last table gives
what each rule's cells phase did per sweep (:class:`CellsPhase`): the cells it headed for, how
many were covered when it turned from them and by the sweep's end, how many beacons from
everywhere the anchor can reach would cover at all, and the path driven to them.

Run: ``python3 benchmarks/adaptive_rule.py [--split fit | --fresh SEED --maps 4]
[--densities 0.1 0.2 0.3 0.4] [--seeds 2] [--nodes 300] [--localizer olstm-dvhop] [--bound]
[--cells] [--variant NAME key=value ...]``, e.g.
``--variant "cells 0.2" cell_need=0.2 --variant "sides 0.5" side_rate=0.5``.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from aoass_env.config import AOASSConfig, ConfigError, config_for_map
from aoass_env.evaluation.report import ci_stats
from aoass_env.localization import METHODS, localize
from aoass_env.maps import MAX_DENSITY, ObstacleMap, generate_map, load_map
from aoass_env.maps.registry import list_maps, validation_split
from aoass_env.metrics import localization_rmse
from aoass_env.network import Network
from aoass_env.planning import AdaptiveConfig
from aoass_env.planning.adaptive import AdaptiveSweep, coverable, site_radio, sweep_config
from aoass_env.simulator import Simulator
from aoass_env.validators import argparse_number


@dataclass(frozen=True)
class Outcome:
    """One sweep: Eq. 18 coverage, path (m), whether it ended by itself (before the time
    limit), where its uncovered nodes lie on the map, and the Eq. 15 RMSE (m) of its log's
    localization (None when not localized)."""

    coverage: float
    path: float
    ended: bool
    in_covered: int
    in_open: int
    outside: int
    rmse: float | None = None
    cells: CellsPhase | None = None


@dataclass(frozen=True)
class CellsPhase:
    """What an adaptive sweep's cells phase did: the cells it headed for, how many of them were
    covered when the sweep turned from each and by the sweep's end, how many beacons from
    everywhere the anchor can reach would cover (:func:`~aoass_env.planning.adaptive.
    coverable`), and the path (m) driven while heading for them, all and to the cells no
    reachable beacon covers."""

    visits: int
    covered_then: int
    covered_at_end: int
    coverable: int
    path: float
    path_uncoverable: float


def _run_cells(sim: Simulator, controller: AdaptiveSweep) -> CellsPhase:
    """``sim.run(controller=controller)`` (the same steps), noting the cells phase's visits."""
    visits: list[tuple[int, float, bool]] = []
    cell, since = -1, 0.0

    def close() -> None:
        if cell >= 0:
            visits.append((cell, sim.network.distance_travelled - since,
                           bool(sim.coverage_map.covered[cell])))

    for _ in range(sim.step_limit()):
        speed, heading = controller.command(sim.world.position, sim.world.heading, sim.config.dt)
        if controller.done:
            break
        if controller.cell != cell:
            close()
            cell, since = controller.cell, sim.network.distance_travelled
        sim.step(speed, heading)
    close()
    able = coverable(sim.planner, sim.coverage_map, sim.config)
    covered = sim.coverage_map.covered
    return CellsPhase(len(visits), sum(v[2] for v in visits),
                      int(sum(covered[v[0]] for v in visits)),
                      int(sum(able[v[0]] for v in visits)), sum(v[1] for v in visits),
                      sum(v[1] for v in visits if not able[v[0]]))


def sweep(obstacle_map: ObstacleMap, seed: int, nodes: int, rule: AdaptiveConfig | None,
          localizer: str | None = None, cells: bool = False) -> Outcome:
    """Sweep ``obstacle_map`` with ``nodes`` nodes and ``seed``: the plain spiral (``rule``
    None) or the adaptive sweep with ``rule``; localize its beacon log with ``localizer`` if
    given; with ``cells``, note the adaptive sweep's cells phase (:class:`CellsPhase`)."""
    config = config_for_map(AOASSConfig(n_nodes=nodes), obstacle_map)
    if rule is not None:
        config = sweep_config(config, rule, obstacle_map.width)
    sim = Simulator(config, np.random.default_rng(seed), obstacle_map=obstacle_map, seed=seed)
    controller = sim.follower() if rule is None else sim.adaptive_sweep(rule)
    phase = None
    if cells and rule is not None:
        phase = _run_cells(sim, controller)
    else:
        sim.run(controller=controller)
    cov = sim.coverage_map
    lookup = -np.ones(cov.shape, dtype=np.int64)
    lookup[cov.index[:, 0], cov.index[:, 1]] = np.arange(cov.n_cells)
    ij = np.minimum((sim.nodes // cov.cell).astype(np.int64), np.array(cov.shape) - 1)
    cell = lookup[ij[:, 0], ij[:, 1]][~sim.network.covered]
    kept = cell >= 0
    in_covered = int(cov.covered[cell[kept]].sum())
    rmse = None
    if localizer is not None:
        rmse, _ = localization_rmse(sim.nodes, localize(sim.finish(), localizer))
    return Outcome(sim.network.coverage_ratio, sim.network.distance_travelled, controller.done,
                   in_covered, int(kept.sum()) - in_covered, int((~kept).sum()), rmse, phase)


def coverage_bound(obstacle_map: ObstacleMap, seed: int, nodes: int) -> float:
    """Eq. 18 coverage (share of nodes) of the nodes of ``seed`` if a beacon were sent from every
    point of the lattice of the free field the anchor can reach (module docstring): an upper
    bound of every sweep's on these nodes, up to the lattice's 1 m spacing."""
    config = config_for_map(AOASSConfig(n_nodes=nodes), obstacle_map)
    sim = Simulator(config, np.random.default_rng(seed), obstacle_map=obstacle_map, seed=seed)
    network = Network(len(sim.nodes), config)
    for point in site_radio(sim.planner, sim.coverage_map).nodes:
        network.record_beacon(point, sim.radio.receivers(point))
    return network.coverage_ratio


def paired(outcomes: Sequence[Outcome], reference: Sequence[Outcome],
           key: str) -> tuple[int, float, float]:
    """(n, mean, 95 % CI half-width) of the paired differences ``key`` of ``outcomes`` minus
    ``reference`` on the same episodes (sweeps with a NaN or no value left out)."""
    n, mean, _, half = ci_stats([getattr(o, key) - getattr(r, key)
                                 if getattr(o, key) is not None and getattr(r, key) is not None
                                 else math.nan for o, r in zip(outcomes, reference, strict=True)])
    return n, mean, half


def _print_paired(table: dict[str, list[Outcome]], localized: bool) -> None:
    """Each variant against the configured rule on the same episodes (:func:`paired`)."""
    print("\neach variant against the rule on the same episodes: mean paired difference "
          "± 95 % interval\n")
    print("| sweep | coverage [points] | path [m] |" + " RMSE [m] |" * localized)
    print("|---|---|---|" + "---|" * localized)
    for name, outcomes in table.items():
        if name in (SPIRAL, "rule"):
            continue
        _, cov, cov_half = paired(outcomes, table["rule"], "coverage")
        _, path, path_half = paired(outcomes, table["rule"], "path")
        row = (f"| {name} | {100 * cov:+.2f} ± {100 * cov_half:.2f} | "
               f"{path:+.0f} ± {path_half:.0f} |")
        if localized:
            n, rmse, rmse_half = paired(outcomes, table["rule"], "rmse")
            row += f" {rmse:+.3f} ± {rmse_half:.3f} (n = {n}) |"
        print(row)


def _mean_rmse(outcomes: Sequence[Outcome]) -> float:
    """Mean RMSE (m) of localized sweeps (a sweep that localized no node has a NaN RMSE)."""
    return float(np.nanmean([o.rmse for o in outcomes]))


#: The reference row's name.
SPIRAL = "plain spiral"
#: With ``--bound``, the returned table's key of the bound (its outcomes' coverage; no path).
BOUND = "reachable bound"


def parse_variants(specs: Sequence[Sequence[str]]) -> dict[str, AdaptiveConfig]:
    """``--variant NAME key=value ...`` groups as rules (the configured rule first)."""
    variants = {"rule": AdaptiveConfig()}
    for name, *fields in specs:
        if name in variants or name in (SPIRAL, BOUND):
            raise ConfigError(f"--variant {name!r}: that row name is taken; choose another")
        kwargs = {}
        for item in fields:
            key, sep, value = item.partition("=")
            if not sep:
                raise ConfigError(f"--variant {name!r}: {item!r} is not key=value")
            if value.lower() in ("true", "false"):
                kwargs[key] = value.lower() == "true"
                continue
            try:
                kwargs[key] = float(value)
            except ValueError:
                raise ConfigError(f"--variant {name!r}: {key}={value!r} is not a number, true "
                                  f"or false") from None
        variants[name] = AdaptiveConfig.from_kwargs(**kwargs)
    return variants


def main(argv: Sequence[str] | None = None) -> dict[str, list[Outcome]]:
    """Run the comparison (module docstring); the outcomes of every sweep by row name."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--split", choices=("fit", "validation"),
                        help="which maps/train split (default fit; never maps/test)")
    parser.add_argument("--field", type=argparse_number(float, 0.0, low_open=True),
                        default=100.0, help="field size of the maps (m)")
    parser.add_argument("--densities", type=float, nargs="+", default=[0.1, 0.2, 0.3, 0.4])
    parser.add_argument("--seeds", type=int, default=2, help="seeds (nodes, obstacles) per map")
    parser.add_argument("--nodes", type=int, default=300, help="N")
    parser.add_argument("--limit", type=int, help="only the first LIMIT maps of the split")
    parser.add_argument("--fresh", type=argparse_number(int, 0), metavar="SEED",
                        help="freshly generated maps from SEED instead of maps/train")
    parser.add_argument("--maps", type=int,
                        help="with --fresh, generated maps per density (default 4)")
    parser.add_argument("--localizer", choices=METHODS,
                        help="also localize every sweep's log and print its RMSE")
    parser.add_argument("--bound", action="store_true",
                        help="also print the coverage of beacons from everywhere the anchor "
                             "can reach (an upper bound)")
    parser.add_argument("--cells", action="store_true",
                        help="also print what each rule's cells phase did (CellsPhase)")
    parser.add_argument("--variant", nargs="+", action="append", default=[],
                        metavar="NAME key=value", help="a rule with these fields changed")
    args = parser.parse_args(argv)
    for flag in ("seeds", "nodes", "limit", "maps"):
        value = getattr(args, flag)
        if value is not None and value < 1:
            parser.error(f"--{flag} must be at least 1, got {value}")
    try:
        variants = parse_variants(args.variant)
    except ConfigError as exc:
        parser.error(str(exc))
    if args.fresh is not None and (args.split or args.limit):
        parser.error("--fresh generates its maps: --split and --limit apply to maps/train only")
    if args.fresh is None and args.maps is not None:
        parser.error("--maps applies to --fresh only (maps/train has its own maps)")
    args.split, args.maps = args.split or "fit", args.maps or 4
    if args.fresh is not None:
        bad = [d for d in args.densities if not 0.0 <= d <= MAX_DENSITY]
        if bad:
            parser.error(f"--densities {bad[0]:g}: a generated map's density must lie in "
                         f"[0, {MAX_DENSITY:g}]")
        maps = [(d, generate_map(args.field, d, np.random.default_rng(
                    [args.fresh, round(100 * d), k]))) for d in args.densities
                for k in range(args.maps)]
        source = f"freshly generated maps (seed {args.fresh}, {args.maps} per density)"
    else:
        fit, held = validation_split(list_maps("train", field_size=args.field))
        names = [n for n in (fit if args.split == "fit" else held)
                 if any(f"/d{d:.2f}_" in n for d in args.densities)]
        names = names[:args.limit] if args.limit is not None else names
        if not names:
            parser.error(f"no maps/train map of field {args.field:g} m at densities "
                         f"{args.densities} in the {args.split} split")
        maps = [(float(n.rsplit("/d", 1)[1][:4]), load_map(n)) for n in names]
        source = f"maps of the {args.split} split"
    episodes = [(m, seed) for _, m in maps for seed in range(args.seeds)]
    density = np.repeat([d for d, _ in maps], args.seeds)
    spiral = [sweep(m, s, args.nodes, None, args.localizer) for m, s in episodes]
    print(f"{len(maps)} {source} x {args.seeds} seeds, N = {args.nodes}")
    table = {SPIRAL: spiral}
    rmse_head = f" RMSE {args.localizer} [m] |" if args.localizer else ""
    print("| sweep | coverage |" + rmse_head + " path [m] | path / spiral's | ended by itself | "
          "uncovered nodes: in covered cells / in open cells / outside the map's cells |")
    print("|---|---|" + "---|" * bool(rmse_head) + "---|---|---|---|")
    table.update({name: [sweep(m, s, args.nodes, rule, args.localizer, args.cells)
                         for m, s in episodes] for name, rule in variants.items()})
    for name, outcomes in table.items():
        cov = np.mean([o.coverage for o in outcomes])
        path = np.mean([o.path for o in outcomes])
        share = np.mean([o.path / s.path for o, s in zip(outcomes, spiral, strict=True)])
        where = [sum(getattr(o, k) for o in outcomes)
                 for k in ("in_covered", "in_open", "outside")]
        ended = np.mean([o.ended for o in outcomes])
        rmse = f" {_mean_rmse(outcomes):.3f} |" if rmse_head else ""
        print(f"| {name} | {cov:.2%} |{rmse} {path:.0f} | {share:.3f} | {ended:.0%} | "
              f"{where[0]} / {where[1]} / {where[2]} |")
    if len(table) > 2:
        _print_paired(table, bool(rmse_head))
    levels = sorted(set(density))
    print(f"\ncoverage / path share of the spiral's{' / RMSE (m)' * bool(rmse_head)}, "
          "by density\n")
    print("| sweep | " + " | ".join(f"d = {d:.1f}" for d in levels) + " |")
    print("|---|" + "---|" * len(levels))
    for name, outcomes in table.items():
        cells = []
        for d in levels:
            pick = [(o, s) for o, s, k in zip(outcomes, spiral, density, strict=True) if k == d]
            rmse = f" / {_mean_rmse([o for o, _ in pick]):.2f}" if rmse_head else ""
            cells.append(f"{np.mean([o.coverage for o, _ in pick]):.2%} / "
                         f"{np.mean([o.path / s.path for o, s in pick]):.3f}{rmse}")
        print(f"| {name} | " + " | ".join(cells) + " |")
    if args.cells:
        print("\nthe cells phase, per sweep: cells headed for / of them covered when the sweep "
              "turned from them / covered by the sweep's end / coverable from where the anchor "
              "can reach; path heading for them (m) / of it to the cells no reachable beacon "
              "covers\n")
        print("| sweep | cells | covered then | covered at the end | coverable | path [m] | "
              "to uncoverable cells [m] |")
        print("|---|---|---|---|---|---|---|")
        for name, outcomes in table.items():
            if name == SPIRAL:
                continue
            mean = {k: np.mean([getattr(o.cells, k) for o in outcomes])
                    for k in CellsPhase.__dataclass_fields__}
            print(f"| {name} | {mean['visits']:.1f} | {mean['covered_then']:.1f} | "
                  f"{mean['covered_at_end']:.1f} | {mean['coverable']:.1f} | "
                  f"{mean['path']:.0f} | {mean['path_uncoverable']:.0f} |")
    if args.bound:
        bound = np.array([coverage_bound(m, s, args.nodes) for m, s in episodes])
        print("| reachable bound (coverage) | " + " | ".join(
            f"{bound[density == d].mean():.2%}" for d in levels) + " |")
        print(f"\nreachable bound over all sweeps: {bound.mean():.2%} (lowest {bound.min():.2%})")
        table[BOUND] = [Outcome(b, 0.0, True, 0, 0, 0) for b in bound]
    return table


if __name__ == "__main__":
    main()
