"""The evaluated methods: one registry, name -> :class:`MethodSpec`, and a runner per kind.

Every runner plays one episode in AOASS-v0's simulator (same radio, energy model and beacon
interval) and returns the finished :class:`~aoass_env.simulator.Simulator` with its beacon log:

* ``aoass``: the full stack of :func:`aoass_env.make_safe_env` (square spiral + Kalman tracks +
  fuzzy-ORCA) driven by the shipped TD3-LSTM policy;
* ``aoass-scripted``: the same stack with the zero action (the ablation without the policy);
* ``aoass-rule``: the stack with the adaptive action type and the zero action: the hand-written
  coverage-aware rule at :class:`~aoass_env.planning.AdaptiveConfig`'s defaults (the spiral
  pruned ahead on the static map, :mod:`aoass_env.planning.pruning`, then densified), the
  strong baseline;
* ``aoass-adaptive``: the same stack driven by the adaptive TD3-LSTM policy
  (``checkpoints/aoass_adaptive/best.zip``), when it is shipped, with the rule its run record
  names (the shipped one was trained on the site tour, every field of the rule named);
* ``spiral``: the plain square spiral with the nominal follower, no safety stack;
* every :class:`~aoass_env.planning.PlannedMethod` of
  :data:`~aoass_env.planning.classical.CLASSICAL_METHODS` and
  :data:`~aoass_env.planning.baselines.BASELINE_METHODS`, registered here at import time.

A runner draws every random number from one generator seeded with the episode's seed, nodes
first, so all methods see the same nodes on the same map and seed.
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from aoass_env.beacon_log import BeaconLog
from aoass_env.config import AOASSConfig
from aoass_env.data import shipped_dir
from aoass_env.evaluation.store import EvaluationError
from aoass_env.maps import ObstacleMap
from aoass_env.planning import AdaptiveConfig, PlannedMethod
from aoass_env.planning.baselines import BASELINE_METHODS
from aoass_env.planning.classical import CLASSICAL_METHODS
from aoass_env.planning.sweep import Controller
from aoass_env.safety.config import SafetyConfig, TrackerConfig
from aoass_env.simulator import Simulator
from aoass_env.wrappers import POLICY_STACK_KEYS, make_safe_env

__all__ = ["DEFAULT_POLICY", "METHODS", "MethodRun", "MethodSpec",
           "RunOptions", "config_defaults_digest", "select_methods"]


def config_defaults_digest(configs: Sequence[type]) -> str:
    """SHA-256 (hex) of the defaults of the config classes ``configs``: a method's rows made
    with other defaults of the configs it is built from (a rule's threshold tuned since) must
    not be mixed with this run's in one table (:attr:`MethodSpec.configs`)."""
    defaults = {cls.__name__: cls().to_dict() for cls in configs}
    text = json.dumps(defaults, sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()


#: The configs whose defaults a method's episodes depend on: every method's (the environment),
#: the safety stack's and the adaptive sweep's rule.
PLAIN_CONFIGS: tuple[type, ...] = (AOASSConfig,)
STACK_CONFIGS: tuple[type, ...] = (AOASSConfig, SafetyConfig, TrackerConfig)
ADAPTIVE_CONFIGS: tuple[type, ...] = (*STACK_CONFIGS, AdaptiveConfig)

#: The shipped AOASS policy and the algorithm that saved it.
DEFAULT_POLICY = shipped_dir("checkpoints") / "aoass_td3_lstm" / "best.zip"
POLICY_ALGO = "td3-lstm"
#: The keys of :data:`POLICY_STACK_KEYS` that are environment config fields.
_ACTION_KEYS = ("action_speed_scale", "action_heading_scale", "obs_coverage_sectors")
#: The shipped adaptive policy (``aoass-adaptive``) and the command that produces it.
ADAPTIVE_POLICY = shipped_dir("checkpoints") / "aoass_adaptive" / "best.zip"
ADAPTIVE_POLICY_COMMAND = ("python3 train.py --config configs/aoass_adaptive.yml --seed 4 "
                           "--threads 1 --out checkpoints/aoass_adaptive --overwrite")
#: The command that produces :data:`DEFAULT_POLICY` (``--overwrite``: the folder keeps the
#: shipped run's other files).
POLICY_COMMAND = ("python3 train.py --algo td3-lstm --out checkpoints/aoass_td3_lstm "
                  "--overwrite")


@dataclass(frozen=True)
class RunOptions:
    """Settings shared by every episode of a sweep.

    Attributes:
        policy: checkpoint of the ``aoass`` policy (a .zip saved by ``algo``).
        algo: the algorithm that saved ``policy`` (``td3-lstm``, or ``td3`` for the
            feedforward ablation).
        max_steps: stop an episode after this many control periods (``dt`` = 0.5 s each);
            None: each method's own limit (the environment's time limit for the safety stack,
            ``Simulator.run``'s for the others).
        policy_run: the run record (run.yml) of the stack ``policy`` was trained in; None: the
            one beside ``policy``.
        adaptive_policy: checkpoint of the ``aoass-adaptive`` policy (a TD3-LSTM .zip with its
            run.yml beside it).
        constant_action: with it, the learned methods (``aoass``, ``aoass-adaptive``) take this
            action, in [-1, 1] per entry, at every decision instead of their policy's, in the
            stack their policy was trained in (a constant-action probe of what the policy
            learned; ``benchmarks/agent_vs_spiral.py --constant``).
    """

    policy: str = str(DEFAULT_POLICY)
    algo: str = POLICY_ALGO
    max_steps: int | None = None
    policy_run: str | None = None
    adaptive_policy: str = str(ADAPTIVE_POLICY)
    constant_action: tuple[float, ...] | None = None


@dataclass(frozen=True)
class MethodRun:
    """A finished episode: the simulator, its beacon log, whether the method ended it itself
    (False: cut by the step limit) and, for the safety stack, the mean safety intervention
    |v* - v_des| (m/s) per agent decision, the Eq. 14 return and the actions taken, one row
    per decision (None for other methods)."""

    sim: Simulator
    log: BeaconLog
    complete: bool
    safety_intervention: float | None = None
    episode_return: float | None = None
    actions: np.ndarray | None = None


#: (config, obstacle map, seed, options) -> the finished episode.
Runner = Callable[[AOASSConfig, ObstacleMap, int, RunOptions], MethodRun]


@dataclass(frozen=True)
class MethodSpec:
    """One evaluated method: command-line name, label for tables and figures, kind ("aoass",
    "ablation", "spiral", "classical" or "baseline"), runner, whether it needs the policy
    checkpoint of ``--policy``, a shipped checkpoint of its own it needs (with the command
    that produces it), if any, and the config classes whose defaults its episodes depend on."""

    name: str
    label: str
    kind: str
    runner: Runner
    uses_policy: bool = False
    checkpoint: Path | None = None
    checkpoint_command: str = ""
    configs: tuple[type, ...] = PLAIN_CONFIGS
    #: the recorded stack of the zero-action ablations: the ``--policy``'s ("policy") or the
    #: shipped adaptive policy's ("adaptive"); "" for the others (:func:`zero_action_stack`)
    stack: str = ""

    @property
    def defaults_digest(self) -> str:
        """:func:`config_defaults_digest` of :attr:`configs`."""
        return config_defaults_digest(self.configs)

    @property
    def available(self) -> bool:
        """Whether the checkpoint of its own, if it needs one, is there."""
        return self.checkpoint is None or self.checkpoint.is_file()


@functools.lru_cache(maxsize=2)
def load_policy(path: str, algo: str = POLICY_ALGO, record: str | None = None) -> Any:
    """The policy saved at ``path`` by ``algo``, loaded once per process (on the CPU) without
    unpickling anything, rebuilt from ``record`` (default: the run.yml beside it)."""
    from agents.hyperparams import ALGORITHMS  # the agent's stack: imported only when used
    return ALGORITHMS[algo].load(path, device="cpu", record=record)


def policy_stack(path: str, record: str | None = None) -> dict[str, Any]:
    """The :func:`~aoass_env.make_safe_env` keywords of :data:`POLICY_STACK_KEYS` that the policy
    at ``path`` was trained with, read from its run record (``record``, else the ``run.yml``
    that ``train.py`` writes beside it; ``hyperparameters.env``, validated); empty when there
    is no such file."""
    from agents.checkpoints import record_path
    run = Path(record) if record is not None else record_path(path)
    if not run.is_file():
        return {}
    return _recorded_stack(str(run), run.stat().st_mtime_ns)


@functools.lru_cache(maxsize=4)
def _recorded_stack(record: str, mtime_ns: int) -> dict[str, Any]:
    """:func:`policy_stack` of one version (``mtime_ns``) of a run record, read once."""
    from agents.hyperparams import read_run_record
    env = read_run_record(record)["hyperparameters"].get("env", {})
    return {k: env[k] for k in POLICY_STACK_KEYS if k in env}


#: The entries of a recorded stack that a zero-action run depends on: what filters and tracks
#: the anchor, and what an action means (the decision period, the residual's scales and the
#: observation's coverage sectors change nothing the zero action does).
ZERO_ACTION_STACK_KEYS = ("tracker", "safety", "action_type")


def _stack(options: RunOptions, *, learned: bool, adaptive: bool) -> dict[str, Any]:
    """The :func:`~aoass_env.make_safe_env` keywords a stack method plays in (the policy's
    recorded stack; the adaptive rule without the sweep rule its policy was trained on)."""
    if not adaptive:
        return policy_stack(options.policy, options.policy_run)
    stack = {"action_type": "adaptive", **policy_stack(options.adaptive_policy)}
    if not learned:   # the rule at AdaptiveConfig's defaults, not the one the policy knew
        stack.pop("adaptive", None)
    return stack


def zero_action_stack(name: str, options: RunOptions) -> dict[str, Any]:
    """What the episodes of zero-action method ``name`` (a :class:`MethodSpec` with a
    ``stack``) take from the run record they play in: its :data:`ZERO_ACTION_STACK_KEYS`, so
    that evaluate.py can tell rows made in another stack (another ``--policy-run``, a retrained
    policy that sets ``safety``) from this one's."""
    spec = METHODS[name]
    if not spec.stack or spec.uses_policy or spec.checkpoint is not None:
        raise ValueError(f"{name} is not a zero-action method of a recorded stack")
    stack = _stack(options, learned=False, adaptive=spec.stack == "adaptive")
    return {k: stack[k] for k in ZERO_ACTION_STACK_KEYS if k in stack}


def zero_action_stack_digest(name: str, options: RunOptions) -> str:
    """SHA-256 (hex) of :func:`zero_action_stack`: the input of evaluate.py's record that
    ties that method's rows to the stack they were played in."""
    text = json.dumps(zero_action_stack(name, options), sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()


def _run_safety_stack(config: AOASSConfig, obstacle_map: ObstacleMap, seed: int,
                      options: RunOptions, *, learned: bool, adaptive: bool = False
                      ) -> MethodRun:
    """AOASS-v0 inside the Kalman + fuzzy-ORCA stack (set up as the policy was trained), driven
    by the policy (``learned``, one decision every ``action_repeat`` control periods) or the
    zero action, until the episode ends or ``options.max_steps`` control periods; ``adaptive``:
    the adaptive action type and its policy (``options.adaptive_policy``)."""
    if adaptive:
        path, algo, record = options.adaptive_policy, POLICY_ALGO, None
    else:
        path, algo, record = options.policy, options.algo, options.policy_run
    stack = _stack(options, learned=learned, adaptive=adaptive)
    repeat = int(stack.get("action_repeat", 1)) if learned else 1
    config = config.replace(**{k: stack[k] for k in _ACTION_KEYS if k in stack})
    env = make_safe_env(config=config, tracker=stack.get("tracker"),
                        safety=stack.get("safety"), action_repeat=repeat,
                        action_type=stack.get("action_type", "residual"),
                        adaptive=stack.get("adaptive"))
    if not learned:
        constant: np.ndarray | None = np.zeros(env.action_space.shape, np.float32)
    elif options.constant_action is not None:
        constant = _constant_action(options.constant_action, env.action_space)
    else:
        constant = None
    policy = load_policy(path, algo, record) if constant is None else None
    obs, _ = env.reset(seed=seed, options={"map": obstacle_map})
    state, start = None, np.ones(1, dtype=bool)
    interventions: list[float] = []
    actions: list[np.ndarray] = []
    limit = options.max_steps if options.max_steps is not None else math.inf
    steps, total, terminated, truncated = 0, 0.0, False, False
    while not (terminated or truncated) and steps < limit:
        if policy is None:
            action = constant.copy()
        else:
            action, state = policy.predict(obs, state=state, episode_start=start,
                                           deterministic=True)
            start = np.zeros(1, dtype=bool)
        actions.append(np.asarray(action, dtype=np.float32).ravel())
        obs, reward, terminated, truncated, info = env.step(action)
        total += float(reward)
        if "safety" in info:
            interventions.append(info["safety"]["intervention"])
        steps += repeat
    base = env.unwrapped
    run = MethodRun(base.sim, base.beacon_log, terminated,
                    float(np.mean(interventions)) if interventions else None, total,
                    np.array(actions).reshape(len(actions), *env.action_space.shape))
    env.close()
    return run


def _constant_action(values: tuple[float, ...], space: Any) -> np.ndarray:
    """``RunOptions.constant_action`` as an action of ``space`` (a Box in [-1, 1]); ValueError
    naming ``constant_action`` when its length or a value is not valid."""
    action = np.asarray(values, dtype=np.float64).ravel()
    if action.shape != space.shape:
        raise ValueError(f"constant_action has {action.size} entries; this stack's actions "
                         f"have {space.shape[0]}")
    if not np.all(np.abs(action) <= 1.0):     # NaN fails too
        raise ValueError(f"constant_action={tuple(values)!r}: every entry must lie in [-1, 1]")
    return action.astype(np.float32)


def _run_simulator(sim: Simulator, options: RunOptions,
                   controller: Controller | None = None) -> MethodRun:
    """Drive ``sim`` with ``controller`` (None: the nominal follower of its path) until it is
    done or the step limit (``options.max_steps``, else ``time_limit_factor`` times the path's
    nominal duration)."""
    limit = (options.max_steps if options.max_steps is not None
             else sim.step_limit())
    log = sim.run(max_steps=limit, controller=controller)
    return MethodRun(sim, log, complete=len(log.anchor_path) - 1 < limit)


def _run_spiral(config: AOASSConfig, obstacle_map: ObstacleMap, seed: int,
                options: RunOptions) -> MethodRun:
    """The square spiral with the nominal follower, no safety stack."""
    sim = Simulator(config, np.random.default_rng(seed), obstacle_map=obstacle_map, seed=seed,
                    method="spiral")
    return _run_simulator(sim, options)


def _run_planned(method: PlannedMethod, config: AOASSConfig, obstacle_map: ObstacleMap,
                 seed: int, options: RunOptions) -> MethodRun:
    """A classical path or a baseline: its planned path in the simulator, driven by its own
    controller or else the nominal follower."""
    sim = Simulator(config, np.random.default_rng(seed), obstacle_map=obstacle_map, seed=seed,
                    method=method.name, path=method.plan(obstacle_map, config))
    return _run_simulator(sim, options,
                          method.controller(sim) if method.controller is not None else None)


def _registry() -> dict[str, MethodSpec]:
    methods = {
        "aoass": MethodSpec("aoass", "AOASS", "aoass",
                            functools.partial(_run_safety_stack, learned=True), uses_policy=True,
                            configs=STACK_CONFIGS, stack="policy"),
        "aoass-scripted": MethodSpec("aoass-scripted", "AOASS, zero action (ablation)",
                                     "ablation",
                                     functools.partial(_run_safety_stack, learned=False),
                                     configs=STACK_CONFIGS, stack="policy"),
        "aoass-rule": MethodSpec("aoass-rule", "AOASS, adaptive rule", "ablation",
                                 functools.partial(_run_safety_stack, learned=False,
                                                   adaptive=True),
                                 configs=ADAPTIVE_CONFIGS, stack="adaptive"),
        "aoass-adaptive": MethodSpec("aoass-adaptive", "AOASS, adaptive policy", "aoass",
                                     functools.partial(_run_safety_stack, learned=True,
                                                       adaptive=True),
                                     checkpoint=ADAPTIVE_POLICY,
                                     checkpoint_command=ADAPTIVE_POLICY_COMMAND,
                                     configs=ADAPTIVE_CONFIGS, stack="adaptive"),
        "spiral": MethodSpec("spiral", "Square spiral", "spiral", _run_spiral),
    }
    for kind, planned in (("classical", CLASSICAL_METHODS), ("baseline", BASELINE_METHODS)):
        for name, method in planned.items():
            if name in methods:
                raise RuntimeError(f"method name {name!r} is registered twice")
            methods[name] = MethodSpec(name, method.label, kind,
                                       functools.partial(_run_planned, method))
    return methods


#: Every evaluated method by command-line name, in the order of tables and figures.
METHODS: dict[str, MethodSpec] = _registry()


def select_methods(names: Sequence[str] | None, policy: str | Path = DEFAULT_POLICY
                   ) -> list[str]:
    """The methods to run (None: all, less those whose own checkpoint is not shipped:
    ``aoass-adaptive``), checked before any work.

    Raises:
        EvaluationError: an unknown name (the message lists the valid ones), or a method that
            needs the policy while its checkpoint file is missing.
    """
    chosen = ([n for n, spec in METHODS.items() if spec.available]
              if names is None else list(dict.fromkeys(names)))
    unknown = [n for n in chosen if n not in METHODS]
    if unknown:
        raise EvaluationError(f"unknown method(s) {', '.join(map(repr, unknown))}; valid: "
                              f"{', '.join(METHODS)}")
    for spec in (METHODS[n] for n in chosen):
        if not spec.available:
            raise EvaluationError(
                f"method {spec.name} needs the checkpoint {spec.checkpoint}, which is missing; "
                f"produce it with `{spec.checkpoint_command}`")
    needs = [n for n in chosen if METHODS[n].uses_policy]
    if needs and not Path(policy).is_file():
        raise EvaluationError(
            f"method(s) {', '.join(needs)} need the AOASS policy checkpoint {policy}, which is "
            f"missing; produce it with `{POLICY_COMMAND}` (see docs/training.md)")
    return chosen
