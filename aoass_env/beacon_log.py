"""The record of one episode: nodes, obstacles, beacons and who heard them (docs/design.md).

:class:`BeaconLogRecorder` collects the record while an episode runs; :meth:`~BeaconLogRecorder.
finish` returns the immutable :class:`BeaconLog`, which saves to and loads from an ``.npz`` file
with exactly these keys (extra keys are allowed and preserved):

==================  ===============  ====================================================
key                 shape, dtype     meaning
==================  ===============  ====================================================
version             (), int          schema version (1)
config_json         (), str          full config, seed and method name as a JSON object
field               (2,), float      field width, height [m], each in (0, MAX_FIELD]
obstacle_vertices   (V, 2), float    all polygon vertices, concatenated [m]
obstacle_offsets    (P+1,), int      polygon p is ``obstacle_vertices[off[p]:off[p+1]]``
nodes               (N, 2), float    true node positions [m]
beacons             (B, 3), float    t [s], x, y [m] of each broadcast, in time order
receptions          (K, 2), int      (beacon index, node index) of every direct reception
node_links          (E, 2), int      node pairs i < j that hear each other
anchor_path         (T, 3), float    t [s], x, y [m] of the anchor at every step
node_energy         (N,), float      energy spent by each node [J]
anchor_energy       (), float        anchor energy spent, motion + transmissions [J]
radio_range         (), float        R [m]
collisions          (), int          anchor contacts with obstacles
==================  ===============  ====================================================

Every key is validated (presence, shape, dtype kind, finiteness, index ranges, time order) on
construction and on :meth:`BeaconLog.load`; a problem raises :class:`BeaconLogError` naming the
key. Files are written atomically.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from aoass_env.atomic import atomic_open
from aoass_env.config import AOASSConfig
from aoass_env.maps import MapError, ObstacleMap
from aoass_env.validators import one_line, parse_json

__all__ = ["KEYS", "SCHEMA_VERSION", "SUPPORTED_VERSIONS", "BeaconLog", "BeaconLogError",
           "BeaconLogRecorder", "episode_config_json"]

SCHEMA_VERSION = 1
SUPPORTED_VERSIONS = (1,)

# key -> (kind, shape); shape symbols bind on first use and must agree afterwards.
_SCHEMA: dict[str, tuple[str, tuple[int | str, ...]]] = {
    "version": ("int", ()),
    "config_json": ("str", ()),
    "field": ("float", (2,)),
    "obstacle_vertices": ("float", ("V", 2)),
    "obstacle_offsets": ("int", ("P+1",)),
    "nodes": ("float", ("N", 2)),
    "beacons": ("float", ("B", 3)),
    "receptions": ("int", ("K", 2)),
    "node_links": ("int", ("E", 2)),
    "anchor_path": ("float", ("T", 3)),
    "node_energy": ("float", ("N",)),
    "anchor_energy": ("float", ()),
    "radio_range": ("float", ()),
    "collisions": ("int", ()),
}
#: The schema keys, in file order.
KEYS = tuple(_SCHEMA)
#: Names ``np.savez`` takes as its own arguments: an extra array cannot be saved under them.
_SAVEZ_ARGUMENTS = ("file", "allow_pickle")
_KINDS = {"int": ("iu", np.int64, "an integer"), "float": ("fiu", np.float64, "a real number"),
          "str": ("U", np.str_, "a string")}


#: How far (a fraction of the field's width and height) a recorded position may lie outside
#: the field before a log is refused as impossible.
FIELD_TOLERANCE = 0.01
#: The largest field side (m) a log may have: AOASSConfig's bound on ``field_size``, the side of
#: every field an episode is recorded on.
MAX_FIELD = next(f.metadata["high"] for f in dataclasses.fields(AOASSConfig)
                 if f.name == "field_size")


class BeaconLogError(ValueError):
    """A beacon log is malformed.

    Attributes:
        key: the offending schema or extra key (None: the file as a whole).
        path: the file, when the log came from one.
        reason: what is wrong, without key and path.
    """

    def __init__(self, reason: str, key: str | None = None,
                 path: str | os.PathLike[str] | None = None) -> None:
        where = f"{path}: " if path is not None else ""
        what = f"beacon log key {key!r}: " if key else ""
        super().__init__(f"{where}{what}{reason}")
        self.reason, self.key, self.path = reason, key, path


def _shape_text(shape: tuple[int | str, ...]) -> str:
    return "(" + ", ".join(str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"


def _checked(key: str, value: Any, dims: dict[str, int]) -> np.ndarray:
    """``value`` as a read-only array of the schema's dtype and shape for ``key``.

    Named axes (N, B, ...) bind in ``dims`` on first use and must agree afterwards.
    """
    kind, shape = _SCHEMA[key]
    kinds, dtype, what = _KINDS[kind]
    try:
        a = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise BeaconLogError(f"not an array ({exc})", key) from None
    if a.dtype.kind not in kinds:
        raise BeaconLogError(f"dtype {a.dtype}, every entry must be {what}", key)
    if a.ndim != len(shape) or any(isinstance(want, int) and want != got
                                   for want, got in zip(shape, a.shape, strict=True)) \
            or (shape == ("P+1",) and a.shape[0] < 1):
        raise BeaconLogError(f"shape {a.shape}, expected {_shape_text(shape)}", key)
    for axis, (want, got) in enumerate(zip(shape, a.shape, strict=True)):
        if isinstance(want, str) and want != "P+1":
            if dims.setdefault(want, got) != got:
                raise BeaconLogError(f"shape {a.shape}: axis {axis} must be {want}={dims[want]} "
                                     f"as elsewhere in the log", key)
    a = np.array(a, dtype=dtype)
    if kind == "float" and not np.all(np.isfinite(a)):
        where = tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])
        raise BeaconLogError(f"non-finite value at index {where}", key)
    a.flags.writeable = False
    return a


def _parse_config(text: Any) -> dict[str, Any]:
    if not isinstance(text, str):
        raise BeaconLogError(f"must be a JSON string, got {type(text).__name__}", "config_json")
    try:
        config = parse_json(text)
    except ValueError as exc:
        raise BeaconLogError(f"not valid JSON ({exc})", "config_json") from None
    if not isinstance(config, dict):
        raise BeaconLogError("must be a JSON object", "config_json")
    return config


def _fail_at(bad: np.ndarray, key: str, message: str) -> None:
    """Raise for ``key`` when any row of ``bad`` is set; ``{row}`` in ``message`` is the first."""
    if bad.any():
        raise BeaconLogError(message.format(row=int(np.flatnonzero(bad)[0])), key)


def _repeated_rows(rows: np.ndarray) -> np.ndarray:
    """(n,) bool: the rows of the (n, 2) ``rows`` equal to an earlier row."""
    order = np.lexsort((rows[:, 1], rows[:, 0]))  # stable: equal rows keep their order
    repeated = np.zeros(len(rows), dtype=bool)
    repeated[order[1:]] = np.all(rows[order[1:]] == rows[order[:-1]], axis=1)
    return repeated


@dataclass(frozen=True, eq=False)
class BeaconLog:
    """One episode's record, validated and immutable (arrays are read-only).

    Build one with :class:`BeaconLogRecorder` or :meth:`load`; the constructor takes every
    schema key as a keyword and ``extras``, further named arrays kept as they are.
    """

    config_json: str
    field: np.ndarray
    obstacle_vertices: np.ndarray
    obstacle_offsets: np.ndarray
    nodes: np.ndarray
    beacons: np.ndarray
    receptions: np.ndarray
    node_links: np.ndarray
    anchor_path: np.ndarray
    node_energy: np.ndarray
    anchor_energy: float
    radio_range: float
    collisions: int
    version: int = SCHEMA_VERSION
    extras: Mapping[str, np.ndarray] = dataclasses.field(default_factory=dict)
    _obstacle_map: ObstacleMap = dataclasses.field(init=False, repr=False)

    def __post_init__(self) -> None:
        dims: dict[str, int] = {}
        values = {key: _checked(key, getattr(self, key), dims) for key in KEYS}
        version = int(values["version"])
        if version not in SUPPORTED_VERSIONS:
            raise BeaconLogError(f"unsupported version {version} (this reader supports "
                                 f"{', '.join(map(str, SUPPORTED_VERSIONS))})", "version")
        _parse_config(str(values["config_json"]))
        if not np.all(values["field"] > 0):
            raise BeaconLogError("width and height must be positive", "field")
        if np.any(values["field"] > MAX_FIELD):
            raise BeaconLogError(f"width and height must be at most {MAX_FIELD:g} m (the largest "
                                 f"field_size), got {values['field'].tolist()}", "field")
        obstacle_map = self._obstacles(values["field"], values["obstacle_vertices"],
                                       values["obstacle_offsets"])
        n, b = dims["N"], dims["B"]
        for key in ("beacons", "anchor_path"):
            _fail_at(np.diff(values[key][:, 0]) < 0, key,
                     "time (column 0) decreases from row {row} to the next")
            _fail_at(values[key][:, 0] < 0, key, "negative time in row {row}")
        # positions inside the field (up to FIELD_TOLERANCE of its size): nodes, beacons and
        # the anchor's path all lie on the field
        low = -FIELD_TOLERANCE * values["field"]
        high = (1 + FIELD_TOLERANCE) * values["field"]
        w, h = values["field"]
        for key, xy in (("nodes", values["nodes"]), ("beacons", values["beacons"][:, 1:]),
                        ("anchor_path", values["anchor_path"][:, 1:])):
            _fail_at(((xy < low) | (xy > high)).any(axis=1), key,
                     f"row {{row}} lies outside the {w:g} x {h:g} m field")
        rec = values["receptions"]
        _fail_at((rec[:, 0] < 0) | (rec[:, 0] >= b), "receptions",
                 f"beacon index out of [0, B={b}) in row {{row}}")
        _fail_at((rec[:, 1] < 0) | (rec[:, 1] >= n), "receptions",
                 f"node index out of [0, N={n}) in row {{row}}")
        _fail_at(_repeated_rows(rec), "receptions", "row {row} repeats an earlier (beacon, node)")
        links = values["node_links"]
        _fail_at((links < 0).any(axis=1) | (links >= n).any(axis=1), "node_links",
                 f"node index out of [0, N={n}) in row {{row}}")
        _fail_at(links[:, 0] >= links[:, 1], "node_links", "row {row} is not a pair i < j")
        _fail_at(_repeated_rows(links), "node_links", "row {row} repeats an earlier pair")
        _fail_at(values["node_energy"] < 0, "node_energy", "negative energy at node {row}")
        for key in ("anchor_energy", "collisions"):
            if values[key] < 0:
                raise BeaconLogError(f"must not be negative, got {values[key]}", key)
        if values["radio_range"] <= 0:
            raise BeaconLogError(f"must be positive, got {values['radio_range']}",
                                 "radio_range")
        extras = {}
        for name, value in dict(self.extras).items():
            if (not isinstance(name, str) or not name or name in _SCHEMA or "/" in name
                    or name in _SAVEZ_ARGUMENTS):
                raise BeaconLogError(f"extra key {name!r} must be a new, non-empty name "
                                     f"without '/', and not {' or '.join(_SAVEZ_ARGUMENTS)} "
                                     f"(np.savez's own arguments)")
            a = np.array(value)
            if a.dtype.hasobject:
                raise BeaconLogError("extra arrays must not hold Python objects", name)
            a.flags.writeable = False
            extras[name] = a
        for key, value in values.items():
            if value.ndim == 0:
                value = {"int": int, "float": float, "str": str}[_SCHEMA[key][0]](value)
            object.__setattr__(self, key, value)
        object.__setattr__(self, "extras", extras)
        object.__setattr__(self, "_obstacle_map", obstacle_map)

    @staticmethod
    def _obstacles(field_size: np.ndarray, vertices: np.ndarray,
                   offsets: np.ndarray) -> ObstacleMap:
        if offsets[0] != 0:
            raise BeaconLogError(f"must start at 0, got {offsets[0]}", "obstacle_offsets")
        if offsets[-1] != len(vertices):
            raise BeaconLogError(f"must end at V={len(vertices)} (rows of obstacle_vertices), "
                                 f"got {offsets[-1]}", "obstacle_offsets")
        short = np.diff(offsets) < 3
        if short.any():
            raise BeaconLogError(f"must increase by >= 3 (vertices per polygon); polygon "
                                 f"{int(np.flatnonzero(short)[0])} does not",
                                 "obstacle_offsets")
        try:
            return ObstacleMap(float(field_size[0]), float(field_size[1]),
                               [vertices[offsets[p]:offsets[p + 1]]
                                for p in range(len(offsets) - 1)])
        except MapError as exc:
            raise BeaconLogError(str(exc), "obstacle_vertices") from None

    # --- views ----------------------------------------------------------------------------
    @property
    def obstacle_map(self) -> ObstacleMap:
        """The field and obstacles as an :class:`ObstacleMap` (built during validation)."""
        return self._obstacle_map

    @property
    def config(self) -> dict[str, Any]:
        """``config_json`` parsed."""
        return json.loads(self.config_json)

    @property
    def n_nodes(self) -> int:
        return len(self.nodes)

    @property
    def n_beacons(self) -> int:
        return len(self.beacons)

    def arrays(self) -> dict[str, np.ndarray]:
        """Every schema key and extra as a numpy array, as written to the file."""
        out = {key: np.asarray(getattr(self, key), dtype=_KINDS[_SCHEMA[key][0]][1])
               for key in KEYS}
        return {**out, **self.extras}

    # --- files ----------------------------------------------------------------------------
    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the log to ``path`` (exactly that name) as ``.npz``, atomically."""
        with atomic_open(path, "wb") as f:
            np.savez(f, **self.arrays())

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> BeaconLog:
        """Read and validate a log written by :meth:`save` (or any tool following the schema).

        Raises:
            FileNotFoundError: no file at ``path``.
            BeaconLogError: the file is not a readable ``.npz`` or a key is missing or invalid.
        """
        # A damaged archive fails deep inside zipfile, zlib or numpy's header parser with many
        # exception types (BadZipFile, zlib.error, NotImplementedError for unknown zip
        # versions, RuntimeError for a flipped "encrypted" bit, tokenize.TokenError for a
        # garbled .npy header, ...): at this file boundary every one of them means "unreadable".
        unreadable = Exception
        arrays: dict[str, np.ndarray] = {}
        if os.path.isfile(path) and not zipfile.is_zipfile(path):
            raise BeaconLogError("not an .npz archive (no zip structure): written by "
                                 "BeaconLog.save?", path=path)
        try:
            data = np.load(path, allow_pickle=False)
        except FileNotFoundError:
            raise
        except unreadable as exc:
            raise BeaconLogError(f"not a readable .npz file ({type(exc).__name__}: "
                                 f"{one_line(exc)})",
                                 path=path) from None
        if not isinstance(data, np.lib.npyio.NpzFile):
            raise BeaconLogError("not an .npz archive (a single .npy array)", path=path)
        with data:
            for key in data.files:
                try:
                    arrays[key] = data[key]
                except unreadable as exc:
                    raise BeaconLogError(f"cannot read ({type(exc).__name__}: {one_line(exc)})",
                                         key, path) from None
        for key in KEYS:
            if key not in arrays:
                raise BeaconLogError(f"missing (keys present: {sorted(arrays)})", key, path)
        schema = {key: arrays.pop(key) for key in KEYS}
        try:
            return cls(**schema, extras=arrays)
        except BeaconLogError as exc:
            raise BeaconLogError(exc.reason, exc.key, path) from None


def episode_config_json(config: AOASSConfig, *, seed: int | None, method: str) -> str:
    """The ``config_json`` of an episode: ``{"config": {...}, "seed": seed, "method": method}``."""
    return json.dumps({"config": config.to_dict(), "seed": seed, "method": method},
                      sort_keys=True)


class BeaconLogRecorder:
    """Collects one episode's log step by step; :meth:`finish` returns the :class:`BeaconLog`.

    Args:
        config_json: the full config, seed and method name as a JSON object string.
        obstacle_map: the episode's field and static obstacles.
        nodes: (N, 2) true node positions [m].
        radio_range: R [m].
    """

    def __init__(self, *, config_json: str, obstacle_map: ObstacleMap, nodes: np.ndarray,
                 radio_range: float) -> None:
        if not isinstance(obstacle_map, ObstacleMap):
            raise TypeError(f"obstacle_map must be an ObstacleMap, got {type(obstacle_map)!r}")
        _parse_config(config_json)
        r = _checked("radio_range", radio_range, {})
        if not r > 0:
            raise BeaconLogError(f"must be positive, got {radio_range!r}", "radio_range")
        self._static = {"config_json": config_json,
                        "field": np.array([obstacle_map.width, obstacle_map.height]),
                        "nodes": _checked("nodes", nodes, {}), "radio_range": float(r)}
        polys = obstacle_map.polygons
        self._static["obstacle_vertices"] = (np.concatenate(polys) if polys
                                             else np.zeros((0, 2)))
        self._static["obstacle_offsets"] = np.concatenate(
            [[0], np.cumsum([len(p) for p in polys], dtype=np.int64)]).astype(np.int64)
        self._n_nodes = len(self._static["nodes"])
        self._beacons: list[tuple[float, float, float]] = []
        self._receivers: list[np.ndarray] = []
        self._path: list[tuple[float, float, float]] = []

    @property
    def n_beacons(self) -> int:
        return len(self._beacons)

    @property
    def beacon_positions(self) -> np.ndarray:
        """(B, 2) positions [m] of the beacons recorded so far, in order (a new array)."""
        return np.array(self._beacons, dtype=np.float64).reshape(-1, 3)[:, 1:]

    @property
    def path_points(self) -> np.ndarray:
        """(P, 2) anchor positions [m] recorded so far, in order (a new array)."""
        return np.array(self._path, dtype=np.float64).reshape(-1, 3)[:, 1:]

    @staticmethod
    def _row(key: str, t: float, position: np.ndarray,
             rows: list[tuple[float, float, float]]) -> tuple[float, float, float]:
        """(t [s], x [m], y [m]) as Python floats, checked: finite, not before the last row."""
        if type(position) is tuple and len(position) == 2:
            # the simulator's (x, y) of Python floats, the common case: no array (a finite sum
            # means three finite floats; anything else goes on to the checks below)
            x, y = position
            if type(x) is float and type(y) is float and type(t) is float \
                    and math.isfinite(t + x + y) and not (rows and t < rows[-1][0]):
                return t, x, y
        p = np.asarray(position, dtype=np.float64)
        if p.shape != (2,) or not (np.all(np.isfinite(p)) and np.isfinite(t)):
            raise BeaconLogError(f"need a finite time and (2,) position, got t={t!r}, "
                                 f"position={position!r}", key)
        if rows and t < rows[-1][0]:
            raise BeaconLogError(f"time {t} s is before the previous entry's {rows[-1][0]} s", key)
        return float(t), float(p[0]), float(p[1])

    def add_beacon(self, t: float, position: np.ndarray, receivers: np.ndarray) -> int:
        """Record a beacon broadcast at time ``t`` [s] from ``position`` (2,) [m], heard by
        the node indices ``receivers``; returns the beacon's index."""
        row = self._row("beacons", t, position, self._beacons)
        idx = np.asarray(receivers)
        if idx.ndim != 1 or (idx.size and idx.dtype.kind not in "iu"):
            raise BeaconLogError(f"receivers must be 1-D node indices, got shape {idx.shape} "
                                 f"dtype {idx.dtype}", "receptions")
        idx = idx.astype(np.int64)
        if idx.size and (idx.min() < 0 or idx.max() >= self._n_nodes):
            raise BeaconLogError(f"receivers must be node indices in [0, {self._n_nodes})",
                                 "receptions")
        self._beacons.append(row)
        self._receivers.append(idx)
        return len(self._beacons) - 1

    def add_path_point(self, t: float, position: np.ndarray) -> None:
        """Record the anchor at ``position`` (2,) [m] at time ``t`` [s]."""
        self._path.append(self._row("anchor_path", t, position, self._path))

    def finish(self, *, node_energy: np.ndarray, anchor_energy: float, collisions: int,
               node_links: np.ndarray,
               extras: Mapping[str, np.ndarray] | None = None) -> BeaconLog:
        """The validated log, with the final energies [J], collision count and node links."""
        counts = [len(r) for r in self._receivers]
        receptions = np.stack([
            np.repeat(np.arange(len(counts), dtype=np.int64), counts),
            np.concatenate(self._receivers) if counts else np.zeros(0, np.int64)], axis=1)
        return BeaconLog(
            **self._static,
            beacons=np.array(self._beacons, dtype=np.float64).reshape(-1, 3),
            receptions=receptions,
            node_links=np.zeros((0, 2), np.int64) if np.size(node_links) == 0 else node_links,
            anchor_path=np.array(self._path, dtype=np.float64).reshape(-1, 3),
            node_energy=node_energy, anchor_energy=anchor_energy, collisions=collisions,
            extras=dict(extras or {}))
