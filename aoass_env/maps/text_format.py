"""The IMR-CIIRC planning-map text format: ``[SCALE]``, ``[BORDER]`` and ``[OBSTACLE]`` sections.

:func:`read_map` parses a file into an :class:`~aoass_env.maps.ObstacleMap` (malformed files
raise :class:`MapFormatError` naming the file and line); :func:`write_map` writes one back
exactly.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import numpy as np
import shapely

from aoass_env.atomic import write_text_atomic
from aoass_env.maps.obstacle_map import MapError, ObstacleMap, _field_dims


class MapFormatError(MapError):
    """A map file is malformed; ``path`` and the 1-based ``line`` say where."""

    def __init__(self, path: Path, line: int, message: str) -> None:
        super().__init__(f"{path}:{line}: {message}")
        self.path = path
        self.line = line
        self.message = message

    def __reduce__(self) -> tuple:  # picklable across processes despite the custom __init__
        return type(self), (self.path, self.line, self.message)


_SECTIONS = ("[SCALE]", "[BORDER]", "[OBSTACLE]")


_Rows = list[tuple[int, list[float]]]  # (line number, values) of one section


def _parse_sections(path: Path, lines: list[str]) -> list[tuple[str, int, _Rows]]:
    """[(section, header line number, rows), ...] of a map file, in file order."""
    sections: list[tuple[str, int, _Rows]] = []
    for number, raw in enumerate(lines, start=1):
        text = raw.strip()
        if not text:
            continue
        if text.startswith("["):
            if text not in _SECTIONS:
                raise MapFormatError(path, number, f"unknown section {text!r}; valid sections "
                                                   f"are {', '.join(_SECTIONS)}")
            if text != "[OBSTACLE]" and any(s[0] == text for s in sections):
                raise MapFormatError(path, number, f"second {text} section")
            sections.append((text, number, []))
            continue
        if not sections:
            raise MapFormatError(path, number, f"{text!r} before the first section "
                                               f"(the file must start with [SCALE])")
        kind, _, rows = sections[-1]
        values = []
        for token in text.split():
            # float() also reads Python's spellings ('1_5' is 15, Arabic-Indic digits, 'nan'):
            # a decimal number of ASCII digits only
            if not _NUMBER.fullmatch(token):
                raise MapFormatError(path, number, f"{token!r} is not a number (decimal "
                                                   f"digits, e.g. 12, -0.5, 1.5e3)")
            value = float(token)
            if not math.isfinite(value):
                raise MapFormatError(path, number, f"{token!r} is not a finite number")
            values.append(value)
        want = 1 if kind == "[SCALE]" else 2
        if len(values) != want:
            what = "one number" if want == 1 else "two numbers 'x y'"
            raise MapFormatError(path, number, f"expected {what} in {kind}, got {len(values)}")
        if kind == "[SCALE]" and rows:
            raise MapFormatError(path, number, "[SCALE] holds a single number")
        rows.append((number, values))
    return sections


#: A number of a map file: an optional sign, ASCII digits with an optional point, an optional
#: exponent.
_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")


def _polygon(path: Path, kind: str, line: int, rows: _Rows, scale: float) -> np.ndarray:
    """Validated (k, 2) vertices (m) of a [BORDER] or [OBSTACLE] section."""
    if len(rows) < 3:
        raise MapFormatError(path, line, f"{kind} has {len(rows)} vertices; a polygon needs >= 3")
    with np.errstate(over="ignore"):   # an overflow is reported below, in one line
        v = np.array([values for _, values in rows]) * scale
    if not np.isfinite(v).all():
        raise MapFormatError(path, line, f"{kind}'s coordinates times the scale overflow a float "
                                         f"(coordinates or scale too large)")
    poly = shapely.Polygon(v)
    if not poly.is_valid:
        raise MapFormatError(path, line, f"{kind} is not a simple polygon "
                                         f"({shapely.is_valid_reason(poly)})")
    if poly.area <= 0:
        raise MapFormatError(path, line, f"{kind} has zero area")
    if not math.isfinite(poly.area):     # clipping it to the field would drop it unseen
        what = "border" if kind == "[BORDER]" else "obstacle"
        raise MapFormatError(path, line, f"the {what}'s extent overflows a float (coordinates "
                                         f"too large)")
    return v


def read_map(path: str | os.PathLike, field_size: float | tuple[float, float] | None = None
             ) -> ObstacleMap:
    """Read an IMR-CIIRC map file (``[SCALE]``, ``[BORDER]``, ``[OBSTACLE]`` sections).

    Coordinates are scaled to metres (value x scale) and the border's bounding box is moved to
    the origin; it becomes the field. With ``field_size`` (m, side or (width, height)) the map
    is stretched per axis to that size. Parts of the bounding box outside a non-rectangular
    border become obstacles; obstacles are clipped to the field (one with no area inside it is
    an error: a typo or a wrong scale would drop it unseen). Malformed files raise
    :class:`MapFormatError` naming the file and line.
    """
    path = Path(path)
    try:   # utf-8-sig: a byte-order mark some editors write is not part of the text
        # lines end at \n, \r\n or \r only: str.splitlines also breaks at a form feed,
        # \x1c-\x1e, \x85 and U+2028/9, which read one line as two vertices and shifted the
        # line numbers of every error after it
        lines = re.split(r"\r\n|\r|\n", path.read_text(encoding="utf-8-sig"))
        if lines and lines[-1] == "":
            lines.pop()
    except UnicodeDecodeError as err:
        raise MapError(f"{path}: not a UTF-8 text map file ({err.reason})") from None
    except (IsADirectoryError, PermissionError) as err:
        raise MapError(f"{path}: not a readable map file ({err.strerror})") from None
    sections = _parse_sections(path, lines)
    end = max(len(lines), 1)
    found = {kind: (line, rows) for kind, line, rows in sections if kind != "[OBSTACLE]"}
    for kind in ("[SCALE]", "[BORDER]"):
        if kind not in found:
            raise MapFormatError(path, end, f"missing {kind} section")
    header_line, scale_rows = found["[SCALE]"]
    if not scale_rows:
        raise MapFormatError(path, header_line, "[SCALE] has no value")
    value_line, (scale,) = scale_rows[0]
    if scale <= 0:
        raise MapFormatError(path, value_line, f"scale {scale!r} must be positive")
    border = _polygon(path, "[BORDER]", *found["[BORDER]"], scale)
    obstacle_lines = [line for kind, line, _ in sections if kind == "[OBSTACLE]"]
    obstacles = [_polygon(path, kind, line, rows, scale)
                 for kind, line, rows in sections if kind == "[OBSTACLE]"]

    low = border.min(axis=0)
    with np.errstate(over="ignore"):
        span = border.max(axis=0) - low
    if not np.isfinite(span).all():
        raise MapFormatError(path, found["[BORDER]"][0],
                             "the border's extent overflows a float (coordinates too large)")
    if field_size is None:
        size = span
        border, obstacles = border - low, [v - low for v in obstacles]
    else:  # (v - low) / span is exactly 0 and 1 on the border's bounding box
        size = np.array(_field_dims(field_size))
        border = (border - low) / span * size
        obstacles = [(v - low) / span * size for v in obstacles]

    width, height = float(size[0]), float(size[1])
    field_box = shapely.box(0.0, 0.0, width, height)
    polygons = []
    for v, line in zip(obstacles, obstacle_lines, strict=True):
        if np.all(v >= 0) and np.all(v <= size):
            polygons.append(v)
            continue
        clipped = shapely.intersection(shapely.Polygon(v), field_box)
        inside = [shapely.get_coordinates(p.exterior)[:-1]
                  for p in shapely.get_parts(clipped) if p.area > 0]
        if not inside:
            raise MapFormatError(path, line, f"the obstacle lies outside the field (the border's "
                                             f"bounding box, {width:g} x {height:g} m after "
                                             f"scaling)")
        polygons += inside
    outside = shapely.difference(field_box, shapely.Polygon(border))
    polygons += [shapely.get_coordinates(p.exterior)[:-1]
                 for p in shapely.get_parts(outside) if p.area > 0]
    try:
        return ObstacleMap(width, height, tuple(polygons), path.stem)
    except MapError as err:     # e.g. a sliver that the stretch to field_size made degenerate
        raise MapError(f"{path}: {err}") from None


def write_map(obstacle_map: ObstacleMap, path: str | os.PathLike) -> None:
    """Write ``obstacle_map`` as an IMR-CIIRC text file (SCALE 1, metres), atomically.

    Floats are written exactly (``repr``), so ``read_map`` gives back the same polygons; a map
    with a polygon outside the field (an ``ObstacleMap`` may hold one, the world clips it) is
    refused with a :class:`MapError`, since ``read_map`` clips obstacles to the field.
    """
    w, h = obstacle_map.width, obstacle_map.height
    for i, p in enumerate(obstacle_map.polygons):
        if not (np.all(p >= 0.0) and np.all(p <= (w, h))):
            raise MapError(f"write_map: obstacle {i} of {obstacle_map.name or 'the map'} reaches "
                           f"outside the {w:g} x {h:g} m field; the file would read back "
                           f"clipped (clip it to the field first)")
    out = ["[SCALE]", "1", "", "[BORDER]", "0 0", f"{w!r} 0", f"{w!r} {h!r}", f"0 {h!r}"]
    for p in obstacle_map.polygons:
        out += ["", "[OBSTACLE]"]
        out += [f"{float(x)!r} {float(y)!r}" for x, y in p]
    write_text_atomic(Path(path), "\n".join(out) + "\n")
