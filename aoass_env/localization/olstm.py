"""OLSTM-DV-Hop: a learned reception model (Eq. 12) inside the visibility consensus.

With radio irregularity (DOI > 0) the anchor's range is R K(theta), one closed random walk over
the directions shared by all beacons (:mod:`aoass_env.radio`). The visibility consensus alone
only knows the bound: hearing is certain within R (1 - DOI), possible within R (1 + DOI). The
OLSTM reads the log's record of heard and unheard (beacon, node) pairs near the range circle,
placed by a first consensus pass (:mod:`~aoass_env.localization.reception`), as a circular
sequence over the 360 degrees (a bidirectional LSTM) and predicts per degree a Gaussian over the
range factor. Its band, mean -/+ ``band_width`` standard deviations, replaces the DOI bound in a
second consensus pass: a heard beacon outside it, or an unheard one in sight inside its certain
part, is a violation. With DOI 0 the unit disk is exact and OLSTM-DV-Hop is the consensus.

Checkpoints are plain dictionaries (weights as tensors, metadata as lists, numbers and strings)
saved with :func:`torch.save` and read with ``torch.load(..., weights_only=True)``; their format,
schema version and feature list must match this code.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from aoass_env.atomic import atomic_open
from aoass_env.data import shipped_dir
from aoass_env.localization.consensus import RELIABLE_SPREAD, Consensus, node_consensus
from aoass_env.localization.episode import Episode
from aoass_env.localization.reception import (
    FEATURE_NAMES,
    FEATURE_VERSION,
    N_FEATURES,
    pair_histograms,
    pair_statistics,
    range_band,
)
from aoass_env.validators import one_line, torch_load_problem

__all__ = ["CHECKPOINT_FORMAT", "CHECKPOINT_VERSION", "DEFAULT_CHECKPOINT", "CheckpointError",
           "OLSTM", "load_checkpoint", "olstm_dvhop", "predict_pattern", "save_checkpoint"]

CHECKPOINT_FORMAT = "aoass-olstm-dvhop"
CHECKPOINT_VERSION = 2
#: The shipped, trained localizer (the checkout's, or the installed wheel's copy).
DEFAULT_CHECKPOINT = shipped_dir("checkpoints") / "olstm_dvhop.pt"
#: Wrap-around padding of the circular sequence on each side [degrees].
PAD = 32
_LOGSTD_MIN, _LOGSTD_MAX = -6.0, 2.0


class CheckpointError(ValueError):
    """A localizer checkpoint is missing, unreadable or does not match this code."""


class OLSTM(nn.Module):
    """Bidirectional LSTM over the 360 degrees of an episode's reception record; per degree the
    mean (in [-1, 1]) and log standard deviation of z_K = (K - 1) / DOI.

    Args:
        hidden: LSTM hidden size per direction.
        band_width: standard deviations on each side of the mean that make the range band
            (chosen on validation; stored in the checkpoint).
    """

    def __init__(self, hidden: int = 32, band_width: float = 1.0) -> None:
        super().__init__()
        self.hidden = hidden
        self.band_width = float(band_width)
        self.embed = nn.Sequential(nn.Linear(N_FEATURES, hidden), nn.ReLU())
        self.lstm = nn.LSTM(hidden, hidden, batch_first=True, bidirectional=True)
        self.head = nn.Sequential(nn.Linear(3 * hidden, hidden), nn.ReLU(), nn.Linear(hidden, 2))

    def forward(self, features: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Features (S, 360, N_FEATURES) -> mean z_K (S, 360), log std (S, 360)."""
        wrapped = torch.cat([features[:, -PAD:], features, features[:, :PAD]], dim=1)
        e = self.embed(wrapped)
        out = self.head(torch.cat([self.lstm(e)[0], e], dim=-1))[:, PAD:-PAD]
        return torch.tanh(out[..., 0]), out[..., 1].clamp(_LOGSTD_MIN, _LOGSTD_MAX)


def save_checkpoint(model: OLSTM, path: str | os.PathLike[str],
                    training: dict[str, Any]) -> None:
    """Write ``model`` and its metadata to ``path`` atomically (``training``: JSON-like info)."""
    payload = {"format": CHECKPOINT_FORMAT, "version": CHECKPOINT_VERSION,
               "feature_names": list(FEATURE_NAMES), "feature_version": FEATURE_VERSION,
               "hidden": model.hidden, "band_width": model.band_width,
               "state_dict": model.state_dict(), "training": training}
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    with atomic_open(path, "wb") as f:
        torch.save(payload, f)


def load_checkpoint(path: str | os.PathLike[str] = DEFAULT_CHECKPOINT) -> OLSTM:
    """The model stored at ``path`` (read with ``weights_only=True``), in eval mode.

    Raises:
        CheckpointError: no file, not a checkpoint of this format, its schema version or
            feature set differs from this code's, or its settings or weights are invalid
            (NaN or infinite included).
    """
    if not Path(path).is_file():
        raise CheckpointError(f"{path}: no localizer checkpoint there (train one with "
                              f"`python train.py localizer`)")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types for a damaged or foreign file
        raise CheckpointError(f"{path}: not a readable torch checkpoint "
                              f"({torch_load_problem(exc)})") from None
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
    width = payload.get("band_width")
    if isinstance(width, bool) or not isinstance(width, (int, float)) \
            or not (math.isfinite(width) and width >= 0):
        raise CheckpointError(f"{path}: band_width must be a finite number >= 0, got {width!r}")
    state = payload.get("state_dict")
    if not isinstance(state, dict):
        raise CheckpointError(f"{path}: state_dict must be a dict of weight tensors, got "
                              f"{type(state).__name__}")
    embed = state.get("embed.0.weight")
    got = tuple(embed.shape) if isinstance(embed, torch.Tensor) else \
        "nothing" if embed is None else type(embed).__name__
    if got != (hidden, N_FEATURES):  # before the model is built: a huge hidden allocates
        raise CheckpointError(f"{path}: state_dict: embed.0.weight must be a tensor of shape "
                              f"(hidden={hidden}, {N_FEATURES}), got {got}")
    for name, tensor in state.items():   # load_state_dict casts ints, bools and complex
        if isinstance(tensor, torch.Tensor) and not tensor.is_floating_point():
            raise CheckpointError(f"{path}: state_dict: {name} must hold floating-point "
                                  f"weights, got {tensor.dtype}")
    model = OLSTM(hidden, width)
    try:
        model.load_state_dict(state)
    except (KeyError, RuntimeError, TypeError, AttributeError) as exc:
        raise CheckpointError(f"{path}: weights do not fit the model "
                              f"({one_line(exc)})") from None
    for name, tensor in model.state_dict().items():
        if not bool(torch.isfinite(tensor).all()):
            raise CheckpointError(f"{path}: state_dict: {name} holds NaN or infinite weights")
    return model.eval()


def predict_pattern(model: OLSTM, features: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean z_K and its standard deviation (360,) from one episode's features (360, F)."""
    with torch.inference_mode():
        mean, logstd = model(torch.from_numpy(features[None]))
    return mean[0].numpy().astype(np.float64), np.exp(logstd[0].numpy().astype(np.float64))


def olstm_dvhop(episode: Episode, model: OLSTM, first: Consensus | None = None) -> np.ndarray:
    """OLSTM-DV-Hop estimates (N, 2) [m]; NaN for nodes not covered under Eq. 18.

    DOI 0: the visibility consensus. DOI > 0: a first consensus pass places the nodes; the pairs
    of the reliable ones (spread <= ``RELIABLE_SPREAD``) give the OLSTM its per-degree record; the
    predicted range band replaces the DOI bound in a second, final consensus pass. ``first``:
    that first pass (:func:`node_consensus` of the covered nodes) when the caller has it.
    """
    out = np.full((episode.log.n_nodes, 2), np.nan)
    nodes = np.flatnonzero(episode.covered)
    if len(nodes) == 0:
        return out
    if first is None:
        first = node_consensus(episode, nodes)
    elif not np.array_equal(first.nodes, nodes):
        raise ValueError("first must be the consensus of exactly the covered nodes")
    doi = episode.config.doi
    if doi == 0:
        out[nodes] = first.estimate
        return out
    reliable = first.spread <= RELIABLE_SPREAD
    record = pair_statistics(episode, nodes[reliable], first.estimate[reliable])
    mean, std = predict_pattern(model, pair_histograms(record))
    band = range_band(mean, std, doi, model.band_width)
    out[nodes] = node_consensus(episode, nodes, band=band).estimate
    return out
