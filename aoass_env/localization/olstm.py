"""OLSTM-DV-Hop (Eq. 12 then Eq. 13): an LSTM predicts each node's distance to its beacons.

For every covered node the model reads the node's beacon sequence (:mod:`~aoass_env.
localization.features`) in time order with a bidirectional LSTM and predicts, per beacon, the
distance ``d_hat`` as the distance from the reference point plus a learned correction, and the
log-variance of that prediction. The reference point of the sequences and the start of Eq. 13
(weights ``1 / variance``, :func:`~aoass_env.localization.multilateration.multilaterate`) is the
node's visibility-consensus estimate (:mod:`~aoass_env.localization.consensus`).

Checkpoints are plain dictionaries (weights as tensors, metadata as lists, numbers and strings)
saved with :func:`torch.save` and read with ``torch.load(..., weights_only=True)``; their format,
schema version and feature list must match this code.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from aoass_env.atomic import atomic_open
from aoass_env.localization.consensus import RELIABLE_SPREAD, node_consensus
from aoass_env.localization.episode import Episode
from aoass_env.localization.features import FEATURE_NAMES, FEATURE_VERSION, build_sequences
from aoass_env.localization.multilateration import multilaterate

__all__ = ["CHECKPOINT_FORMAT", "CHECKPOINT_VERSION", "DEFAULT_CHECKPOINT", "CheckpointError",
           "OLSTM", "load_checkpoint", "olstm_dvhop", "predict", "save_checkpoint"]

CHECKPOINT_FORMAT = "aoass-olstm-dvhop"
CHECKPOINT_VERSION = 1
#: The shipped, trained localizer.
DEFAULT_CHECKPOINT = Path(__file__).resolve().parents[2] / "checkpoints" / "olstm_dvhop.pt"
_RANGE = FEATURE_NAMES.index("range")
_LOGVAR_MIN, _LOGVAR_MAX = -12.0, 4.0
_BATCH = 256  # sequences per forward call at inference


class CheckpointError(ValueError):
    """A localizer checkpoint is missing, unreadable or does not match this code."""


class OLSTM(nn.Module):
    """Bidirectional LSTM over a node's beacon sequence; per step (d_hat / R, log variance).

    The two directions are separate one-layer LSTMs over padded batches; the backward one reads
    each sequence reversed within its length.

    Args:
        n_features: features per step (``len(FEATURE_NAMES)``).
        hidden: LSTM hidden size per direction.
        mean, std: (F,) feature normalisation, stored as buffers (part of the checkpoint).
    """

    def __init__(self, n_features: int = len(FEATURE_NAMES), hidden: int = 48,
                 mean: torch.Tensor | None = None, std: torch.Tensor | None = None) -> None:
        super().__init__()
        self.hidden = hidden
        self.register_buffer("mean", torch.zeros(n_features) if mean is None else mean.float())
        self.register_buffer("std", torch.ones(n_features) if std is None else std.float())
        self.embed = nn.Sequential(nn.Linear(n_features, hidden), nn.ReLU())
        self.forward_lstm = nn.LSTM(hidden, hidden, batch_first=True)
        self.backward_lstm = nn.LSTM(hidden, hidden, batch_first=True)
        self.head = nn.Sequential(nn.Linear(3 * hidden, hidden), nn.ReLU(), nn.Linear(hidden, 2))

    def forward(self, features: torch.Tensor,
                lengths: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Features (S, L, F) raw, lengths (S,) -> d_hat / R (S, L), log variance (S, L)."""
        e = self.embed((features - self.mean) / self.std)
        # The backward direction reads each sequence reversed within its own length, so the
        # padding after the end is never read before a real step (no packing needed).
        steps = torch.arange(features.shape[1], device=features.device)
        rev = torch.where(steps < lengths[:, None], lengths[:, None] - 1 - steps, steps)
        rev = rev[..., None].expand(-1, -1, e.shape[-1])
        h_fwd = self.forward_lstm(e)[0]
        h_bwd = self.backward_lstm(e.gather(1, rev))[0].gather(1, rev)
        out = self.head(torch.cat([h_fwd, h_bwd, e], dim=-1))
        d_hat = features[..., _RANGE] + out[..., 0]
        return d_hat, out[..., 1].clamp(_LOGVAR_MIN, _LOGVAR_MAX)


def save_checkpoint(model: OLSTM, path: str | os.PathLike[str],
                    training: dict[str, Any]) -> None:
    """Write ``model`` and its metadata to ``path`` atomically (``training``: JSON-like info)."""
    payload = {"format": CHECKPOINT_FORMAT, "version": CHECKPOINT_VERSION,
               "feature_names": list(FEATURE_NAMES), "feature_version": FEATURE_VERSION,
               "hidden": model.hidden, "state_dict": model.state_dict(), "training": training}
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    with atomic_open(path, "wb") as f:
        torch.save(payload, f)


def load_checkpoint(path: str | os.PathLike[str] = DEFAULT_CHECKPOINT) -> OLSTM:
    """The model stored at ``path`` (read with ``weights_only=True``), in eval mode.

    Raises:
        CheckpointError: no file, not a checkpoint of this format, or its schema version or
            feature set differs from this code's.
    """
    if not Path(path).is_file():
        raise CheckpointError(f"{path}: no localizer checkpoint there (train one with "
                              f"`python train.py localizer`)")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types for a damaged or foreign file
        raise CheckpointError(f"{path}: not a readable torch checkpoint ({exc})") from None
    if not isinstance(payload, dict) or payload.get("format") != CHECKPOINT_FORMAT:
        raise CheckpointError(f"{path}: not an {CHECKPOINT_FORMAT} checkpoint")
    if payload.get("version") != CHECKPOINT_VERSION:
        raise CheckpointError(f"{path}: checkpoint version {payload.get('version')!r}, this "
                              f"code reads version {CHECKPOINT_VERSION}")
    names = payload.get("feature_names")
    if names != list(FEATURE_NAMES) or payload.get("feature_version") != FEATURE_VERSION:
        raise CheckpointError(f"{path}: feature set {names} (version "
                              f"{payload.get('feature_version')!r}) does not match this code's "
                              f"{list(FEATURE_NAMES)} (version {FEATURE_VERSION}); retrain")
    hidden = payload.get("hidden")
    if isinstance(hidden, bool) or not isinstance(hidden, int) or hidden < 1:
        raise CheckpointError(f"{path}: hidden must be an integer >= 1, got {hidden!r}")
    model = OLSTM(len(FEATURE_NAMES), hidden)
    try:
        model.load_state_dict(payload["state_dict"])
    except (KeyError, RuntimeError, TypeError, AttributeError) as exc:
        raise CheckpointError(f"{path}: weights do not fit the model ({exc})") from None
    for name, tensor in model.state_dict().items():
        if not bool(torch.isfinite(tensor).all()):
            raise CheckpointError(f"{path}: state_dict: {name} holds NaN or infinite weights")
    return model.eval()


def predict(model: OLSTM, features: np.ndarray,
            lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Predicted d_hat / R and log variance (S, L) for padded sequences, deterministically."""
    d_hat = np.zeros(features.shape[:2], dtype=np.float32)
    logvar = np.zeros_like(d_hat)
    order = np.argsort(-lengths, kind="stable")
    with torch.inference_mode():
        for start in range(0, len(order), _BATCH):
            idx = order[start:start + _BATCH]
            width = int(lengths[idx].max())
            d, v = model(torch.from_numpy(np.ascontiguousarray(features[idx, :width])),
                         torch.from_numpy(lengths[idx]))
            d_hat[idx, :width], logvar[idx, :width] = d.numpy(), v.numpy()
    return d_hat, logvar


def olstm_dvhop(episode: Episode, model: OLSTM) -> np.ndarray:
    """OLSTM-DV-Hop estimates (N, 2) [m]; NaN for nodes not covered under Eq. 18.

    Every covered node starts from its visibility-consensus estimate; the nodes whose consensus
    region is wide (spread above ``RELIABLE_SPREAD``) then get the OLSTM distances (Eq. 12) and
    Eq. 13 from there.
    """
    out = np.full((episode.log.n_nodes, 2), np.nan)
    nodes = np.flatnonzero(episode.covered)
    if len(nodes) == 0:
        return out
    ref = node_consensus(episode, nodes)
    out[nodes] = ref.estimate
    wide = ~(ref.spread <= RELIABLE_SPREAD)  # NaN spread: no consensus cell, wide too
    if not wide.any():
        return out
    seq = build_sequences(episode, nodes[wide], ref.estimate[wide], ref.spread[wide])
    d_hat, logvar = predict(model, seq.features, seq.lengths)
    mask = seq.mask
    weights = np.where(mask, np.exp(-logvar.astype(np.float64)), 0.0)
    out[nodes[wide]] = multilaterate(episode.beacon_xy[np.maximum(seq.beacons, 0)],
                                     np.where(mask, d_hat * episode.log.radio_range, 0.0),
                                     weights, ref.estimate[wide], episode.field)
    return out
