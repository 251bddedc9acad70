"""Training pipeline of the OLSTM localizer: beacon logs, examples, training, checkpoint.

1. **Logs.** :func:`episode_specs` draws episodes on the shipped *training* maps only
   (``maps/train``): both field sizes, every density, several node counts, with and without
   radio irregularity, square-spiral trajectories. A fixed set of validation maps (the last map
   of each density and field size) is held out from training. :func:`generate_logs` simulates
   them and caches the ``.npz`` logs, so a rerun only simulates what is missing.
2. **Examples.** Per log, up to ``nodes_per_log`` covered nodes are drawn; each gives two
   sequences, one around its visibility-consensus estimate (the reference at inference) and one
   around its true position displaced by Gaussian noise of a random scale (so that the model
   learns to correct a reference in any direction). The target of each step is the true
   node-beacon distance / R.
3. **Training.** Gaussian negative log-likelihood of the target under (d_hat, log variance),
   Adam, a fixed seed, one thread. After every epoch the full OLSTM-DV-Hop localization runs on
   the validation logs; the weights with the lowest validation RMSE are kept and training stops
   after ``patience`` epochs without improvement.
"""

from __future__ import annotations

import dataclasses
import re
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from aoass_env.beacon_log import BeaconLog
from aoass_env.config import AOASSConfig
from aoass_env.localization.consensus import node_consensus
from aoass_env.localization.episode import Episode, prepare
from aoass_env.localization.features import FEATURE_NAMES, build_sequences
from aoass_env.localization.olstm import DEFAULT_CHECKPOINT, OLSTM, olstm_dvhop, save_checkpoint
from aoass_env.maps import list_maps, load_map
from aoass_env.metrics import localization_rmse
from aoass_env.simulator import Simulator

__all__ = ["EpisodeSpec", "TrainConfig", "episode_specs", "generate_logs", "map_density",
           "node_examples", "pad_batch", "train_localizer", "validation_maps"]

_MAP_NAME = re.compile(r"d(?P<density>[0-9.]+)_f(?P<field>[0-9]+)_s[0-9]+$")


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


def simulate(spec: EpisodeSpec) -> BeaconLog:
    """Run one square-spiral episode of ``spec`` and return its beacon log."""
    density, field = map_density(spec.map_name)
    config = AOASSConfig(field_size=field, n_nodes=spec.n_nodes, obstacle_density=density,
                         map=spec.map_name, doi=spec.doi)
    return Simulator(config, np.random.default_rng(spec.seed), obstacle_map=load_map(
        spec.map_name), seed=spec.seed).run()


def validation_maps(names: Sequence[str]) -> list[str]:
    """The held-out maps among ``names``: the last (by name) of each density and field size."""
    last: dict[tuple[float, float], str] = {}
    for name in sorted(names):
        last[map_density(name)] = name
    return sorted(last.values())


def episode_specs(n_episodes: int, maps: Sequence[str], seed: int) -> list[EpisodeSpec]:
    """``n_episodes`` episodes drawn over ``maps``: 85 % on 100 m fields with 100-500 nodes,
    15 % on 200 m fields with 500 or 1000 nodes (they cost several times as much to simulate);
    DOI 0 in half the episodes, else 0.05, 0.1 or 0.15."""
    rng = np.random.default_rng(seed)
    by_field = {f: [n for n in maps if map_density(n)[1] == f] for f in (100.0, 200.0)}
    specs = []
    for i in range(n_episodes):
        field = 200.0 if by_field[200.0] and (not by_field[100.0] or rng.random() < 0.15) \
            else 100.0
        name = by_field[field][i % len(by_field[field])]
        n_nodes = rng.choice((100, 200, 300, 500) if field == 100.0 else (500, 1000))
        doi = float(rng.choice([0.0, 0.0, 0.0, 0.05, 0.1, 0.15]))
        specs.append(EpisodeSpec(name, int(n_nodes), doi, int(rng.integers(2**31))))
    return specs


def generate_logs(specs: Sequence[EpisodeSpec], folder: str | Path,
                  report: Callable[[str], None] = print) -> list[Path]:
    """Simulate the episodes of ``specs`` into ``folder`` (existing logs are reused)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for i, spec in enumerate(specs):
        path = folder / spec.file_name
        if not path.is_file():
            start = time.perf_counter()
            simulate(spec).save(path)
            report(f"  log {i + 1}/{len(specs)} {path.name} ({time.perf_counter() - start:.1f} s)")
        paths.append(path)
    return paths


def node_examples(episode: Episode, rng: np.random.Generator, nodes_per_log: int,
                  max_noise: float) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Training sequences of one episode: per-sequence feature arrays (L, F) and targets (L,).

    Up to ``nodes_per_log`` covered nodes, each around its consensus estimate and around its true
    position plus isotropic Gaussian noise of standard deviation U(0, ``max_noise``) [m]; both
    carry the node's consensus spread.
    """
    covered = np.flatnonzero(episode.covered)
    nodes = np.sort(rng.permutation(covered)[:nodes_per_log])
    true = episode.log.nodes[nodes]
    noisy = true + rng.normal(size=true.shape) * rng.uniform(0, max_noise, (len(nodes), 1))
    w, h = episode.field
    noisy = np.clip(noisy, 0.0, [w, h])
    ref = node_consensus(episode, nodes)
    features, targets = [], []
    for refs in (ref.estimate, noisy):
        seq = build_sequences(episode, nodes, refs, ref.spread)
        xy = episode.beacon_xy[np.maximum(seq.beacons, 0)]
        dist = np.hypot(*(xy - true[:, None, :]).transpose(2, 0, 1)) / episode.log.radio_range
        for s, n in enumerate(seq.lengths):
            features.append(seq.features[s, :n])
            targets.append(dist[s, :n].astype(np.float32))
    return features, targets


@dataclass(frozen=True)
class TrainConfig:
    """Settings of :func:`train_localizer` (defaults: the shipped checkpoint)."""

    data_dir: Path = Path("out/localizer_logs")
    checkpoint: Path = DEFAULT_CHECKPOINT
    n_train_logs: int = 120
    n_val_logs: int = 16
    nodes_per_log: int = 80
    max_noise: float = 4.0
    hidden: int = 32
    epochs: int = 30
    patience: int = 5
    batch_size: int = 64
    learning_rate: float = 3e-3
    seed: int = 0


def _batches(n: int, batch_size: int, rng: np.random.Generator) -> list[np.ndarray]:
    order = rng.permutation(n)
    return [order[i:i + batch_size] for i in range(0, n, batch_size)]


def pad_batch(arrays: list[np.ndarray], idx: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
    """Arrays ``idx`` of ``arrays`` (each (L_i, ...)) zero-padded to (len(idx), max L_i, ...),
    and their lengths."""
    lengths = np.array([len(arrays[i]) for i in idx])
    out = np.zeros((len(idx), lengths.max(), *arrays[idx[0]].shape[1:]), dtype=np.float32)
    for row, i in enumerate(idx):
        out[row, :lengths[row]] = arrays[i]
    return torch.from_numpy(out), torch.from_numpy(lengths)


def gaussian_nll(d_hat: torch.Tensor, logvar: torch.Tensor, target: torch.Tensor,
                 mask: torch.Tensor) -> torch.Tensor:
    """Mean Gaussian negative log-likelihood (up to a constant) over the masked steps."""
    nll = 0.5 * (logvar + (target - d_hat) ** 2 * torch.exp(-logvar))
    return (nll * mask).sum() / mask.sum()


def validation_rmse(model: OLSTM, episodes: Sequence[Episode]) -> float:
    """Pooled localization RMSE [m] of OLSTM-DV-Hop over ``episodes``."""
    model.eval()
    sq, count = 0.0, 0
    for ep in episodes:
        est = olstm_dvhop(ep, model)
        rmse, frac = localization_rmse(ep.log.nodes, est)
        k = round(frac * ep.log.n_nodes)
        sq, count = sq + rmse ** 2 * k, count + k
    return float(np.sqrt(sq / max(count, 1)))


def train_localizer(cfg: TrainConfig, report: Callable[[str], None] = print) -> dict:
    """Generate logs, train the OLSTM, write the best checkpoint; returns its metadata."""
    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    names = list_maps("train")
    val_names = validation_maps(names)
    train_names = [n for n in names if n not in val_names]
    train_specs = episode_specs(cfg.n_train_logs, train_names, cfg.seed)
    val_specs = episode_specs(cfg.n_val_logs, val_names, cfg.seed + 1)
    report(f"simulating {len(train_specs)} training and {len(val_specs)} validation logs "
           f"into {cfg.data_dir}")
    train_paths = generate_logs(train_specs, cfg.data_dir, report)
    val_paths = generate_logs(val_specs, cfg.data_dir, report)
    features: list[np.ndarray] = []
    targets: list[np.ndarray] = []
    for path in train_paths:
        f, t = node_examples(prepare(BeaconLog.load(path)), rng, cfg.nodes_per_log,
                             cfg.max_noise)
        features += f
        targets += t
    val_episodes = [prepare(BeaconLog.load(p)) for p in val_paths]
    flat = np.concatenate(features)
    mean = torch.from_numpy(flat.mean(axis=0))
    std = torch.from_numpy(np.maximum(flat.std(axis=0), 1e-3))
    report(f"{len(features)} training sequences, {len(flat)} steps")
    model = OLSTM(len(FEATURE_NAMES), cfg.hidden, mean, std)
    optim = torch.optim.Adam(model.parameters(), lr=cfg.learning_rate)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(optim, cfg.epochs)
    best, best_state, best_epoch, history = np.inf, None, -1, []
    for epoch in range(cfg.epochs):
        start = time.perf_counter()
        model.train()
        total = 0.0
        batches = _batches(len(features), cfg.batch_size, rng)
        for idx in batches:
            x, lengths = pad_batch(features, idx)
            y, _ = pad_batch(targets, idx)
            mask = (torch.arange(x.shape[1])[None, :] < lengths[:, None]).float()
            d_hat, logvar = model(x, lengths)
            loss = gaussian_nll(d_hat, logvar, y, mask)
            optim.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
            optim.step()
            total += float(loss.detach())
        sched.step()
        rmse = validation_rmse(model, val_episodes)
        history.append({"epoch": epoch, "loss": total / len(batches), "val_rmse": rmse})
        report(f"epoch {epoch:2d}  loss {total / len(batches):+.4f}  val RMSE {rmse:.3f} m  "
               f"({time.perf_counter() - start:.0f} s)")
        if rmse < best:
            best, best_epoch = rmse, epoch
            best_state = {k: v.detach().clone() for k, v in model.state_dict().items()}
        elif epoch - best_epoch >= cfg.patience:
            report(f"early stop: no improvement for {cfg.patience} epochs")
            break
    model.load_state_dict(best_state)
    settings = {k: str(v) if isinstance(v, Path) else v
                for k, v in dataclasses.asdict(cfg).items() if k != "checkpoint"}
    meta = {"config": settings,
            "best_epoch": best_epoch, "val_rmse": best, "history": history,
            "train_maps": train_names, "val_maps": val_names}
    save_checkpoint(model, cfg.checkpoint, meta)
    report(f"wrote {cfg.checkpoint} (best epoch {best_epoch}, val RMSE {best:.3f} m)")
    return meta
