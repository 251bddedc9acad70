"""Does the shipped AOASS policy help? It against the zero action, both inside the safety stack.

With ``--adaptive``, the adaptive policy against the hand-written rule (the adaptive action
type's zero action, issue 19: a higher return, energy no higher, coverage within 0.5 point).

On the shipped 100 m test maps of densities 0.1-0.4 (``--densities``: any of 0.1-0.6),
``--seeds`` seeds per density (each seed a test map of that density in turn, the same episodes
for both), both policies drive the full stack (AOASS-Safe-v0). Per episode: the Eq. 14 return,
η_traj (Eq. 19), node coverage (Eq. 18) and anchor contacts. Issue 6's criteria: a higher mean
return, η_traj no lower, coverage no more than 1 point lower, no more contacts. Prints a table
per density and overall (means, and the mean paired difference with its 95 % interval) and saves
``OUT/results.json`` and ``OUT/episodes.csv``.

With ``--maps validation`` the episodes are on the validation split of the 100 m training maps
instead (:func:`~aoass_env.maps.registry.validation_split`): the maps on which to choose between
policies, since maps/test is for reported tables only. That split holds one map per density;
with ``--maps fresh --fresh SEED`` episode s of a density runs on a map generated for it
instead (``generate_map(100, d, default_rng([SEED, round(100 d), s]))``, every episode its own
map): take a SEED used nowhere else, and choose on it or check a choice on it.

With ``--constant a,b,...`` the "agent" takes that action at every decision instead of the
model's, in the stack the model was trained in (a constant-action probe: does the policy do
better than its own typical action held fixed?).

With ``--localizer olstm-dvhop`` (or ``dvhop``, ``consensus``) every episode's beacon log is
localized too, and the Eq. 15 RMSE (m, over the localized nodes) is a column and a criterion
(no higher than the zero action's): a policy that saves path by passing over beacon sites can
cost localization, which return and energy do not show.

Run: ``python3 benchmarks/agent_vs_spiral.py [--model checkpoints/aoass_td3_lstm/best.zip]
[--algo td3-lstm] [--seeds 30] [--jobs 2] [--maps test|validation|fresh] [--fresh SEED]
[--constant a,b,...] [--localizer olstm-dvhop]``.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
from functools import lru_cache
from multiprocessing import Pool
from pathlib import Path

import numpy as np
import torch

from agents.checkpoints import PolicyFileError
from aoass_env.action import AdaptiveAction, ResidualAction
from aoass_env.atomic import folder_problem, write_text_atomic
from aoass_env.config import AOASSConfig
from aoass_env.evaluation.episode import episode_metrics, localization_row
from aoass_env.evaluation.methods import DEFAULT_POLICY, METHODS, RunOptions, load_policy
from aoass_env.localization import METHODS as LOCALIZERS
from aoass_env.maps import ObstacleMap, generate_map, list_maps, load_map
from aoass_env.maps.registry import validation_split
from aoass_env.validators import argparse_number

DENSITIES = ("0.10", "0.20", "0.30", "0.40")
#: The densities ``--densities`` may name: those of the shipped maps.
ALL_DENSITIES = (*DENSITIES, "0.50", "0.60")
#: An action entry at or beyond this magnitude counts as at its bound (``saturated``).
SATURATED = 0.9
METRICS = ("return", "eta_traj", "coverage", "energy", "contacts", "steps")


#: Prefix of a freshly generated map's name (``fresh/d0.30_s<SEED>_<s>``, :func:`fresh_map`).
FRESH = "fresh/"


def density_name(text: str) -> str:
    """``--densities``' value ``text`` as a density's name (``"0.5"`` -> ``"0.50"``)."""
    try:
        name = f"{float(text):.2f}"
    except ValueError:
        name = ""
    if name not in ALL_DENSITIES:
        raise argparse.ArgumentTypeError(f"{text!r} is not one of {', '.join(ALL_DENSITIES)}")
    return name


def fresh_name(seed: int, density: str, index: int) -> str:
    """The name of generated map ``index`` of ``density`` (e.g. ``"0.30"``) from ``seed``."""
    return f"{FRESH}d{density}_s{seed}_{index}"


@lru_cache(maxsize=4)
def fresh_map(name: str) -> ObstacleMap:
    """The 100 m map of a :func:`fresh_name`: ``generate_map(100, d, default_rng([SEED,
    round(100 d), index]))``."""
    density, seed, index = name.removeprefix(FRESH).split("_")
    d = float(density[1:])
    return generate_map(100.0, d, np.random.default_rng([int(seed[1:]), round(100 * d),
                                                         int(index)]), name=name)


def episode(task: tuple) -> dict:
    """(policy: an algorithm name or 'zero', map name, seed, model path, adaptive, constant
    action or None, localizer or None) -> the episode's record. The evaluation's runners play
    it: the policy acts in the stack it was trained in (``action_repeat`` etc. from the
    ``run.yml`` beside the model); with a localizer the record holds its Eq. 15 ``rmse`` (m)."""
    policy, map_name, seed, model_path, adaptive, constant, localizer = task
    torch.set_num_threads(1)
    if map_name.startswith(FRESH):
        obstacle_map = fresh_map(map_name)
        config = AOASSConfig(field_size=obstacle_map.width)
    else:
        obstacle_map = load_map(map_name)
        config = AOASSConfig(field_size=obstacle_map.width, map=map_name)
    if adaptive:
        method = "aoass-rule" if policy == "zero" else "aoass-adaptive"
        options = RunOptions(adaptive_policy=model_path, constant_action=constant)
    else:
        method = "aoass-scripted" if policy == "zero" else "aoass"
        options = RunOptions(policy=model_path, algo="td3-lstm" if policy == "zero" else policy,
                             constant_action=constant)
    run = METHODS[method].runner(config, obstacle_map, seed, options)
    m = episode_metrics(run)
    names = (AdaptiveAction if adaptive else ResidualAction).NAMES
    rmse = {} if localizer is None else {"rmse": localization_row(run.log, localizer)["rmse"]}
    return {"policy": "zero" if policy == "zero" else "agent", "map": map_name,
            "density": map_name.split("/")[1][1:5],
            "seed": seed, "return": run.episode_return, "eta_traj": m["eta_traj"],
            "coverage": m["coverage"], "energy": m["energy_total"], "contacts": m["collisions"],
            "steps": round(m["travel_time"] / config.dt), "complete": bool(m["path_complete"]),
            **rmse, **action_summary(run.actions, names)}


def action_summary(actions: np.ndarray, names: tuple[str, ...]) -> dict[str, float]:
    """What a policy did in an episode of (decisions, entries) ``actions``: its mean action per
    entry (``mean_<name>``) and the share of all entries at +-:data:`SATURATED` or beyond
    (``saturated``: a policy pinned to its bounds shows 1)."""
    return {**{f"mean_{n}": float(actions[:, i].mean()) for i, n in enumerate(names)},
            "saturated": float((np.abs(actions) >= SATURATED).mean())}


def parse_constant(text: str, adaptive: bool) -> tuple[float, ...]:
    """``--constant``'s comma-separated action (one entry per name of the adaptive action type
    with ``--adaptive``, else of the residual one), each in [-1, 1]; ValueError naming the flag
    otherwise (before any episode runs; the runner checks the action against the stack's
    space again)."""
    size = len((AdaptiveAction if adaptive else ResidualAction).NAMES)
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"--constant {text!r}: not {size} comma-separated numbers") from None
    if len(values) != size or not all(-1.0 <= v <= 1.0 for v in values):
        raise ValueError(f"--constant {text!r}: {size} numbers in [-1, 1] expected (the "
                         f"{'adaptive' if adaptive else 'residual'} action)")
    return values


def paired(rows: list[dict], key: str) -> tuple[float, float]:
    """Mean paired difference agent - zero and the half-width of its 95 % interval."""
    by = {(r["map"], r["seed"], r["policy"]): r[key] for r in rows}
    diffs = np.array([by[(m, s, "agent")] - by[(m, s, "zero")]
                      for (m, s, p) in by if p == "agent"])
    half = 1.96 * diffs.std(ddof=1) / np.sqrt(len(diffs)) if len(diffs) > 1 else float("nan")
    return float(diffs.mean()), float(half)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--model", type=Path, default=DEFAULT_POLICY,
                        help="the policy .zip (default: the shipped residual policy)")
    parser.add_argument("--algo", choices=["td3-lstm", "td3"], default="td3-lstm",
                        help="the algorithm that saved --model (default: td3-lstm)")
    parser.add_argument("--adaptive", action="store_true",
                        help="--model is an adaptive policy (checkpoints/aoass_adaptive/best.zip):"
                             " compare it with the hand-written rule, the adaptive zero action")
    parser.add_argument("--seeds", type=argparse_number(int, 1), default=30,
                        help="episodes per density")
    parser.add_argument("--jobs", type=argparse_number(int, 1), default=2)
    parser.add_argument("--maps", choices=("test", "validation", "fresh"), default="test",
                        help="maps/test (reported tables), the validation split of maps/train "
                             "(choosing between policies) or maps generated from --fresh")
    parser.add_argument("--fresh", type=int, metavar="SEED",
                        help="with --maps fresh: the generated maps' seed (one map per episode)")
    parser.add_argument("--constant", metavar="A,B,...",
                        help="take this action at every decision instead of --model's (in "
                             "--model's stack)")
    parser.add_argument("--densities", nargs="+", type=density_name, default=list(DENSITIES),
                        metavar="D",
                        help=f"the map densities, each one of {', '.join(ALL_DENSITIES)} "
                             f"(default: {' '.join(DENSITIES)}, the policies' training range)")
    parser.add_argument("--localizer", choices=LOCALIZERS,
                        help="also localize every beacon log with this localizer and compare "
                             "the Eq. 15 RMSE")
    parser.add_argument("--out", type=Path, default=Path("out/bench_agent"))
    args = parser.parse_args()
    problem = folder_problem(args.out)    # refused now, not after the work
    if problem is not None:
        parser.error(f"--out {args.out}: {problem}")
    if not args.model.is_file():
        parser.error(f"--model {args.model}: no such file")
    try:              # here, in one line, rather than in every worker of the pool
        load_policy(str(args.model.resolve()), "td3-lstm" if args.adaptive else args.algo)
    except PolicyFileError as err:
        parser.error(f"--model: {err}")
    try:
        constant = (parse_constant(args.constant, args.adaptive) if args.constant is not None
                    else None)
    except ValueError as err:
        parser.error(str(err))
    if (args.maps == "fresh") != (args.fresh is not None):
        parser.error("--fresh SEED goes with --maps fresh, and --maps fresh needs --fresh SEED")
    if args.fresh is not None and args.fresh < 0:
        parser.error(f"--fresh must be a non-negative seed, got {args.fresh}")
    metrics = METRICS + (("rmse",) if args.localizer else ())
    densities = tuple(dict.fromkeys(args.densities))
    tasks = []
    for d in densities:
        if args.maps == "test":
            maps = list_maps("test", field_size=100, densities=(float(d), float(d)))
        elif args.maps == "fresh":
            maps = [fresh_name(args.fresh, d, s) for s in range(args.seeds)]
        else:
            maps = validation_split(list_maps("train", field_size=100,
                                              densities=(float(d), float(d))))[1]
        for s in range(args.seeds):
            for policy in (args.algo, "zero"):
                tasks.append((policy, maps[s % len(maps)], 100 + s, str(args.model.resolve()),
                              args.adaptive, constant if policy != "zero" else None,
                              args.localizer))
    with Pool(args.jobs) as pool:
        rows = pool.map(episode, tasks, chunksize=1)

    what = f"the constant action {constant}" if constant is not None else args.model
    where = f"fresh maps of seed {args.fresh}" if args.fresh is not None else \
        f"{args.maps} maps"
    print(f"{what}: {args.seeds} episodes per density on the {where}, both inside the safety "
          "stack")
    print(f"{'density':8s} {'policy':7s} " + " ".join(f"{k:>9s}" for k in metrics))
    summary: dict = {}
    for d in (*densities, "all"):
        sel = [r for r in rows if d == "all" or r["density"] == d]
        summary[d] = {}
        for policy in ("agent", "zero"):
            mine = [r for r in sel if r["policy"] == policy]
            means = {k: float(np.mean([r[k] for r in mine])) for k in metrics}
            summary[d][policy] = means
            print(f"{d:8s} {policy:7s} " + " ".join(f"{means[k]:9.3f}" for k in metrics))
        summary[d]["difference"] = {k: paired(sel, k) for k in metrics}
        print(f"{d:8s} {'diff':7s} " + " ".join(
            f"{summary[d]['difference'][k][0]:+9.3f}" for k in metrics))
    overall = summary["all"]
    verdict = {
        "higher_return": overall["agent"]["return"] > overall["zero"]["return"],
        "eta_traj_no_lower": overall["agent"]["eta_traj"] >= overall["zero"]["eta_traj"],
        "coverage_within_1pt": overall["agent"]["coverage"] >= overall["zero"]["coverage"]
        - 0.01,
        "energy_no_higher": overall["agent"]["energy"] <= overall["zero"]["energy"],
        "no_more_contacts": overall["agent"]["contacts"] <= overall["zero"]["contacts"],
    }
    if args.localizer:
        verdict["rmse_no_higher"] = overall["agent"]["rmse"] <= overall["zero"]["rmse"]
    agent = [r for r in rows if r["policy"] == "agent"]
    means = {k[5:]: round(float(np.mean([r[k] for r in agent])), 3)
             for k in agent[0] if k.startswith("mean_")}
    summary["actions"] = {"mean": means,
                          "saturated": float(np.mean([r["saturated"] for r in agent]))}
    print(f"the agent's mean action {means}; share of its action entries at +-{SATURATED} or "
          f"beyond: {summary['actions']['saturated']:.3f}")
    print("criteria:", ", ".join(f"{k} {'met' if v else 'MISSED'}" for k, v in verdict.items()))
    args.out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(args.out / "results.json", json.dumps(
        {"model": str(args.model), "constant": constant, "seeds": args.seeds,
         "localizer": args.localizer, "summary": summary,
         "criteria": verdict}, indent=1))
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
    write_text_atomic(args.out / "episodes.csv", buf.getvalue())
    print(f"wrote {args.out / 'results.json'}")


if __name__ == "__main__":
    main()
