"""Training pipeline of the OLSTM reception model: beacon logs, examples, training, checkpoint.

1. **Logs.** :func:`episode_specs` draws square-spiral episodes on the shipped *training* maps
   only (``maps/train``): DOI in {0, 0.05, 0.1, 0.15, 0.2}, moving obstacles on (the default
   config), 100 m fields with N in {100, 200, 300, 500} and, in 8 % of the episodes, 200 m fields
   with N in {500, 1000}. The validation maps of :func:`aoass_env.maps.validation_split` are held
   out. :func:`generate_logs` simulates them into ``<folder>/train`` and ``<folder>/val`` with the
   anchor's true DOI pattern beside each log (``*_K.npy``, the training target; never read at
   inference), and reuses what is there when its recorded config is the one the episode would
   run now (a log simulated before a config default changed is simulated again).
2. **Examples.** Per log with DOI > 0: the first consensus pass, the pair record of its reliable
   nodes (:func:`~aoass_env.localization.reception.pair_statistics`) and the target
   z_K = (K - 1) / DOI per degree. Each training draw keeps a random 50-100 % share of the nodes
   and rotates the 360 degrees by a random shift (the pattern has no preferred direction).
3. **Training.** Gaussian negative log-likelihood of z_K, Adam, a fixed seed, one thread; the
   epoch with the lowest validation NLL is kept. Then the band width (standard deviations on each
   side of the mean) is chosen among ``BAND_WIDTHS`` by the pooled OLSTM-DV-Hop RMSE on the
   validation logs, and the checkpoint is written.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from aoass_env.atomic import atomic_open
from aoass_env.beacon_log import BeaconLog, BeaconLogError, episode_config_json
from aoass_env.config import AOASSConfig
from aoass_env.localization.consensus import RELIABLE_SPREAD, node_consensus
from aoass_env.localization.episode import Episode, prepare
from aoass_env.localization.olstm import DEFAULT_CHECKPOINT, OLSTM, olstm_dvhop, save_checkpoint
from aoass_env.localization.reception import PairRecord, pair_histograms, pair_statistics
from aoass_env.maps import list_maps, load_map, validation_split
from aoass_env.simulator import Simulator
from aoass_env.validators import first_difference, integer, one_line, real

__all__ = ["BAND_WIDTHS", "TRAIN_RANGES", "CachedLogError", "DivergedError", "EpisodeSpec",
           "Example", "TrainConfig", "augment", "draw_episodes", "episode_specs", "example",
           "gaussian_nll", "generate_logs", "map_density", "train_localizer"]

_MAP_NAME = re.compile(r"d(?P<density>[0-9.]+)_f(?P<field>[0-9]+)_s[0-9]+$")
#: Candidate band widths [standard deviations], chosen on validation.
BAND_WIDTHS = (0.5, 1.0, 2.0)
_DOIS = (0.0, 0.05, 0.1, 0.15, 0.2)
_SPEC_SEED = 7000  # episode draws: validation seed + 1, training seed + 2


@dataclass(frozen=True)
class EpisodeSpec:
    """One simulated episode: a shipped map, node count, radio irregularity and seed."""

    map_name: str
    n_nodes: int
    doi: float
    seed: int

    @property
    def file_name(self) -> str:
        stem = self.map_name.replace("/", "_")
        return f"{stem}_n{self.n_nodes}_doi{self.doi:.2f}_seed{self.seed}.npz"


def map_density(name: str) -> tuple[float, float]:
    """Obstacle density and field size [m] encoded in a shipped map name (``d0.20_f100_s005``)."""
    match = _MAP_NAME.search(name)
    if match is None:
        raise ValueError(f"map name {name!r} does not look like d<density>_f<field>_s<seed>")
    return float(match["density"]), float(match["field"])


def spec_config(spec: EpisodeSpec) -> AOASSConfig:
    """The config of the episode of ``spec`` (today's defaults for everything it does not
    name)."""
    density, field = map_density(spec.map_name)
    return AOASSConfig(field_size=field, n_nodes=spec.n_nodes, obstacle_density=density,
                       map=spec.map_name, doi=spec.doi)


def simulate(spec: EpisodeSpec) -> tuple[BeaconLog, np.ndarray]:
    """Run one square-spiral episode of ``spec``: its beacon log and the anchor's DOI pattern
    K (360,)."""
    config = spec_config(spec)
    sim = Simulator(config, np.random.default_rng(spec.seed),
                    obstacle_map=load_map(spec.map_name), seed=spec.seed)
    return sim.run(), np.array(sim.radio.anchor_pattern)


def episode_specs(n_episodes: int, maps: Sequence[str], seed: int) -> list[EpisodeSpec]:
    """``n_episodes`` episodes drawn over ``maps``: 92 % on 100 m fields with 100-500 nodes,
    8 % on 200 m fields with 500 or 1000 nodes; DOI uniform over {0, 0.05, 0.1, 0.15, 0.2}."""
    rng = np.random.default_rng(seed)
    by_field = {f: [n for n in maps if map_density(n)[1] == f] for f in (100.0, 200.0)}
    specs = []
    for _ in range(n_episodes):
        big = rng.random() < 0.08
        names = by_field[200.0] if big else by_field[100.0]
        name = names[rng.integers(len(names))]
        n_nodes = int(rng.choice((500, 1000) if big else (100, 200, 300, 500)))
        doi = float(rng.choice(_DOIS))
        specs.append(EpisodeSpec(name, n_nodes, doi, int(rng.integers(2**31))))
    return specs


def pattern_path(log_path: Path) -> Path:
    """Where the anchor pattern of the log at ``log_path`` is stored."""
    return log_path.with_name(log_path.stem + "_K.npy")


def _changed_settings(path: Path, spec: EpisodeSpec) -> str:
    """How the config recorded in the cached log at ``path`` differs from the one ``spec``'s
    episode runs now ("" when it does not); :class:`CachedLogError` naming the file when its
    record cannot be read."""
    try:
        with np.load(path, allow_pickle=False) as data:
            recorded = json.loads(str(data["config_json"]))["config"]
        if not isinstance(recorded, dict):
            raise TypeError(f"its config is a {type(recorded).__name__}, not an object")
    except Exception as exc:  # noqa: BLE001 -- any failure to read the file's record
        raise CachedLogError(f"{path}: no readable config_json ({one_line(exc)}); "
                             f"delete it and its pair to simulate them again") from None
    now = json.loads(episode_config_json(spec_config(spec), seed=spec.seed,
                                         method="spiral"))["config"]
    differ = first_difference(recorded, now)
    if differ is None:
        return ""
    key, was, this, others = differ
    return f"{key} {was}, now {this}{f' and {len(others)} more' if others else ''}"


def generate_logs(specs: Sequence[EpisodeSpec], folder: str | Path,
                  report: Callable[[str], None] = print) -> list[Path]:
    """Simulate the episodes of ``specs`` into ``folder``, each log with its anchor pattern.
    A log already there is reused when its recorded config is the one its episode runs now;
    one simulated with other settings (a config default changed since) is simulated again,
    and the report says so. (Changes of the code that leave the config alone are not
    detected: delete the folder after such a change.)"""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for i, spec in enumerate(specs):
        path = folder / spec.file_name
        cached = path.is_file() and pattern_path(path).is_file()
        changed = _changed_settings(path, spec) if cached else ""
        if changed:
            report(f"  log {i + 1}/{len(specs)} {path.name}: simulated with other settings "
                   f"({changed}); simulating it again")
        if not cached or changed:
            start = time.perf_counter()
            log, pattern = simulate(spec)
            with atomic_open(pattern_path(path), "wb") as f:
                np.save(f, pattern)
            log.save(path)
            report(f"  log {i + 1}/{len(specs)} {path.name} ({time.perf_counter() - start:.1f} s)")
        paths.append(path)
    return paths


@dataclass(frozen=True)
class Example:
    """One log's pair record (from its reliable first-pass nodes) and target z_K (360,)."""

    record: PairRecord
    target: np.ndarray


def example(episode: Episode, pattern: np.ndarray) -> Example:
    """The training example of an episode with DOI > 0 and its true anchor pattern (360,)."""
    nodes = np.flatnonzero(episode.covered)
    first = node_consensus(episode, nodes)
    reliable = first.spread <= RELIABLE_SPREAD
    record = pair_statistics(episode, nodes[reliable], first.estimate[reliable])
    doi = episode.config.doi
    return Example(record, np.clip((pattern - 1) / doi, -1, 1).astype(np.float32))


def augment(ex: Example, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Features (360, F) and target (360,) of ``ex`` with a random 50-100 % share of its nodes,
    rotated by a random whole number of degrees."""
    nodes = np.unique(ex.record.node)
    share = nodes[rng.random(len(nodes)) < rng.uniform(0.5, 1.0)]
    x = pair_histograms(ex.record, np.isin(ex.record.node, share))
    shift = rng.integers(360)
    return np.roll(x, shift, 0), np.roll(ex.target, shift)


def gaussian_nll(mean: torch.Tensor, logstd: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Mean Gaussian negative log-likelihood (up to a constant)."""
    return (logstd + 0.5 * ((target - mean) / torch.exp(logstd)) ** 2).mean()


#: Valid ranges of :class:`TrainConfig`'s numbers: (type, low, low open).
TRAIN_RANGES: dict[str, tuple[type, float, bool]] = {
    "n_train_logs": (int, 1, False), "n_val_logs": (int, 1, False), "hidden": (int, 1, False),
    "epochs": (int, 1, False), "batch_size": (int, 1, False),
    "learning_rate": (float, 0, True), "seed": (int, 0, False)}


@dataclass(frozen=True)
class TrainConfig:
    """Settings of :func:`train_localizer` (defaults: the shipped checkpoint); numbers in
    :data:`TRAIN_RANGES`, else ValueError naming the field."""

    data_dir: Path = Path("out/localizer_logs")
    checkpoint: Path = DEFAULT_CHECKPOINT
    n_train_logs: int = 240
    n_val_logs: int = 30
    hidden: int = 32
    epochs: int = 25
    batch_size: int = 8
    learning_rate: float = 3e-3
    seed: int = 0

    def __post_init__(self) -> None:
        for name, (kind, low, low_open) in TRAIN_RANGES.items():
            value = getattr(self, name)
            high = 2**64 - 1 if name == "seed" else None  # torch.manual_seed's largest
            object.__setattr__(self, name, integer(name, value, low=low, high=high)
                               if kind is int else real(name, value, low=low, low_open=low_open))
        for name in ("data_dir", "checkpoint"):
            value = getattr(self, name)
            if not isinstance(value, (str, os.PathLike)):
                raise TypeError(f"{name} must be a path, got {type(value).__name__}")


def draw_episodes(cfg: TrainConfig) -> tuple[list[str], list[str], list[EpisodeSpec],
                                              list[EpisodeSpec]]:
    """The training and validation maps and the episodes drawn on them (validation, training).

    Raises:
        ValueError: the validation or the training draw holds no episode with DOI > 0 (only
            those are examples): nothing to validate or to train on.
    """
    fit_maps, val_maps = validation_split(list_maps("train"))
    val_specs = episode_specs(cfg.n_val_logs, val_maps, _SPEC_SEED + cfg.seed + 1)
    train_specs = episode_specs(cfg.n_train_logs, fit_maps, _SPEC_SEED + cfg.seed + 2)
    for name, specs in (("n_val_logs", val_specs), ("n_train_logs", train_specs)):
        if not any(spec.doi > 0 for spec in specs):
            raise ValueError(f"{name}={len(specs)}: no episode of this draw (seed {cfg.seed}) "
                             f"has DOI > 0, the only ones the OLSTM learns from; draw more")
    return fit_maps, val_maps, val_specs, train_specs


class CachedLogError(ValueError):
    """A log or anchor pattern in the data folder (simulated by an earlier run and reused) cannot
    be read; the message names the file."""


class DivergedError(ValueError):
    """Training gave no epoch with a finite validation loss: nothing to save."""


def _load_cached(path: Path) -> tuple[Episode, np.ndarray | None]:
    """The prepared episode of the log at ``path`` and, with DOI > 0, its anchor pattern (360,);
    :class:`CachedLogError` naming the file otherwise."""
    hint = "delete it and its pair to simulate them again"
    try:
        episode = prepare(BeaconLog.load(path))
    except BeaconLogError as exc:         # prepare()'s errors name no file: named here
        named = exc if exc.path is not None else BeaconLogError(exc.reason, exc.key, path)
        raise CachedLogError(f"{one_line(named)}; {hint}") from None
    if episode.config.doi <= 0:
        return episode, None
    file = pattern_path(path)
    try:
        pattern = np.load(file, allow_pickle=False)
    except (OSError, ValueError, EOFError) as exc:
        raise CachedLogError(f"{file}: not a readable anchor pattern ({one_line(exc)}); "
                             f"{hint}") from None
    if pattern.shape != (360,) or not np.issubdtype(pattern.dtype, np.floating) \
            or not np.isfinite(pattern).all():
        raise CachedLogError(f"{file}: an anchor pattern is 360 finite floats, got "
                             f"{pattern.dtype} of shape {pattern.shape}; {hint}")
    return episode, pattern


def _examples(paths: Sequence[Path]) -> tuple[list[Example], list[Episode]]:
    """Examples of the logs with DOI > 0 among ``paths`` (sorted by name), and those episodes."""
    examples, episodes = [], []
    for path in sorted(paths, key=lambda p: p.name):
        episode, pattern = _load_cached(path)
        if pattern is not None:
            examples.append(example(episode, pattern))
            episodes.append(episode)
    return examples, episodes


def pooled_rmse(model: OLSTM, episodes: Sequence[Episode]) -> float:
    """Pooled OLSTM-DV-Hop localization RMSE [m] over ``episodes``."""
    sq, count = 0.0, 0
    for episode in episodes:
        est = olstm_dvhop(episode, model)
        ok = np.all(np.isfinite(est), axis=1)
        sq += float(np.sum((est[ok] - episode.log.nodes[ok]) ** 2))
        count += int(ok.sum())
    return float(np.sqrt(sq / max(count, 1)))


def train_localizer(cfg: TrainConfig, report: Callable[[str], None] = print) -> dict:
    """Generate logs, train the OLSTM, choose the band width, write the checkpoint; returns its
    metadata."""
    rng = np.random.default_rng(cfg.seed)
    torch.manual_seed(cfg.seed)
    fit_maps, val_maps, val_specs, train_specs = draw_episodes(cfg)
    report(f"simulating {len(train_specs)} training and {len(val_specs)} validation logs "
           f"into {cfg.data_dir}")
    val_paths = generate_logs(val_specs, Path(cfg.data_dir) / "val", report)
    train_paths = generate_logs(train_specs, Path(cfg.data_dir) / "train", report)
    train, _ = _examples(train_paths)
    val, val_episodes = _examples(val_paths)
    report(f"{len(train)} training and {len(val)} validation logs with DOI > 0")
    model = OLSTM(cfg.hidden)
    optim = torch.optim.Adam(model.parameters(), lr=cfg.learning_rate)
    x_val = torch.from_numpy(np.stack([pair_histograms(ex.record) for ex in val]))
    y_val = torch.from_numpy(np.stack([ex.target for ex in val]))
    best, best_state, best_epoch, history = np.inf, None, -1, []
    for epoch in range(cfg.epochs):
        model.train()
        order = rng.permutation(len(train))
        total = 0.0
        for i in range(0, len(order), cfg.batch_size):
            pairs = [augment(train[j], rng) for j in order[i:i + cfg.batch_size]]
            x = torch.from_numpy(np.stack([p[0] for p in pairs]))
            y = torch.from_numpy(np.stack([p[1] for p in pairs]))
            loss = gaussian_nll(*model(x), y)
            optim.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
            optim.step()
            total += float(loss.detach())
        model.eval()
        with torch.no_grad():
            mean, logstd = model(x_val)
            nll = float(gaussian_nll(mean, logstd, y_val))
            mae = float((mean - y_val).abs().mean())
        history.append({"epoch": epoch, "val_nll": nll, "val_mae_z": mae})
        report(f"epoch {epoch:2d}  val NLL {nll:+.3f}  val MAE of z_K {mae:.3f}")
        if nll < best:
            best, best_epoch = nll, epoch
            best_state = {k: v.detach().clone() for k, v in model.state_dict().items()}
    if best_state is None:
        raise DivergedError(f"training diverged: the validation NLL was not finite in any of "
                            f"{cfg.epochs} epoch(s) (learning_rate={cfg.learning_rate:g}); "
                            f"nothing was written")
    model.load_state_dict(best_state)
    widths = {}
    for width in BAND_WIDTHS:
        model.band_width = width
        widths[width] = pooled_rmse(model, val_episodes)
        report(f"band width {width}: validation RMSE {widths[width]:.3f} m")
    model.band_width = min(widths, key=widths.get)
    settings = {k: str(v) if isinstance(v, Path) else v
                for k, v in dataclasses.asdict(cfg).items() if k != "checkpoint"}
    meta = {"config": settings, "best_epoch": best_epoch, "val_nll": best, "history": history,
            "band_width_val_rmse": {str(k): v for k, v in widths.items()},
            "zero_predictor_val_mae_z": float(y_val.abs().mean()),
            "train_maps": fit_maps, "val_maps": val_maps}
    save_checkpoint(model.eval(), cfg.checkpoint, meta)
    report(f"wrote {cfg.checkpoint} (best epoch {best_epoch}, band width {model.band_width})")
    return meta
