"""Classical sweep paths: geometry, closed-form lengths, coverage of an empty field, episodes."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env.config import AOASSConfig
from aoass_env.maps import ObstacleMap
from aoass_env.network import Network
from aoass_env.planning.classical import (
    CLASSICAL_METHODS,
    MAX_CELLS,
    circles_vertices,
    corner_radius,
    covering_cell,
    double_scan_vertices,
    hilbert_cells,
    hilbert_order,
    hilbert_vertices,
    lmat_vertices,
    morton_cells,
    scan_vertices,
    z_curve_vertices,
)
from aoass_env.planning.path import polyline_path
from aoass_env.planning.square_spiral import config_spacing
from aoass_env.simulator import Simulator, episode_map
from aoass_env.trajectory import beacons_along

VERTICES = [scan_vertices, double_scan_vertices, hilbert_vertices, circles_vertices,
            lmat_vertices, z_curve_vertices]

L = 100.0
CONFIG = AOASSConfig()                      # R = 25 m, beacons every 2 m, edge margin 1.5 m
EMPTY = ObstacleMap(L, L)
D = config_spacing(CONFIG, L, L)            # the spiral's spacing, 16.17 m
N = math.ceil(L / D)                        # 7 passes / cells across
C = L / N                                   # fitted resolution, 14.29 m
M = CONFIG.edge_margin


def _length(vertices: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(vertices, axis=0), axis=1).sum())


def test_registry():
    assert list(CLASSICAL_METHODS) == ["scan", "double-scan", "hilbert", "circles", "lmat",
                                       "z-curve"]
    for name, m in CLASSICAL_METHODS.items():
        assert m.name == name and m.controller is None and not m.reconstructed
        assert m.label and m.source


@settings(max_examples=25, deadline=None)
@given(width=st.floats(10, 200), height=st.floats(10, 200), spacing=st.floats(2, 60),
       margin_frac=st.floats(0, 0.9), fn=st.sampled_from(VERTICES))
def test_every_path_stays_in_the_clipped_field(width, height, spacing, margin_frac, fn):
    margin = margin_frac * min(width, height) / 2
    v = fn(width, height, spacing, margin)
    assert v.ndim == 2 and v.shape[1] == 2 and np.all(np.isfinite(v))
    eps = 1e-9
    assert np.all(v >= margin - eps)
    assert np.all(v[:, 0] <= width - margin + eps) and np.all(v[:, 1] <= height - margin + eps)


@settings(max_examples=25, deadline=None)
@given(width=st.floats(10, 200), height=st.floats(10, 200), spacing=st.floats(2, 60))
def test_scan_passes_are_at_most_spacing_apart_and_half_a_pass_from_the_edge(width, height,
                                                                            spacing):
    v = scan_vertices(width, height, spacing, 0.0)
    ys = np.unique(v[:, 1])
    assert np.all(np.diff(ys) <= spacing + 1e-9)
    assert ys[0] <= spacing / 2 + 1e-9 and ys[0] == pytest.approx(height - ys[-1])
    # boustrophedon: passes along x alternate direction, joined by links along y
    steps = np.diff(v, axis=0)
    assert np.all((np.abs(steps[:, 0]) < 1e-9) | (np.abs(steps[:, 1]) < 1e-9))


def test_scan_and_double_scan_lengths():
    """Exact: N passes of length L - C plus N - 1 links of C. baselines.md's L²/d + L counts
    N + 1 passes from edge to edge; ours are inset half a cell, which is shorter by L + C, a
    relative C/L = 1/N (14 %)."""
    scan = scan_vertices(L, L, D, M)
    assert _length(scan) == pytest.approx(N * (L - C) + (N - 1) * C)
    assert _length(scan) == pytest.approx(L**2 / C + L, rel=1 / N + 1e-9)
    double = double_scan_vertices(L, L, D, M)
    assert _length(double) == pytest.approx(2 * _length(scan))
    assert _length(double) == pytest.approx(2 * (L**2 / C + L), rel=1 / N + 1e-9)
    # the second sweep runs along y and crosses every pass of the first
    second = double[len(scan):]
    assert np.all(np.abs(np.diff(second[::2, 0])) > 0)
    np.testing.assert_allclose(second[0], scan[-1])


def test_hilbert_order_and_length():
    k = hilbert_order(L, L, D)
    assert L / 2**k <= D < L / 2 ** (k - 1)
    cell = L / 2**k
    v = hilbert_vertices(L, L, D, M)
    # 4^k - 1 unit steps; baselines.md's L²/d within 1/4^k (1.6 %)
    assert _length(v) == pytest.approx((4**k - 1) * cell)
    assert _length(v) == pytest.approx(L**2 / cell, rel=2**-(2 * k) + 1e-9)


@pytest.mark.parametrize("order", range(7))
def test_hilbert_visits_each_cell_once_through_neighbours(order):
    cells = hilbert_cells(order)
    n = 2**order
    assert len({tuple(c) for c in cells}) == n * n == len(cells)
    assert cells.min() == 0 and cells.max() == n - 1
    assert np.all(np.abs(np.diff(cells, axis=0)).sum(axis=1) == 1)
    assert tuple(cells[0]) == (0, 0) and tuple(cells[-1]) == (n - 1, 0)


def test_circles_length_and_chord_error():
    """Circles at radii 0, C, 2C, 3C: 2πC(1 + 2 + 3) ≈ baselines.md's πL²/(4d) (within 1/N²);
    plus the radial links (L/2 - margin in all) and the border ring 4(L - 2 margin)."""
    v = circles_vertices(L, L, D, M)
    radii = C * np.arange((N + 1) // 2)
    circles = 2 * math.pi * radii.sum()
    assert circles == pytest.approx(math.pi * L**2 / (4 * C), rel=1 / N**2 + 1e-9)
    # polygonisation shortens each circle by about 2π/3 * chord error
    assert _length(v) == pytest.approx(circles + (L / 2 - M) + 4 * (L - 2 * M), abs=1.0)
    r = np.hypot(*(v - L / 2).T)
    on_circle = np.isclose(r[:, None], radii[None, 1:]).any(axis=1)
    pairs = on_circle[:-1] & on_circle[1:] & np.isclose(r[:-1], r[1:])
    half_chord = np.linalg.norm(np.diff(v, axis=0), axis=1)[pairs] / 2
    sagitta = r[:-1][pairs] - np.sqrt(r[:-1][pairs] ** 2 - half_chord**2)
    assert sagitta.max() < 0.1
    # the last ring runs along the clipped border through all four corners
    for corner in [(M, M), (L - M, M), (M, L - M), (L - M, L - M)]:
        assert np.any(np.all(np.isclose(v, corner), axis=1))


def test_lmat_side_vertices_and_length():
    side = CONFIG.radio_range
    v = lmat_vertices(L, L, side, M)
    ys = np.unique(v[:, 1])
    rows = len(ys) - 1
    row_h = (L - 2 * M) / rows
    a = 2 * row_h / math.sqrt(3)
    assert a <= side and rows == math.ceil((L - 2 * M) / (side * math.sqrt(3) / 2))
    # every lattice vertex is visited
    for j, y in enumerate(ys):
        for x in np.arange(M + (j % 2) * a / 2, L - M + 1e-9, a):
            assert np.any(np.all(np.isclose(v, (x, y)), axis=1)), (x, y)
    # every step is a triangle edge (or part of one cut by the border): at most a side long
    assert np.linalg.norm(np.diff(v, axis=0), axis=1).max() <= a + 1e-9
    # zig-zags cover 2 (L - 2 margin) each, plus border edges and links between them
    pairs = math.ceil(len(ys) / 2)
    estimate = pairs * (2 * (L - 2 * M) + 2 * row_h) + (pairs - 1) * row_h
    assert _length(v) == pytest.approx(estimate, rel=0.05)


def _morton_key(col: int, row: int) -> int:
    bits = max(col, row).bit_length()
    return int("".join(f"{row:0{bits}b}"[i] + f"{col:0{bits}b}"[i] for i in range(bits)) or "0",
               2)


@settings(max_examples=30, deadline=None)
@given(nx=st.integers(1, 20), ny=st.integers(1, 20))
def test_z_curve_order_is_morton_order(nx, ny):
    cells = morton_cells(nx, ny)
    assert len({tuple(c) for c in cells}) == nx * ny == len(cells)
    keys = [_morton_key(int(c), int(r)) for c, r in cells]
    assert keys == sorted(keys)


def test_z_curve_diagonal_jumps_and_length():
    """On a 2^k grid the Z-curve is four order-(k-1) curves joined by three jumps:
    Z_k = 4 Z_{k-1} + c (2 sqrt(1 + (s-1)²) + sqrt((2s-1)² + 1)), s = 2^(k-1)."""
    np.testing.assert_array_equal(morton_cells(2, 2), [[0, 0], [1, 0], [0, 1], [1, 1]])
    cell = 12.5
    v = z_curve_vertices(L, L, cell, M)
    expected = 0.0
    for k in range(1, 4):
        s = 2 ** (k - 1)
        expected = 4 * expected + cell * (2 * math.hypot(1, s - 1) + math.hypot(2 * s - 1, 1))
    assert len(v) == 64 and _length(v) == pytest.approx(expected)


def _beacons(method: str, obstacle_map: ObstacleMap = EMPTY,
             config: AOASSConfig = CONFIG) -> np.ndarray:
    """(B, 2) beacon points (m) every ``config.beacon_interval`` along the method's ideal path on
    the map (default the empty 100 m field; the first at the start, as the simulator
    broadcasts)."""
    path = CLASSICAL_METHODS[method].plan(obstacle_map, config)
    samples = np.c_[path.arc_length, path.waypoints]
    beacons, _ = beacons_along(samples, 0.0, config.beacon_interval)
    return np.r_[samples[:1], beacons][:, 1:]


def _hears_three_non_collinear(points: np.ndarray, beacons: np.ndarray, r: float) -> np.ndarray:
    """(P,) True where a point hears >= 3 beacons within ``r`` that do not lie on one line (the
    smaller principal variance of the heard beacons exceeds 1e-3 m²)."""
    d = beacons[None] - points[:, None]
    heard = (np.hypot(d[..., 0], d[..., 1]) <= r).astype(float)
    n = heard.sum(axis=1)
    mean = np.einsum("pb,pbi->pi", heard, d) / np.maximum(n, 1)[:, None]
    cov = np.einsum("pb,pbi,pbj->pij", heard, d, d) / np.maximum(n, 1)[:, None, None]
    cov -= mean[:, :, None] * mean[:, None, :]
    return (n >= 3) & (np.linalg.eigvalsh(cov)[:, 0] > 1e-3)


@pytest.mark.parametrize("method", ["scan", "double-scan", "hilbert", "circles", "lmat",
                                    "z-curve"])
def test_every_point_of_the_empty_field_hears_three_non_collinear_beacons(method):
    beacons = _beacons(method)
    corners = np.array([[0, 0], [L, 0], [0, L], [L, L]])
    assert _hears_three_non_collinear(corners, beacons, CONFIG.radio_range).all()
    g = np.linspace(0, L, 51)
    grid = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
    ok = _hears_three_non_collinear(grid, beacons, CONFIG.radio_range)
    assert ok.all(), grid[~ok][:5]


def _eq18_covered(method: str, size: float, config: AOASSConfig) -> np.ndarray:
    """(P,) the Network's Eq.-18 verdict (>= 3 beacons within R, root-sum-square distance from
    their best line >= collinearity_tol) for sample points of the empty ``size`` m field -- every
    metre along its four edges, where the uncovered strips lay, and a 5 m grid -- once every
    beacon of the method's ideal path has been heard."""
    edge = np.arange(0.0, size + 1e-9, 1.0)
    inner = np.arange(0.0, size + 1e-9, 5.0)
    points = np.unique(np.concatenate([
        np.c_[edge, np.zeros_like(edge)], np.c_[edge, np.full_like(edge, size)],
        np.c_[np.zeros_like(edge), edge], np.c_[np.full_like(edge, size), edge],
        np.stack(np.meshgrid(inner, inner), axis=-1).reshape(-1, 2)]), axis=0)
    net = Network(len(points), config)
    r2 = config.radio_range**2
    for b in _beacons(method, ObstacleMap(size, size), config):
        d = points - b
        net.record_beacon(b, np.flatnonzero(d[:, 0] ** 2 + d[:, 1] ** 2 <= r2))
    return net.covered


@pytest.mark.parametrize("method", ["scan", "hilbert", "circles", "z-curve"])
@pytest.mark.parametrize(("size", "radio_range"), [
    (60, 25), (100, 25), (137, 25), (150, 25), (200, 25), (250, 25), (300, 25), (100, 15),
    (137, 15), (150, 15), (200, 40), (300, 40)])
def test_the_whole_empty_field_of_any_size_is_eq18_covered(method, size, radio_range):
    """Like the spiral, the paths cover the empty field of any size. At the spiral's spacing
    alone, SCAN, CIRCLES and the Z-curve left border strips or corners hearing a single line
    on fields from about 110 m (200 m, R = 25 m: 2.5 %, 1.6 % and 23 points of a 1 m grid;
    docs/planning.md, "Classical sweep paths"), and HILBERT at 137 m (11 of these sample
    points), 300 m (23) and at 150 m for R = 15 m (1)."""
    config = AOASSConfig(field_size=size, radio_range=radio_range)
    covered = _eq18_covered(method, float(size), config)
    assert covered.all(), f"{(~covered).sum()} of {len(covered)} sample points uncovered"


def test_covering_cell_closed_form():
    """Largest c with sqrt(max(c/2, margin)^2 + (3c/2)^2) = R - beacon interval."""
    assert covering_cell(25.0, 2.0, 1.5) == pytest.approx(46 / math.sqrt(10))   # 14.546 m
    assert covering_cell(25.0, 2.0, 1.5) > C                # the 100 m field's 14.29 m cells
    # a margin wider than half the cell: the first centre sits on the margin
    c = covering_cell(25.0, 2.0, 10.0)
    assert c < 20.0 and math.hypot(10.0, 1.5 * c) == pytest.approx(23.0)
    assert covering_cell(25.0, 2.0, 23.0) == math.inf     # no centre reaches a field corner
    # the corner's own centre, clipped to (18, 18), is 25.5 m > 23 m away: no c helps (a bound
    # here once shrank the cells: SCAN at edge_margin 22.99 m ran 6 644 m instead of 1 675 m)
    assert covering_cell(25.0, 2.0, 18.0) == math.inf
    assert covering_cell(25.0, 2.0, 23.0 / math.sqrt(2) - 1e-9) < math.inf
    with pytest.raises(ValueError, match="beacon_interval"):
        covering_cell(2.0, 2.0, 0.0)


@settings(max_examples=50, deadline=None)
@given(radio_range=st.floats(3, 100), interval_frac=st.floats(0.01, 0.9),
       margin_frac=st.floats(0, 0.99))
def test_covering_cell_puts_the_third_centre_at_reach(radio_range, interval_frac, margin_frac):
    interval = interval_frac * radio_range
    reach = radio_range - interval
    margin = margin_frac * reach
    c = covering_cell(radio_range, interval, margin)
    if math.sqrt(2) * margin >= reach:
        assert c == math.inf
        return
    assert math.hypot(max(c / 2, margin), 1.5 * c) == pytest.approx(reach)
    assert 1.5 * c >= margin * (1 - 1e-12)      # the second row is not clipped onto the first


def test_circles_continue_clipped_until_the_corner_radius():
    """200 m field, default config: 11 cells of c = 18.18 m, inscribed circles up to 5c =
    90.9 m; the corners need 99.55 m (corner_radius), so one circle of 6c = 109.1 m is added,
    its parts beyond the clipped field on the border."""
    size = 200.0
    config = AOASSConfig(field_size=size)
    d = config_spacing(config, size, size)
    c = size / math.ceil(size / d)
    need = corner_radius(size, size, M, config.radio_range, config.beacon_interval)
    a = math.sqrt(25**2 - 2**2)
    x_l = M + math.sqrt(25**2 - (M + 4) ** 2)
    assert need == pytest.approx(math.hypot(size / 2 - x_l, size / 2) - a)
    assert 5 * c < need <= 6 * c
    v = circles_vertices(size, size, d, M, radio_range=config.radio_range,
                         beacon_interval=config.beacon_interval)
    assert np.all(v >= M) and np.all(v <= size - M)
    r = np.hypot(*(v - size / 2).T)
    clipped = np.any((v == M) | (v == size - M), axis=1)
    assert r[~clipped].max() == pytest.approx(6 * c)       # the corner arcs of the new circle
    assert clipped.sum() > 6          # the ring's 6 corners, and the new circle's border parts
    # without the radio parameters: the inscribed circles and the ring only
    plain = circles_vertices(size, size, d, M)
    assert np.hypot(*(plain - size / 2).T)[
        ~np.any((plain == M) | (plain == size - M), axis=1)].max() == pytest.approx(5 * c)


@settings(max_examples=25, deadline=None)
@given(width=st.floats(10, 300), height=st.floats(10, 300), spacing=st.floats(2, 60),
       margin_frac=st.floats(0, 0.9), radio_range=st.floats(5, 60),
       interval_frac=st.floats(0.01, 0.9))
def test_continued_circles_stay_in_the_clipped_field_and_reach_the_corner_radius(
        width, height, spacing, margin_frac, radio_range, interval_frac):
    margin = margin_frac * min(width, height) / 2
    interval = interval_frac * radio_range
    v = circles_vertices(width, height, spacing, margin, radio_range=radio_range,
                         beacon_interval=interval)
    eps = 1e-9
    assert np.all(v >= margin - eps)
    assert np.all(v[:, 0] <= width - margin + eps) and np.all(v[:, 1] <= height - margin + eps)
    # the circles: the inscribed ones (cell-centre radii of the shorter side), then r_in + k c
    # for k = 1, 2, ... until one reaches corner_radius or the next would pass the clipped
    # corners (the circle of the ring); each circle of radius > 0 starts and ends on the +x
    # axis, as does the ring
    short = min(width, height)
    n = math.ceil(short / spacing - 1e-9)
    cell = short / n
    centres = np.unique(np.clip((np.arange(n) + 0.5) * cell, margin, short - margin))
    r_in = centres[centres >= short / 2 - 1e-9] - short / 2
    need = corner_radius(width, height, margin, radio_range, interval)
    ring = math.hypot(width / 2 - margin, height / 2 - margin)
    extra = 0
    while r_in[-1] + extra * cell < need and r_in[-1] + (extra + 1) * cell < ring:
        extra += 1
    on_axis = np.isclose(v[:, 1], height / 2, rtol=0, atol=1e-9) & (v[:, 0] > width / 2 + 1e-9)
    assert on_axis.sum() == 2 * (np.count_nonzero(r_in > 1e-9) + extra) + 2


def test_the_default_100_m_paths_are_unchanged():
    """At the default 100 m config the coverage rules add nothing: SCAN and the Z-curve keep
    the spiral-spacing cells (N = 7: covering_cell's 14.55 m >= C = 14.29 m), HILBERT its
    order 3 (12.5 m cells) and CIRCLES its inscribed circles (the largest, 42.86 m, beyond
    corner_radius's 30.6 m): the waypoints are those of the pure geometry at the spiral's
    spacing, as before the rules. HILBERT keeps its order on fig3's 200 m field too."""
    assert corner_radius(L, L, M, CONFIG.radio_range, CONFIG.beacon_interval) < 3 * C
    for method, fn, n_waypoints, length in [
            ("scan", scan_vertices, 350, N * (L - C) + (N - 1) * C),       # 685.71 m
            ("hilbert", hilbert_vertices, 442, 787.5),
            ("circles", circles_vertices, 531, 974.4426280458059),
            ("z-curve", z_curve_vertices, 535, 992.7286125557047)]:
        path = CLASSICAL_METHODS[method].plan(EMPTY, CONFIG)
        np.testing.assert_array_equal(
            path.waypoints, polyline_path(fn(L, L, D, M), CONFIG.path_step).waypoints)
        assert len(path.waypoints) == n_waypoints
        assert path.arc_length[-1] == pytest.approx(length, rel=1e-12)
    config = AOASSConfig(field_size=200.0)
    path = CLASSICAL_METHODS["hilbert"].plan(ObstacleMap(200.0, 200.0), config)
    np.testing.assert_array_equal(path.waypoints, polyline_path(hilbert_vertices(
        200.0, 200.0, config_spacing(config, 200.0, 200.0), M), config.path_step).waypoints)
    assert path.arc_length[-1] == pytest.approx(255 * 12.5)          # order 4


@pytest.mark.parametrize("method", list(CLASSICAL_METHODS))
def test_every_method_runs_an_episode(method):
    config = AOASSConfig(field_size=40, n_nodes=30, obstacle_density=0.1, n_moving_obstacles=0)
    obstacle_map = episode_map(config, np.random.default_rng(0))
    path = CLASSICAL_METHODS[method].plan(obstacle_map, config)
    assert np.linalg.norm(np.diff(path.waypoints, axis=0), axis=1).max() <= (
        config.beacon_interval + 1e-9)
    sim = Simulator(config, np.random.default_rng(0), obstacle_map=obstacle_map, path=path)
    log = sim.run()
    coverage = sim.network.coverage_ratio
    assert math.isfinite(coverage) and 0.0 <= coverage <= 1.0
    assert log.n_beacons > 1 and sim.network.distance_travelled > 0


@pytest.mark.parametrize("fn", VERTICES)
@pytest.mark.parametrize(("args", "name"), [
    ((100, 100, 0.0, 1.0), "spacing|side"),
    ((100, 100, -5.0, 1.0), "spacing|side"),
    ((100, 100, math.nan, 1.0), "spacing|side"),
    ((100, 100, 10.0, 50.0), "margin"),
    ((100, 60, 10.0, 31.0), "margin"),
    ((100, 100, 10.0, -1.0), "margin"),
    ((0, 100, 10.0, 1.0), "width"),
    ((100, -1, 10.0, 1.0), "height"),
])
def test_bad_parameters_raise_naming_the_parameter(fn, args, name):
    with pytest.raises(ValueError, match=name):
        fn(*args)


def test_bad_grid_parameters():
    with pytest.raises(ValueError, match="order"):
        hilbert_cells(-1)
    with pytest.raises(ValueError, match="n_rows"):
        morton_cells(3, 0)
    with pytest.raises(ValueError, match="max_chord_error"):
        circles_vertices(100, 100, 10, 1, max_chord_error=0)
    with pytest.raises(ValueError, match="give both or neither"):
        circles_vertices(100, 100, 10, 1, radio_range=25.0)
    with pytest.raises(ValueError, match="beacon_interval"):
        corner_radius(100, 100, 1, 25.0, 25.0)
    with pytest.raises(ValueError, match="margin"):
        corner_radius(100, 100, 50, 25.0, 2.0)


@pytest.mark.parametrize("fn", [hilbert_vertices, z_curve_vertices])
def test_a_spacing_asking_for_too_many_cells_is_refused_not_a_memory_error(fn):
    """A tiny spacing used to allocate tens of GiB (HILBERT: 4**15 cells) and die in a
    MemoryError; the limit is MAX_CELLS, and a grid at the limit is still built."""
    with pytest.raises(ValueError, match=r"spacing=0.001 m asks for \d+ cells on a 100 x 100 m "
                                         r"field; at most 4194304"):
        fn(100, 100, 0.001, 0.0)
    side = 2**11 * 0.5                         # 2048 x 2048 = 4**11 = MAX_CELLS cells of 0.5 m
    assert len(fn(side, side, 0.5, 0.0)) == MAX_CELLS
