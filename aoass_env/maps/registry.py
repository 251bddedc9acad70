"""The shipped maps: the ``train`` and ``test`` splits under the repository's ``maps/`` folder.

:func:`list_maps` names them, :func:`validation_split` holds some out for model selection and
:func:`load_map` reads a map by name (or from any path).
"""

from __future__ import annotations

import difflib
import os
import re
from collections import OrderedDict
from pathlib import Path

from aoass_env.data import shipped_dir
from aoass_env.maps.obstacle_map import MapError, ObstacleMap, _field_dims
from aoass_env.maps.text_format import read_map
from aoass_env.validators import positive, vec2

#: Folder of the shipped maps (``train/`` and ``test/``): the repository's ``maps/``, or the
#: installed wheel's copy (:func:`aoass_env.data.shipped_dir`).
MAPS_DIR = shipped_dir("maps")
#: Splits of the shipped maps.
SPLITS = ("train", "test")


def list_maps(split: str, *, field_size: float | None = None,
              densities: tuple[float, float] | None = None) -> list[str]:
    """Names (``"<split>/<stem>"``) of the shipped maps of ``split`` ("train" or "test").

    Shipped stems read ``d<density>_f<field size>_s<seed>``; ``field_size`` (m) keeps the maps
    of that field size, ``densities`` = (low, high) those whose density lies in [low, high]
    (0 <= low <= high <= 1)."""
    if split not in SPLITS:
        raise MapError(f"split={split!r} must be one of {SPLITS}")
    if field_size is not None:
        field_size = positive("field_size", field_size, "m", error=MapError)
    if densities is not None:
        low, high = vec2("densities", densities, "low, high", error=MapError)
        if not 0.0 <= low <= high <= 1.0:
            raise MapError(f"densities={densities!r} must be (low, high) with "
                           f"0 <= low <= high <= 1 (obstacle area / field area)")
        densities = (low, high)
    folder = MAPS_DIR / split
    if not folder.is_dir():
        raise MapError(f"shipped map folder {folder} is missing (it comes with the repository)")
    names = []
    for p in sorted(folder.glob("*.txt")):
        if field_size is not None or densities is not None:
            density, size, _ = _name_parts(p.stem, p)
            if field_size is not None and size != field_size:
                continue
            if densities is not None and not (
                    densities[0] - 1e-9 <= density <= densities[1] + 1e-9):
                continue
        names.append(f"{split}/{p.stem}")
    return names


_NAME = re.compile(r"d(\d+(?:\.\d+)?)_f(\d+(?:\.\d+)?)_s(\d+)")


def _name_parts(stem: str, where: object) -> tuple[float, float, int]:
    """(density, field size (m), seed) of a shipped map's name ``d<density>_f<size>_s<seed>``;
    a :class:`MapError` naming ``where`` for another name (a bare ValueError before)."""
    match = _NAME.fullmatch(stem)
    if match is None:
        raise MapError(f"{where}: a shipped map's name must be d<density>_f<field size>_s<seed> "
                       f"(e.g. d0.10_f100_s000) to be filtered or split by them")
    return float(match[1]), float(match[2]), int(match[3])


def validation_split(names: list[str]) -> tuple[list[str], list[str]]:
    """(fit, validation): shipped map names split for model selection. The map with the
    highest seed of every (density, field size) group is held out for validation (1 in 5 of
    the shipped training maps), the others are for fitting; ``names`` as from
    :func:`list_maps`."""
    groups: dict[tuple[float, float], list[tuple[int, str]]] = {}
    for name in names:
        density, size, seed = _name_parts(name.rsplit("/", 1)[-1], name)
        groups.setdefault((density, size), []).append((seed, name))
    held = {max(group)[1] for group in groups.values() if len(group) > 1}
    return [n for n in names if n not in held], [n for n in names if n in held]


#: Maps read lately: (resolved path, modification time, size, field_size) -> map, newest last.
#: A map is immutable, so the environments and episodes that load one file share one object
#: and its cached geometry (union, convex parts, the detour planner's grid).
_LOADED: OrderedDict[tuple, ObstacleMap] = OrderedDict()
_LOADED_MAX = 8


def _read_cached(path: Path, field_size: float | tuple[float, float] | None) -> ObstacleMap:
    """:func:`read_map` of ``path``, from :data:`_LOADED` while the file is unchanged."""
    stat = path.stat()
    # checked before the key: True == 1 as a key, and a valid 1 m map was found for True
    size = None if field_size is None else _field_dims(field_size)
    key = (str(path.resolve()), stat.st_mtime_ns, stat.st_size, size)
    found = _LOADED.get(key)
    if found is None:
        found = _LOADED[key] = read_map(path, field_size)
        while len(_LOADED) > _LOADED_MAX:
            _LOADED.popitem(last=False)
    else:
        _LOADED.move_to_end(key)
    return found


def load_map(name_or_path: str | os.PathLike,
             field_size: float | tuple[float, float] | None = None) -> ObstacleMap:
    """A map from a file path, or a shipped map by name ("test/d0.30_f100_s500" or its stem)."""
    if not isinstance(name_or_path, (str, os.PathLike)):
        raise TypeError(f"name_or_path must be a shipped map's name or a map file's path, got "
                        f"{type(name_or_path).__name__}")
    path = Path(name_or_path)
    if path.is_file():
        return _read_cached(path, field_size)
    key = str(name_or_path).removesuffix(".txt")
    names = [n for split in SPLITS if (MAPS_DIR / split).is_dir() for n in list_maps(split)]
    matches = [n for n in names if key in (n, n.split("/", 1)[1])]
    if len(matches) == 1:
        return _read_cached(MAPS_DIR / f"{matches[0]}.txt", field_size)
    if matches:
        raise MapError(f"map name {key!r} is ambiguous: {', '.join(matches)}")
    by_stem = {n.split("/", 1)[1]: n for n in names}
    close = difflib.get_close_matches(key.rsplit("/", 1)[-1], list(by_stem), n=3, cutoff=0.5)
    examples = [by_stem[stem] for stem in close] or names[:3]
    raise MapError(f"unknown map {str(name_or_path)!r}: no such file and no shipped map of that "
                   f"name in {MAPS_DIR}; e.g. {', '.join(examples) or '(none shipped)'} "
                   f"(see list_maps('train'), list_maps('test'))")
