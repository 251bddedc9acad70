"""The field's classical static sweep paths, run with the common obstacle rule.

Each path is built over the obstacle-free ``width`` x ``height`` field by a pure function of the
geometry (``*_vertices``, metres in and out) and turned into waypoints by
:func:`~aoass_env.planning.path.polyline_path`; obstacles are left to the simulator's nominal
follower (blocked waypoints skipped, detours around static obstacles). The published geometries:

* SCAN, DOUBLE-SCAN, HILBERT -- Koutsonikolas, Das & Hu, Computer Communications 30(13), 2007;
* CIRCLES -- Huang & Zaruba, PerCom Workshops 2007;
* LMAT -- Han et al., Wireless Communications and Mobile Computing 13(14), 2013;
* Z-curve -- Rezazadeh et al., IEEE Sensors Journal 14(9), 2014.

Choices of this implementation (docs/planning.md, "Classical sweep paths"):

* Resolution: the square spiral's pass spacing ``d`` (:func:`config_spacing`), so the paths are
  compared at the same resolution; for SCAN, HILBERT and the Z-curve at most
  :func:`covering_cell` (below). A side of extent ``E`` is cut into ``n = ceil(E / d)`` equal
  cells of side ``E / n <= d``; passes (and cell centres) lie at the cell centres, the first one
  half a cell from the edge, clipped to the edge margin.
* HILBERT: order ``k``, the smallest with ``max(width, height) / 2**k <= d`` (``d`` as bounded
  above).
* CIRCLES: circles at the cell-centre radii of the shorter side (the outermost half a cell from
  the edge), inside out, joined by radial links along the +x axis, continued outwards (clipped
  to the margin-clipped field) while the corners need them (below); a last rectangular ring on
  the margin-clipped border covers the corners beyond the largest circle.
* LMAT: triangle side ``<= R`` (fitted so the lattice rows land on the clipped border), every
  second row of triangles swept in a zig-zag, rows in boustrophedon order.
* Z-curve: the cells in Morton order of their (column, row) indices; on a grid that is not a
  power of two the cells outside the grid are skipped, so some jumps are longer than a diagonal.

Coverage of the empty field (Eq. 18: a point must hear >= 3 non-collinear beacons within the
radio range ``R``; beacons every ``Δs`` along the path). The spiral runs its outermost pass on
the margin-clipped border and fits its spacing to that (Eq. 5); these paths keep theirs half a
cell inside, so a border point has a single straight pass (or the border ring) close by and
must reach a second line farther in. At the spiral's spacing alone that failed on fields from
about 110-115 m (SCAN, Z-curve) and 160-170 m (CIRCLES), depending on the sample
grid (R = 25 m, Δs = 2 m, 1.5 m margin). The rules, which leave the default 100 m paths
unchanged:

* SCAN, HILBERT and the Z-curve visit every cell centre, and every visited centre has a beacon
  within ``Δs`` of it. The farthest point of the field from its third-nearest non-collinear
  centres (two of the first row or column, one of the second, 3c/2 in) is a field corner or a
  border point midway between two columns, ``sqrt(max(c/2, margin)**2 + (3c/2)**2)`` away; so
  the cell side ``c`` is at most :func:`covering_cell`, where that distance is ``R - Δs``:
  ``c <= 2 (R - Δs) / sqrt(10)``, 14.55 m (the 100 m field's 14.29 m cells are unchanged; the 200 m
  field's 18.18 m cells put SCAN's second pass 27.3 m from the border, beyond ``R``, and left
  the Z-curve's corners with one line in reach, and get 14.29 m). HILBERT's cells halve with its
  order, so the rule raises the order by one where ``max(w, h) / 2**k`` at the spiral's spacing
  exceeds it, doubling the path: at 137 m (17.1 m cells, 11 sample points of the border and a
  5 m grid uncovered) and 250-300 m at R = 25 m (300 m: 18.75 m cells, 23 points), for
  example, and at 137, 150 and 300 m at R = 15 m, 200 m at R = 40 m; at the defaults on the
  100, 150 and 200 m fields (12.5, 9.4 and 12.5 m cells) it keeps its order.
* CIRCLES: a border point hears two beacons of the ring's perpendicular side only within
  ``x_L = margin + sqrt(R**2 - (margin + 2 Δs)**2)`` of a corner, and two beacons of a circle
  within ``a = sqrt(R**2 - Δs**2)`` of it. The circles continue outwards at the same spacing,
  each clipped to the margin-clipped field (the parts beyond it run along the border), until
  the largest reaches :func:`corner_radius`, ``max(hypot(w/2 - x_L, h/2), hypot(w/2, h/2 - x_L))
  - a``: every point farther than ``a`` from it then lies within ``x_L`` of both sides of a
  corner of the ring, and hears both. At 100 m the inscribed circles already reach it (42.86 m
  against 30.6 m); at 200 m one clipped circle of 109.1 m is added (the inscribed ones end at
  90.9 m, the corners need 99.6 m). Beyond about 195 m no inscribed circle could reach it at
  any spacing.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from aoass_env.config import AOASSConfig
from aoass_env.maps import ObstacleMap
from aoass_env.planning.path import WaypointPath, polyline_path
from aoass_env.planning.square_spiral import config_spacing, range_and_interval
from aoass_env.planning.sweep import PlannedMethod
from aoass_env.validators import integer, positive, real

__all__ = ["CLASSICAL_METHODS", "circles_vertices", "corner_radius", "covering_cell",
           "double_scan_vertices", "hilbert_cells", "hilbert_order", "hilbert_vertices",
           "lmat_vertices", "morton_cells", "scan_vertices", "z_curve_vertices"]


def _check_field(width: float, height: float, spacing: float, margin: float,
                 spacing_name: str = "spacing") -> None:
    """ValueError naming the first parameter out of its valid range."""
    for name, value in (("width", width), ("height", height), (spacing_name, spacing)):
        positive(name, value, "m")
    real("margin", margin, "m", low=0.0, high=min(width, height) / 2, high_open=True,
         doc=f"for a {width:g} x {height:g} m field")


#: most cells a cell-by-cell curve (HILBERT, the Z-curve) is built with: 4 194 304 cells,
#: 64 MiB of vertices; a spacing that asks for more is refused, not met by a MemoryError
MAX_CELLS = 1 << 22


def _check_cells(cells: int, spacing: float, width: float, height: float) -> None:
    """ValueError naming ``spacing`` when a curve of ``cells`` cells exceeds
    :data:`MAX_CELLS`."""
    if cells > MAX_CELLS:
        raise ValueError(f"spacing={spacing!r} m asks for {cells} cells on a {width:g} x "
                         f"{height:g} m field; at most {MAX_CELLS} are built (a larger spacing)")


def _n_cells(extent: float, spacing: float) -> int:
    """Number of equal cells of side <= ``spacing`` (m) across ``extent`` (m)."""
    return max(1, math.ceil(extent / spacing - 1e-9))


def _cell_centres(extent: float, n: int, margin: float) -> np.ndarray:
    """(n,) centres (m) of ``n`` equal cells across ``extent`` (m), clipped to the margin."""
    return np.clip((np.arange(n) + 0.5) * extent / n, margin, extent - margin)


def covering_cell(radio_range: float, beacon_interval: float, margin: float) -> float:
    """Largest cell side ``c`` (m) with which every point of an empty field lies within
    ``radio_range - beacon_interval`` (m) of three non-collinear cell centres (module docstring,
    "Coverage of the empty field"): ``sqrt(max(c/2, margin)**2 + (3c/2)**2) <= R - Δs``, i.e.
    ``c = 2 (R - Δs) / sqrt(10)`` while that keeps ``c/2 >= margin``, else
    ``sqrt((R - Δs)**2 - margin**2) / 1.5``; ``math.inf`` (no bound) when
    ``sqrt(2) margin >= R - Δs``: the corner's nearest centre, clipped to ``(margin, margin)``,
    is then out of reach whatever ``c`` (and a second row 3c/2 in would be clipped onto the
    first)."""
    r, ds = range_and_interval(radio_range, beacon_interval)
    m = real("margin", margin, "m", low=0.0)
    reach = r - ds
    if math.sqrt(2) * m >= reach:
        return math.inf      # the clipped corner centre is already out of reach: no c helps
    if math.sqrt(10) * m <= reach:
        return 2 * reach / math.sqrt(10)
    return math.sqrt(reach**2 - m**2) / 1.5


def _boustrophedon(offsets: np.ndarray, start: float, end: float) -> np.ndarray:
    """(2P, 2) (offset, along) ends of parallel passes at ``offsets`` (m), the first running
    from ``start`` to ``end`` (m) and each next one back."""
    even = np.arange(len(offsets)) % 2 == 0
    first = np.where(even, start, end)
    second = np.where(even, end, start)
    return np.stack([np.repeat(offsets, 2), np.stack([first, second], axis=1).ravel()], axis=1)


def scan_vertices(width: float, height: float, spacing: float, margin: float) -> np.ndarray:
    """(V, 2) corners (m) of SCAN: passes parallel to x at most ``spacing`` (m) apart, the first
    half a pass spacing above the bottom edge (at least ``margin``), swept in boustrophedon
    order upwards; each pass runs between the first and last cell centres in x."""
    _check_field(width, height, spacing, margin)
    xs = _cell_centres(width, _n_cells(width, spacing), margin)
    ys = np.unique(_cell_centres(height, _n_cells(height, spacing), margin))
    return _boustrophedon(ys, xs[0], xs[-1])[:, ::-1]


def double_scan_vertices(width: float, height: float, spacing: float,
                         margin: float) -> np.ndarray:
    """(V, 2) corners (m) of DOUBLE-SCAN: SCAN along x, then from its end point a SCAN along y
    (vertical passes swept back across the field), so that every point hears two crossing
    families of passes."""
    along_x = scan_vertices(width, height, spacing, margin)
    xs = np.unique(_cell_centres(width, _n_cells(width, spacing), margin))
    ys = _cell_centres(height, _n_cells(height, spacing), margin)
    end_x, end_y = along_x[-1]
    columns = xs if end_x == xs[0] else xs[::-1]
    along_y = _boustrophedon(columns, end_y, ys[0])
    return np.concatenate([along_x, along_y])


def hilbert_order(width: float, height: float, spacing: float) -> int:
    """Smallest order ``k`` with ``max(width, height) / 2**k <= spacing`` (all in m)."""
    _check_field(width, height, spacing, 0.0)
    return max(0, math.ceil(math.log2(max(width, height) / spacing) - 1e-9))


def hilbert_cells(order: int) -> np.ndarray:
    """(4**order, 2) integer (column, row) cells of the order-``order`` Hilbert curve on a
    2**order grid, from (0, 0) to (2**order - 1, 0), each a grid neighbour of the last.

    Built recursively: the curve of order k+1 is the order-k curve transposed (lower left),
    shifted up (upper left), shifted up and right (upper right) and anti-transposed (lower
    right), so each quarter ends next to where the next one starts.
    """
    if not (isinstance(order, int) and 0 <= order <= 15):
        raise ValueError(f"order={order!r} must be an integer in [0, 15]")
    cells = np.zeros((1, 2), dtype=np.int64)
    for level in range(order):
        s = 2**level
        x, y = cells[:, 0], cells[:, 1]
        cells = np.concatenate([
            np.stack([y, x], axis=1),
            np.stack([x, y + s], axis=1),
            np.stack([x + s, y + s], axis=1),
            np.stack([2 * s - 1 - y, s - 1 - x], axis=1),
        ])
    return cells


def hilbert_vertices(width: float, height: float, spacing: float, margin: float) -> np.ndarray:
    """(4**k, 2) cell centres (m) of HILBERT in curve order: the order-k Hilbert curve
    (:func:`hilbert_order`) over cells of ``width / 2**k`` x ``height / 2**k`` m, centres clipped
    to the margin."""
    _check_field(width, height, spacing, margin)
    k = hilbert_order(width, height, spacing)
    _check_cells(4**k, spacing, width, height)
    cells = hilbert_cells(k)
    xs = _cell_centres(width, 2**k, margin)
    ys = _cell_centres(height, 2**k, margin)
    return np.stack([xs[cells[:, 0]], ys[cells[:, 1]]], axis=1)


def corner_radius(width: float, height: float, margin: float, radio_range: float,
                  beacon_interval: float) -> float:
    """Radius (m) about the field centre that the largest circle of CIRCLES must reach so that,
    with the border ring, every point of the empty field hears three non-collinear beacons
    (module docstring, "Coverage of the empty field"): ``max(hypot(w/2 - x_L, h/2),
    hypot(w/2, h/2 - x_L)) - a`` with ``a = sqrt(R^2 - Δs^2)`` (a curve that close offers two
    beacons) and ``x_L = margin + sqrt(R^2 - (margin + 2 Δs)^2)`` (how far from a corner a
    border point hears two beacons on the ring's perpendicular side; 0 when none does)."""
    for name, value in (("width", width), ("height", height)):
        positive(name, value, "m")
    real("margin", margin, "m", low=0.0, high=min(width, height) / 2, high_open=True,
         doc=f"for a {width:g} x {height:g} m field")
    r, ds = range_and_interval(radio_range, beacon_interval)
    a = math.sqrt(r**2 - ds**2)
    side = r**2 - (margin + 2 * ds) ** 2
    x_l = margin + math.sqrt(side) if side >= 0 else 0.0
    hx, hy = width / 2, height / 2
    return max(math.hypot(hx - min(x_l, hx), hy), math.hypot(hx, hy - min(x_l, hy))) - a


def circles_vertices(width: float, height: float, spacing: float, margin: float,
                     max_chord_error: float = 0.1, *, radio_range: float | None = None,
                     beacon_interval: float | None = None) -> np.ndarray:
    """(V, 2) corners (m) of CIRCLES: concentric circles about the field centre at the cell
    centre radii of the shorter side (at most ``spacing`` apart, the outermost half a cell from
    the edge and inside the margin), inside out, each polygonised with chords that stray at most
    ``max_chord_error`` (m) from the circle, started and ended on the +x axis and joined by radial
    links; then a rectangular ring along the margin-clipped border, which covers the corners
    beyond the largest circle.

    Given ``radio_range`` and ``beacon_interval`` (m), the circles continue outwards at the same
    spacing, clipped to the margin-clipped field (their parts beyond it run along the border),
    until one reaches :func:`corner_radius` (or the clipped corners): the ring alone then covers
    what lies beyond (module docstring). Where the inscribed circles already reach it (the
    100 m field at the default config) nothing is added."""
    _check_field(width, height, spacing, margin)
    positive("max_chord_error", max_chord_error, "m")
    if (radio_range is None) != (beacon_interval is None):
        raise ValueError(f"radio_range={radio_range!r} and beacon_interval={beacon_interval!r}: "
                         f"give both or neither")
    cx, cy = width / 2, height / 2
    lo_x, lo_y, hi_x, hi_y = margin, margin, width - margin, height - margin
    short = min(width, height)
    n_short = _n_cells(short, spacing)
    centres = np.unique(_cell_centres(short, n_short, margin))
    radii = list(centres[centres >= short / 2 - 1e-9] - short / 2)
    if radio_range is not None:
        need = corner_radius(width, height, margin, radio_range, beacon_interval)
        ring = math.hypot(cx - margin, cy - margin)      # the circle through the clipped corners
        inscribed, cell = radii[-1], short / n_short
        k = 1
        while radii[-1] < need and inscribed + k * cell < ring:
            radii.append(inscribed + k * cell)
            k += 1
    pieces = []
    for r in radii:
        if r <= 1e-9:
            pieces.append(np.array([[cx, cy]]))
            continue
        # a chord over angle 2*pi/n strays r * (1 - cos(pi/n)) from the circle
        n = max(4, math.ceil(math.pi / math.acos(max(-1.0, 1 - max_chord_error / r)) + 1e-9))
        angle = np.linspace(0.0, 2 * math.pi, n + 1)
        pieces.append(np.stack([np.clip(cx + r * np.cos(angle), lo_x, hi_x),
                                np.clip(cy + r * np.sin(angle), lo_y, hi_y)], axis=1))
    pieces.append(np.array([[hi_x, cy], [hi_x, hi_y], [lo_x, hi_y], [lo_x, lo_y], [hi_x, lo_y],
                            [hi_x, cy]]))
    return np.concatenate(pieces)


def lmat_vertices(width: float, height: float, side: float, margin: float) -> np.ndarray:
    """(V, 2) corners (m) of LMAT: a tour of an equilateral-triangle lattice with side at most
    ``side`` (m) over the margin-clipped field.

    Lattice rows run parallel to x, ``J = ceil(H' / (side * sqrt(3) / 2))`` rows of triangles
    fitted to the clipped height ``H'`` (the first and last lattice lines on the clipped border),
    alternate lines offset by half a side. The anchor sweeps rows of triangles 0, 2, 4, ... (and
    the last row when the number of lattice lines is odd) in a zig-zag along the triangles'
    slanted edges, which visits every lattice vertex and so every triangle's three vertices;
    each zig-zag starts and ends with the row's border edge (the half triangles cut by the
    border; every step is then at most a side long), and rows alternate direction, each
    leaving on its upper line where the next one enters.
    """
    _check_field(width, height, side, margin, spacing_name="side")
    lo_x, hi_x = margin, width - margin
    clipped_h = height - 2 * margin
    rows = max(1, math.ceil(clipped_h / (side * math.sqrt(3) / 2) - 1e-9))
    row_h = clipped_h / rows
    a = 2 * row_h / math.sqrt(3)

    def line(j: int) -> np.ndarray:
        xs = np.arange(lo_x + (j % 2) * a / 2, hi_x + 1e-9, a)
        return np.stack([xs, np.full(len(xs), margin + j * row_h)], axis=1)

    starts = list(range(0, rows, 2)) + ([rows - 1] if rows % 2 == 0 else [])
    tour = []
    for i, j in enumerate(starts):
        y_lo, y_hi = margin + j * row_h, margin + (j + 1) * row_h
        zigzag = np.concatenate([line(j), line(j + 1)])
        zigzag = zigzag[np.argsort(zigzag[:, 0], kind="stable")]
        x_in, x_out = lo_x, hi_x
        if i % 2 == 1:
            zigzag, x_in, x_out = zigzag[::-1], hi_x, lo_x
        first_y, last_y = zigzag[0, 1], zigzag[-1, 1]
        # border edges: enter from the row below / leave towards the row above when there is
        # one, else enter on the line that does not reach the border first (no retracing)
        entry = ([y_lo, y_hi] if i > 0 else [y_hi if first_y == y_lo else y_lo, first_y])
        leave = ([y_lo, y_hi] if i < len(starts) - 1
                 else [last_y, y_hi if last_y == y_lo else y_lo])
        tour.append(np.concatenate([[[x_in, y] for y in entry], zigzag,
                                    [[x_out, y] for y in leave]]))
    return np.concatenate(tour)


def morton_cells(n_columns: int, n_rows: int) -> np.ndarray:
    """(n_columns * n_rows, 2) integer (column, row) cells in Morton (Z) order: sorted by the key
    whose even bits are the column's bits and odd bits the row's, so each 2 x 2 block is visited
    lower left, lower right, upper left (the diagonal jump), upper right."""
    n_columns = integer("n_columns", n_columns, "cells", low=1)
    n_rows = integer("n_rows", n_rows, "cells", low=1)
    col, row = (g.ravel() for g in np.meshgrid(np.arange(n_columns), np.arange(n_rows)))
    key = np.zeros(len(col), dtype=np.int64)
    for bit in range(max(n_columns, n_rows).bit_length()):
        key |= ((col >> bit) & 1) << (2 * bit) | ((row >> bit) & 1) << (2 * bit + 1)
    order = np.argsort(key)
    return np.stack([col[order], row[order]], axis=1)


def z_curve_vertices(width: float, height: float, spacing: float, margin: float) -> np.ndarray:
    """(C, 2) cell centres (m) of the Z-curve: cells of side at most ``spacing`` (m) visited in
    Morton order (:func:`morton_cells`), centres clipped to the margin."""
    _check_field(width, height, spacing, margin)
    nx, ny = _n_cells(width, spacing), _n_cells(height, spacing)
    _check_cells(nx * ny, spacing, width, height)
    cells = morton_cells(nx, ny)
    xs, ys = _cell_centres(width, nx, margin), _cell_centres(height, ny, margin)
    return np.stack([xs[cells[:, 0]], ys[cells[:, 1]]], axis=1)


def _at_spiral_spacing(vertices: Callable[[float, float, float, float], np.ndarray], *,
                       covering: bool = False) -> Callable[[ObstacleMap, AOASSConfig],
                                                           WaypointPath]:
    """A plan function that builds ``vertices(width, height, d, edge_margin)`` with ``d`` the
    square spiral's spacing on the map's field; with ``covering``, ``d`` at most
    :func:`covering_cell` for the config's radio range, beacon interval and edge margin."""
    def plan(obstacle_map: ObstacleMap, config: AOASSConfig) -> WaypointPath:
        w, h = obstacle_map.width, obstacle_map.height
        d = config_spacing(config, w, h)
        if covering:
            d = min(d, covering_cell(config.radio_range, config.beacon_interval,
                                     config.edge_margin))
        return polyline_path(vertices(w, h, d, config.edge_margin), config.path_step)
    return plan


def _plan_circles(obstacle_map: ObstacleMap, config: AOASSConfig) -> WaypointPath:
    """CIRCLES at the spiral's spacing, continued until the ring covers the corners."""
    w, h = obstacle_map.width, obstacle_map.height
    return polyline_path(circles_vertices(w, h, config_spacing(config, w, h), config.edge_margin,
                                          radio_range=config.radio_range,
                                          beacon_interval=config.beacon_interval),
                         config.path_step)


def _plan_lmat(obstacle_map: ObstacleMap, config: AOASSConfig) -> WaypointPath:
    """LMAT over the map's field with triangle side at most the radio range."""
    return polyline_path(lmat_vertices(obstacle_map.width, obstacle_map.height,
                                       config.radio_range, config.edge_margin), config.path_step)


_KOUTSONIKOLAS = "Koutsonikolas, Das & Hu, Computer Communications 30(13), 2007"

#: The classical paths by command-line name.
CLASSICAL_METHODS: dict[str, PlannedMethod] = {
    m.name: m for m in [
        PlannedMethod(name="scan", label="SCAN", source=_KOUTSONIKOLAS,
                      plan=_at_spiral_spacing(scan_vertices, covering=True)),
        PlannedMethod(name="double-scan", label="DOUBLE-SCAN", source=_KOUTSONIKOLAS,
                      plan=_at_spiral_spacing(double_scan_vertices)),
        PlannedMethod(name="hilbert", label="HILBERT", source=_KOUTSONIKOLAS,
                      plan=_at_spiral_spacing(hilbert_vertices, covering=True)),
        PlannedMethod(name="circles", label="CIRCLES",
                      source="Huang & Zaruba, PerCom Workshops 2007",
                      plan=_plan_circles),
        PlannedMethod(name="lmat", label="LMAT",
                      source="Han et al., Wireless Communications and Mobile Computing 13(14), "
                             "2013",
                      plan=_plan_lmat),
        PlannedMethod(name="z-curve", label="Z-curve",
                      source="Rezazadeh et al., IEEE Sensors Journal 14(9), 2014",
                      plan=_at_spiral_spacing(z_curve_vertices, covering=True)),
    ]
}
