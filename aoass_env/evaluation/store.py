"""``episodes.csv``: its schema, appending finished episodes safely, and reading it back.

One row per (method, map, field_size, n_nodes, obstacle_density, seed, localizer). The rows of
one episode (one per localizer) are appended with a single write followed by ``fsync``, so an
interrupted sweep leaves every finished episode on disk; a crash in the middle of that write can
leave at most one half-written trailing line, which :meth:`EpisodeStore.open` detects, drops
with a warning and removes from the file (rewritten atomically) before anything is appended.
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import json
import math
import os
import warnings
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import IO, Any

from aoass_env.atomic import write_text_atomic
from aoass_env.localization import METHODS as LOCALIZATION_METHODS

try:
    import fcntl
except ImportError:       # Windows: no advisory locks
    fcntl = None  # type: ignore[assignment]

__all__ = ["BLAS_KERNELS", "COLUMNS", "CONFIG_DEFAULTS", "EPISODE_FIELDS", "INPUTS_FILE",
           "KEY_FIELDS", "LOCALIZATION_FIELDS", "NO_LOCALIZER", "TIMING_FIELDS", "EpisodeKey",
           "EpisodeStore", "EvaluationError", "apply_inputs", "blas_kernels", "checked_row",
           "RUNS_FILE", "comparable_lines", "config_input", "file_digest", "in_key_order",
           "read_episodes", "read_inputs", "read_runs", "record_run", "row_key", "stale_rows"]


class EvaluationError(ValueError):
    """Bad input to the evaluation (unknown name, missing checkpoint, unusable folder)."""


@dataclass(frozen=True, order=True)
class EpisodeKey:
    """What fixes one episode: the method, the map (shipped name or file path), the field side
    (m), the node count, the map's obstacle density (nominal, fraction of the field) and the
    seed of the episode's random generator."""

    method: str
    map: str
    field_size: float
    n_nodes: int
    obstacle_density: float
    seed: int

    def __str__(self) -> str:
        return (f"{self.method} {self.map} f{self.field_size:g} N={self.n_nodes} "
                f"d={self.obstacle_density:g} seed={self.seed}")


KEY_FIELDS = tuple(f.name for f in fields(EpisodeKey))
#: Columns of one localizer's result: Eq. 15 RMSE (m) over the localized nodes, the localized
#: fraction, and the localizer's wall time (s).
LOCALIZATION_FIELDS = ("localizer", "rmse", "localized", "localize_seconds")
#: The ``localizer`` of an episode's single row when it is not localized (``--localizers
#: none``): its localization cells are empty, its episode columns filled as usual.
NO_LOCALIZER = "none"
#: The localizer column's values: a localization method, or none.
_LOCALIZER_NAMES = (*LOCALIZATION_METHODS, NO_LOCALIZER)
#: Columns of the episode, the same on each of its localizer rows (units in docs/evaluation.md).
EPISODE_FIELDS = ("coverage", "beacons", "path_length", "ideal_length", "travel_time",
                  "ideal_time", "eta_traj", "collisions", "collisions_static",
                  "collisions_moving", "energy_total", "e_norm", "eer", "path_complete",
                  "safety_intervention", "wall_seconds")
COLUMNS = KEY_FIELDS + LOCALIZATION_FIELDS + EPISODE_FIELDS
#: The wall-clock columns: they differ between any two runs of the same episode.
TIMING_FIELDS = ("localize_seconds", "wall_seconds")
_TEXT = ("method", "map", "localizer")
_INTEGER = ("n_nodes", "seed", "beacons", "collisions", "collisions_static",
            "collisions_moving", "path_complete")
#: What a value read back may be: (low, high), both included; a column not listed here is
#: >= 0 (a seed may be -1: a log localized by ``--logs`` that recorded none). Empty cells
#: (NaN) pass; only ``e_norm`` and ``eer`` may be infinite (no beacons, no energy). A row
#: outside them was not written by an episode (hand-edited, or another tool's).
_RANGES = {"field_size": (1e-9, math.inf), "n_nodes": (1, math.inf),
           "seed": (-1, math.inf), "obstacle_density": (0.0, 1.0), "localized": (0.0, 1.0),
           "coverage": (0.0, 1.0), "path_complete": (0, 1)}
_INFINITE = ("e_norm", "eer")


def _cell(value: Any) -> Any:
    """A CSV cell: missing values (None, NaN) are empty."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    return value


def _parsed(row: dict[str, str]) -> dict[str, Any]:
    """A CSV row with typed values: text, int, float (empty cells: NaN)."""
    out: dict[str, Any] = {}
    for name in COLUMNS:
        text = row[name]
        if name in _TEXT:
            if "\n" in text or "\r" in text:   # the file is read line by line
                raise ValueError(f"{name}={text!r} holds a line break")
            out[name] = text
        elif text == "":
            out[name] = math.nan
        else:
            value = int(text) if name in _INTEGER else float(text)
            low, high = _RANGES.get(name, (0, math.inf))
            if math.isnan(value) or not low <= value <= high or (
                    math.isinf(value) and name not in _INFINITE):
                what = "a number" if name in _INFINITE else "a finite number"
                where = f">= {low:g}" if high == math.inf else f"in [{low:g}, {high:g}]"
                raise ValueError(f"{name}={text!r} must be {what} {where}")
            out[name] = value
    if not out["method"]:
        raise ValueError("method is empty")
    # a hand-edited "dvhopX" made a column of its own ("": the episode part alone, checked_row)
    if out["localizer"] and out["localizer"] not in _LOCALIZER_NAMES:
        raise ValueError(f"localizer={out['localizer']!r} is not one of "
                         f"{', '.join(_LOCALIZER_NAMES)}")
    return out


def checked_row(values: Mapping[str, Any]) -> dict[str, Any]:
    """``values`` (column -> value; a missing column is empty) as episodes.csv would read them
    back: typed and range-checked; ValueError naming the column otherwise."""
    return _parsed({name: str(_cell(values.get(name))) for name in COLUMNS})


def row_key(row: dict[str, Any]) -> tuple[EpisodeKey, str]:
    """(episode key, localizer) of a typed row."""
    return EpisodeKey(**{k: row[k] for k in KEY_FIELDS}), row["localizer"]


def in_key_order(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """``rows`` sorted by (episode key, localizer): the order the tables and figures read
    them in, so that they do not depend on the order the episodes finished in (workers, a
    resume): their means are sums in row order, their bootstrap resamples rows by position."""
    return sorted(rows, key=row_key)


def _csv_text(rows: list[dict[str, Any]], header: bool) -> str:
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(COLUMNS), lineterminator="\n")
    if header:
        writer.writeheader()
    writer.writerows({k: _cell(r[k]) for k in COLUMNS} for r in rows)
    return buf.getvalue()


def _split_complete(path: Path, text: str) -> tuple[list[dict[str, Any]], str]:
    """Typed rows of ``text`` and the text of its complete lines; a half-written trailing line
    is dropped with a warning. Raises EvaluationError for another schema or a broken row."""
    # lines end at "\n" only: str.splitlines also breaks at \x0c, \x1c-\x1e, \x85 and
    # U+2028/9, which the writer leaves unquoted in a map name (the row then read as broken)
    lines = [line + "\n" for line in text.split("\n")]
    lines[-1] = lines[-1][:-1]
    if not lines[-1]:
        lines.pop()
    if not lines or not lines[0].endswith("\n"):
        return [], ""            # nothing, or a crash while writing the header
    header = next(csv.reader([lines[0]]))
    if tuple(header) != COLUMNS:
        raise EvaluationError(
            f"{path} has other columns than this version writes ({', '.join(header)}); "
            f"move it away or choose another --out folder")
    if not lines[-1].endswith("\n"):
        warnings.warn(f"{path}: dropped a half-written last line (an interrupted write): "
                      f"{lines[-1][:80]!r}", stacklevel=3)
        lines = lines[:-1]
    rows: list[dict[str, Any]] = []
    line_of: dict[tuple[EpisodeKey, str], int] = {}
    for number, record in enumerate(csv.reader(lines[1:]), start=2):
        try:
            if len(record) != len(COLUMNS):
                raise ValueError(f"{len(record)} cells, expected {len(COLUMNS)}")
            rows.append(_parsed(dict(zip(COLUMNS, record, strict=True))))
        except ValueError as exc:
            raise EvaluationError(f"{path}, line {number}: broken row ({exc}); fix or remove "
                                  f"the line, or choose another --out folder") from None
        first = line_of.setdefault(row_key(rows[-1]), number)
        if first != number:     # e.g. two runs appending to one folder: counted twice
            raise EvaluationError(f"{path}, line {number}: repeats the episode and localizer "
                                  f"of line {first}; remove one of them")
    return rows, "".join(lines)


def read_episodes(path: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """The typed rows of an ``episodes.csv`` (a half-written last line dropped, with a
    warning)."""
    path = Path(path)
    return _split_complete(path, _read_text(path))[0]


def _read_text(path: Path) -> str:
    """The UTF-8 text of ``path``; EvaluationError naming it when it is not UTF-8."""
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise EvaluationError(f"{path} is not an episodes.csv of this evaluation (not UTF-8 "
                              f"text: {exc.reason} at byte {exc.start})") from None


def comparable_lines(path: str | os.PathLike[str]) -> set[str]:
    """The lines of an ``episodes.csv``, header included, without the :data:`TIMING_FIELDS`
    cells: the same set for two runs of the same episodes, in any order, on any backend."""
    with open(path, encoding="utf-8", newline="") as f:
        records = list(csv.reader(f))
    keep = [i for i, name in enumerate(records[0]) if name not in TIMING_FIELDS]
    return {_csv_line([record[i] for i in keep]) for record in records}


def _csv_line(cells: list[str]) -> str:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(cells)
    return buf.getvalue()


#: The file beside ``episodes.csv`` that names the checkpoints its rows were produced with.
INPUTS_FILE = "inputs.json"


def file_digest(*paths: str | os.PathLike[str]) -> str:
    """SHA-256 (hex) of the bytes of ``paths`` in turn; a missing path counts as empty."""
    digest = hashlib.sha256()
    for path in paths:
        digest.update(str(Path(path).name).encode())
        if Path(path).is_file():
            digest.update(Path(path).read_bytes())
    return digest.hexdigest()


#: The input names (:func:`stale_rows`) of the config defaults a method is built from start
#: with this (:func:`config_input`); a record of an older evaluate.py holds it alone, for the
#: defaults of every method's configs.
CONFIG_DEFAULTS = "config defaults"


def config_input(method: str) -> str:
    """The input name of the config defaults ``method`` is built from: "config defaults of
    spiral"."""
    return f"{CONFIG_DEFAULTS} of {method}"


#: The input name (:func:`stale_rows`) of the BLAS kernels every row was computed with
#: (:func:`blas_kernels`).
BLAS_KERNELS = "BLAS kernels"


def blas_kernels() -> str:
    """The BLAS libraries NumPy and SciPy load in this process and the kernels each picked for
    the CPU, e.g. ``"openblas SkylakeX"`` (``threadpoolctl``; a library that does not say:
    its name alone).

    The episodes depend on the last bits of small matrix products (the safety stack's tracker
    and fuzzy controller, the localizers' least squares), which OpenBLAS sums in an order its
    kernels set: another CPU, or ``OPENBLAS_CORETYPE``, can move an episode (docs/evaluation.md).
    """
    import scipy.linalg  # noqa: F401  (loads SciPy's own BLAS, which the localizers use)
    from threadpoolctl import threadpool_info

    found = {" ".join(filter(None, (info.get("internal_api"), info.get("architecture"))))
             for info in threadpool_info() if info.get("user_api") == "blas"}
    return ", ".join(sorted(found)) or "none"


def _input_phrase(name: str) -> str:
    """How an input of :func:`stale_rows` is named in its refusal: "another policy
    checkpoint", "another aoass-adaptive checkpoint", "other config defaults of spiral",
    "another aoass-rule stack", "other BLAS kernels"."""
    if name.startswith(CONFIG_DEFAULTS) or name == BLAS_KERNELS:
        return f"other {name}"
    if name.endswith(" stack"):
        return f"another {name} (the tracker, safety filter or action type of its run record)"
    return f"another {name.removesuffix(' checkpoint')} checkpoint"


def stale_rows(store: EpisodeStore, inputs: dict[str, str],
               scope: Mapping[str, Collection[str]] | None = None,
               discard: bool = False, localizers: Mapping[str, str] | None = None
               ) -> Callable[[dict[str, Any]], bool] | None:
    """Which rows of ``store`` were produced with other inputs than this run's: a predicate
    of the rows :func:`apply_inputs` drops (None: none); nothing is changed yet, so that
    other checks may refuse the run first.

    ``inputs`` maps a name (``"policy"``, ``"olstm-dvhop"``, :func:`config_input` of a
    method, :data:`BLAS_KERNELS`) to the digest (:func:`file_digest`, or
    :func:`~aoass_env.evaluation.methods.config_defaults_digest`) or the name
    (:func:`blas_kernels`) of what that name stands for; ``scope`` maps a name to the methods
    whose rows depend on it (a name not in it: every row), and ``localizers`` a name to the
    one localizer whose rows alone depend on it (a localizer's checkpoint: the other rows of
    its episodes stay). An input changed for the rows in its scope when the record
    (:data:`INPUTS_FILE` beside the CSV) gives another value, or none while such rows exist
    (they were made by an older evaluate.py that did not record it).

    Raises:
        EvaluationError: without ``discard``, an input changed for some rows, i.e. resuming
            would mix episodes of two checkpoints, two sets of defaults or two BLAS kernels
            in one table; an unreadable record.
    """
    record_path = store.path.with_name(INPUTS_FILE)
    recorded = read_inputs(store.path.parent)

    def depends(name: str, row: dict[str, Any]) -> bool:
        """Does ``row`` depend on the input ``name``?"""
        only = (localizers or {}).get(name)
        return ((scope is None or name not in scope or row["method"] in scope[name])
                and (only is None or row["localizer"] == only))

    changed: dict[str, set[str]] = {}     # input -> the methods of the rows that depend on it
    for name, value in inputs.items():
        if recorded.get(name) != value:
            methods = {row["method"] for row in store.rows if depends(name, row)}
            if methods:
                changed[name] = methods
    if changed and not discard:
        stale = sorted(set().union(*changed.values()))
        raise EvaluationError(
            f"{store.path} holds episodes of {', '.join(stale)} produced with "
            f"{' and '.join(_input_phrase(n) for n in changed)} than this run's "
            f"({record_path} records what they were produced with); resuming would mix the "
            f"two in one table. Run again with --discard-changed to drop those episodes and "
            f"run them anew, delete {store.path} (or the folder), or choose another --out folder")
    if not changed:
        return None
    return lambda row: any(depends(name, row) for name in changed)


def apply_inputs(store: EpisodeStore, inputs: dict[str, str],
                 stale: Callable[[dict[str, Any]], bool] | None) -> None:
    """Drop the ``stale`` rows (:func:`stale_rows`) and record ``inputs`` in
    :data:`INPUTS_FILE` (written atomically, merged with earlier records; while no row
    depends on a name, a new digest simply replaces the recorded one)."""
    if stale is not None:
        store.discard(stale)
    record_path = store.path.with_name(INPUTS_FILE)
    merged = read_inputs(store.path.parent) | inputs
    try:
        write_text_atomic(record_path, json.dumps(merged, indent=1, sort_keys=True) + "\n")
    except OSError as exc:
        raise EvaluationError(f"cannot write {record_path}: {exc.strerror or exc}") from None


def read_inputs(folder: str | os.PathLike[str]) -> dict[str, str]:
    """The inputs recorded in :data:`INPUTS_FILE` in ``folder`` ({} without a record): what its
    episodes were produced with (:func:`stale_rows`).

    Raises:
        EvaluationError: the record is unreadable.
    """
    record_path = Path(folder) / INPUTS_FILE
    if not record_path.is_file():
        return {}
    try:
        return dict(json.loads(record_path.read_text(encoding="utf-8")))
    except (OSError, TypeError, ValueError) as exc:
        raise EvaluationError(f"{record_path} is unreadable ({exc}); delete it and the "
                              f"episodes.csv beside it, or choose another --out folder") from None


#: The file beside ``episodes.csv`` with one JSON line per run of evaluate.py on the folder:
#: what the run did and its wall time (s), so that the time of a resumed sweep adds up.
RUNS_FILE = "runs.jsonl"


def record_run(store: EpisodeStore, record: dict[str, Any]) -> None:
    """Append ``record`` as one line of :data:`RUNS_FILE` beside ``store`` (one write, synced).

    Raises:
        EvaluationError: the file cannot be written.
    """
    path = store.path.with_name(RUNS_FILE)
    try:
        torn = path.is_file() and path.stat().st_size > 0 and not path.read_bytes().endswith(b"\n")
        with open(path, "a", encoding="utf-8") as f:
            # a torn last line (a run killed mid-write) is ended first, or this record would
            # join it and be read as one broken line with it
            f.write(("\n" if torn else "") + json.dumps(record, sort_keys=True) + "\n")
            f.flush()
            os.fsync(f.fileno())
    except OSError as exc:
        raise EvaluationError(f"cannot write {path}: {exc.strerror or exc}") from None


def read_runs(folder: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """The records of :data:`RUNS_FILE` in ``folder`` (none if it is missing); a line that is
    not a JSON object (a torn last write) is left out."""
    path = Path(folder) / RUNS_FILE
    if not path.is_file():
        return []
    records = []
    for line in path.read_text(encoding="utf-8").splitlines():
        with contextlib.suppress(ValueError):
            record = json.loads(line)
            if isinstance(record, dict):
                records.append(record)
    return records


def _lock(path: Path) -> IO[bytes]:
    """An exclusive lock on ``path``'s folder for appending to it (a ``.<name>.lock`` file
    beside it, held while the returned file is open): a second store on the same file, e.g. a
    second ``evaluate.py`` on one ``--out``, would append the same episodes twice. Advisory
    (``fcntl``); where that is missing (Windows), no lock is taken."""
    handle = open(path.with_name(f".{path.name}.lock"), "ab")  # noqa: SIM115
    if fcntl is not None:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.close()
            raise EvaluationError(f"{path} is being written by another evaluate.py run; wait "
                                  f"for it, or choose another --out folder") from None
    return handle


class EpisodeStore:
    """``episodes.csv`` of an output folder, open for appending finished episodes.

    Args:
        path: the CSV file; created with its header if missing.

    Raises:
        EvaluationError: the folder cannot be created or written, another store holds it
            (:func:`_lock`), or the file holds another schema, a broken or repeated row, or is
            not UTF-8.
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._lock = _lock(self.path)
            try:
                text = _read_text(self.path) if self.path.is_file() else ""
                self.rows, complete = _split_complete(self.path, text)
                if complete != text or not complete:
                    write_text_atomic(self.path, complete or _csv_text([], header=True))
                self._file = open(self.path, "a", encoding="utf-8", newline="")  # noqa: SIM115
            except BaseException:
                self._lock.close()          # a failed store holds no lock
                raise
        except OSError as exc:
            raise EvaluationError(f"cannot write the output folder {self.path.parent}: "
                                  f"{exc.strerror or exc}") from None
        #: (episode key, localizer) pairs already in the file
        self.done = {row_key(r) for r in self.rows}

    def discard(self, drop: Callable[[dict[str, Any]], bool]) -> None:
        """Drop the rows for which ``drop(row)`` holds from the file (rewritten atomically):
        they count as not done (an episode with some of its localizers' rows left runs again
        for the others alone)."""
        self._file.close()
        self.rows = [r for r in self.rows if not drop(r)]
        try:
            write_text_atomic(self.path, _csv_text(self.rows, header=True))
            self._file = open(self.path, "a", encoding="utf-8", newline="")  # noqa: SIM115
        except OSError as exc:
            raise EvaluationError(f"cannot write {self.path}: {exc.strerror or exc}") from None
        self.done = {row_key(r) for r in self.rows}

    def append(self, rows: list[dict[str, Any]]) -> None:
        """Append one episode's rows (one write, flushed and synced to disk). Each row must read
        back as :func:`checked_row` reads it and hold an (episode, localizer) pair not stored
        yet; else a ValueError naming the column or the pair, and nothing is written (a row
        the file could not read back made the whole file unreadable, the sweep unresumable)."""
        keys = []
        for row in rows:
            key = row_key(checked_row(row))
            if key in self.done or key in keys:
                episode, localizer = key
                raise ValueError(f"EpisodeStore.append: {self.path} holds the episode {episode} "
                                 f"with localizer {localizer!r} already (or the rows repeat it)")
            keys.append(key)
        self._file.write(_csv_text(rows, header=False))
        self._file.flush()
        os.fsync(self._file.fileno())
        self.rows.extend({k: math.nan if r[k] is None else r[k] for k in COLUMNS} for r in rows)
        self.done.update(keys)

    def close(self) -> None:
        self._file.close()
        self._lock.close()      # releases the lock

    def __enter__(self) -> EpisodeStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
