"""Tests of aoass_env.maps: ObstacleMap geometry, the generator, room checks and map files."""

from __future__ import annotations

import os
import pickle
import re
from pathlib import Path

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env import maps
from aoass_env.maps import (
    DENSITY_TOL,
    MapError,
    MapFormatError,
    ObstacleMap,
    generate_map,
    list_maps,
    load_map,
    read_map,
    write_map,
)

CLEARANCE = 2.5  # generate_map's default (the config's map_clearance)


def rng(seed: int = 0) -> np.random.Generator:
    return np.random.default_rng(seed)


def box(x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float64)


def assert_same_polygons(a: ObstacleMap, b: ObstacleMap) -> None:
    assert (a.width, a.height) == (b.width, b.height)
    assert len(a.polygons) == len(b.polygons)
    for p, q in zip(a.polygons, b.polygons, strict=True):
        np.testing.assert_array_equal(p, q)


# =========================================================================================
# generate_map
# =========================================================================================
@pytest.fixture(scope="module")
def dense_map() -> ObstacleMap:
    return generate_map(100, 0.6, rng(11))


GENERATED = [(size, density, seed)
             for size in (100, 200)
             for density, seeds in ((0.0, 1), (0.15, 6), (0.35, 4), (0.6, 2))
             for seed in range(seeds)]


@pytest.mark.parametrize(("size", "density", "seed"), GENERATED)
def test_generated_map_hits_density_and_stays_traversable(size, density, seed):
    m = generate_map(size, density, rng(seed), name="g")
    assert (m.width, m.height, m.name) == (size, size, "g")
    assert abs(m.density - density) <= DENSITY_TOL
    # Oracle: shapely directly, not the generator's incremental bookkeeping.
    free = m.free_space
    assert free.geom_type == "Polygon"
    assert shapely.buffer(free, -CLEARANCE / 2).geom_type == "Polygon"
    m.check_traversable(CLEARANCE)
    # Obstacles are the disjoint parts of the union, inside the field, without holes.
    assert sum(s.area for s in m.shapes) == pytest.approx(m.union.area, rel=1e-12)
    if m.polygons:
        assert np.concatenate(m.polygons).min() >= 0.0
        assert np.concatenate(m.polygons).max() <= size


def test_empty_density_gives_empty_map():
    m = generate_map((30, 20), 0.0, rng())
    assert m.polygons == () and m.density == 0.0 and (m.width, m.height) == (30, 20)


def test_rectangular_field_and_other_clearance():
    m = generate_map(np.array([150, 80]), 0.3, rng(4), clearance=3.0)
    assert (m.width, m.height) == (150, 80)
    assert abs(m.density - 0.3) <= DENSITY_TOL
    m.check_traversable(3.0)


def test_same_seed_same_map_and_different_seed_different_map():
    a, b = generate_map(100, 0.3, rng(5)), generate_map(100, 0.3, rng(5))
    assert_same_polygons(a, b)
    c = generate_map(100, 0.3, rng(6))
    assert not np.array_equal(np.concatenate(a.polygons), np.concatenate(c.polygons))


def test_shapes_merge_into_concave_obstacles(dense_map):
    shapes = dense_map.shapes
    concave = [s for s in shapes if s.area < 0.999 * shapely.convex_hull(s).area]
    assert len(concave) >= len(shapes) // 2
    assert max(len(p) for p in dense_map.polygons) > 12  # merged from several shapes


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"density": -0.1}, "density=-0.1"),
    ({"density": 0.61}, r"density=0\.61 must be in \[0, 0\.6\]"),
    ({"density": float("nan")}, "density=nan"),
    ({"density": "0.3"}, "density='0.3'"),
    ({"density": True}, "density=True"),
    ({"field_size": 0}, "field_size=0"),
    ({"field_size": -5.0}, "field_size=-5.0"),
    ({"field_size": (100,)}, r"field_size=\(100,\)"),
    ({"field_size": (100, 0)}, r"field_size=\(100, 0\)"),
    ({"field_size": "big"}, "field_size"),
    ({"clearance": 0.0}, "clearance=0.0"),
    ({"clearance": -1.0}, "clearance=-1.0"),
    ({"clearance": 50.0}, r"clearance=50.0 must be in \(0, 50\)"),
    ({"clearance": float("inf")}, "clearance=inf"),
])
def test_bad_generator_arguments_name_the_parameter(kwargs, match):
    args = {"field_size": 100, "density": 0.3, "clearance": 1.5, **kwargs}
    with pytest.raises(MapError, match=match):
        generate_map(args["field_size"], args["density"], rng(), clearance=args["clearance"])


def test_generator_needs_a_numpy_generator():
    with pytest.raises(TypeError, match="rng must be a numpy.random.Generator"):
        generate_map(100, 0.3, 42)


def test_unreachable_density_is_a_clear_error():
    with pytest.raises(MapError, match=r"cannot reach density=0\.6 .* clearance=9\.9 m"):
        generate_map(20, 0.6, rng(), clearance=9.9)


# --- the incremental topology test against shapely ----------------------------------------
def free_regions(shapes: list) -> int:
    """Number of connected open regions of the 10 x 10 field minus the shapes (oracle)."""
    free = shapely.difference(shapely.box(0, 0, 10, 10), shapely.union_all(shapes))
    return len(shapely.get_parts(free))


cells = st.tuples(st.integers(0, 9), st.integers(0, 9), st.integers(1, 4), st.integers(1, 4))


@settings(max_examples=40, deadline=None)
@given(st.lists(cells, min_size=1, max_size=25))
def test_blocked_set_flags_exactly_the_shapes_that_cut_off_free_space(rects):
    """Integer rectangles touch each other and the border along edges and at corners."""
    field_box = shapely.box(0, 0, 10, 10)
    blocked = maps._BlockedSet(shapely.difference(shapely.box(-1, -1, 11, 11), field_box))
    accepted: list = []
    for x, y, w, h in rects:
        shape = shapely.intersection(shapely.box(x, y, x + w, y + h), field_box)
        members, pieces = blocked.contacts(shape)
        cuts = blocked.encloses(members, pieces)
        assert cuts == (free_regions([*accepted, shape]) != 1)
        if not cuts:
            blocked.add(shape, members)
            accepted.append(shape)


# =========================================================================================
# check_traversable, sample_free_points, inside_obstacle, convex_parts
# =========================================================================================
def test_empty_map_is_traversable():
    ObstacleMap(20, 20).check_traversable(CLEARANCE)


def test_enclosed_pocket_is_rejected():
    ring = [box(4, 4, 16, 5), box(4, 15, 16, 16), box(4, 5, 5, 15), box(15, 5, 16, 15)]
    with pytest.raises(MapError, match=r"enclose part of the free space; 2 separate regions"):
        ObstacleMap(20, 20, ring, "ring").check_traversable(0.0)


def test_wall_across_the_field_disconnects_it():
    with pytest.raises(MapError, match="enclose"):
        ObstacleMap(20, 20, [box(0, 9, 20, 10)]).check_traversable(CLEARANCE)


@pytest.mark.parametrize("wall", [
    [box(0, 9, 9, 10), box(10, 9, 20, 10)],  # 1 m door between two obstacles
    [box(1, 9, 20, 10)],                      # 1 m gap between an obstacle and the border
])
def test_narrow_passage_depends_on_clearance(wall):
    m = ObstacleMap(20, 20, wall, "door")
    m.check_traversable(0.0)
    m.check_traversable(0.9)
    with pytest.raises(MapError, match=r"map 'door': passages narrower than clearance=1\.5 m"):
        m.check_traversable(1.5)


def test_no_room_errors():
    with pytest.raises(MapError, match="no free space"):
        ObstacleMap(10, 10, [box(0, 0, 10, 10)]).check_traversable(0.0)
    with pytest.raises(MapError, match="cannot move"):
        ObstacleMap(10, 10).check_traversable(12.0)
    with pytest.raises(MapError, match="clearance=-1"):
        ObstacleMap(10, 10).check_traversable(-1)


@pytest.mark.parametrize("clearance", [0.0, 1.0, 2.5])
def test_sampled_points_lie_in_free_space_with_clearance(dense_map, clearance):
    pts = dense_map.sample_free_points(400, rng(1), clearance=clearance)
    assert pts.shape == (400, 2) and pts.dtype == np.float64
    assert np.all(dense_map.bounds_contain(pts, margin=clearance))
    if clearance == 0:
        assert not shapely.contains_xy(dense_map.union, pts[:, 0], pts[:, 1]).any()
    else:
        assert shapely.distance(dense_map.union, shapely.points(pts)).min() >= clearance
    np.testing.assert_array_equal(pts, dense_map.sample_free_points(400, rng(1), clearance))


def test_sampling_is_uniform_over_free_space():
    m = ObstacleMap(100, 100, [box(0, 0, 50, 100)])
    pts = m.sample_free_points(4000, rng(2))
    assert pts[:, 0].min() >= 50
    # Uniform on [50, 100] x [0, 100]: each quarter holds 1000 +- 5 sigma (sigma ~ 27).
    quarters = np.histogram2d(pts[:, 0], pts[:, 1], bins=2, range=[[50, 100], [0, 100]])[0]
    assert np.all(np.abs(quarters - 1000) < 140)


def test_sampling_errors():
    m = ObstacleMap(10, 10)
    assert m.sample_free_points(0, rng()).shape == (0, 2)
    for n in (-1, 2.5, True):
        with pytest.raises(MapError, match=f"n={n!r}"):
            m.sample_free_points(n, rng())
    with pytest.raises(MapError, match="clearance=5 m leaves no room"):
        m.sample_free_points(3, rng(), clearance=5)
    with pytest.raises(TypeError, match="rng"):
        m.sample_free_points(3, None)
    full = ObstacleMap(10, 10, [box(0, 0, 10, 10)], "full")
    with pytest.raises(MapError, match="cannot place 5 points in map 'full'"):
        full.sample_free_points(5, rng())
    walled = ObstacleMap(10, 10, [box(0, 0, 10, 4.5), box(0, 5.5, 10, 10)])
    with pytest.raises(MapError, match="free area too small"):
        walled.sample_free_points(5, rng(), clearance=1.0)


def test_inside_obstacle_uses_exact_distance():
    m = ObstacleMap(10, 10, [box(2, 2, 4, 4)])
    pts = np.array([[3, 3], [4.99, 3], [5.01, 3], [4 + 0.7, 4 + 0.7], [1, 1]])
    np.testing.assert_array_equal(m.inside_obstacle(pts), [True, False, False, False, False])
    # corner point (4.7, 4.7) is 0.99 m from the corner (4, 4)
    np.testing.assert_array_equal(m.inside_obstacle(pts, 1.0), [True, True, False, True, False])


def test_convex_parts_reproduce_each_obstacle_exactly(dense_map):
    u_shape = np.array([[0, 0], [6, 0], [6, 5], [4, 5], [4, 2], [2, 2], [2, 5], [0, 5]])
    for m in (dense_map, ObstacleMap(10, 10, [u_shape])):
        parts = [shapely.Polygon(p) for p in m.convex_parts]
        for p in parts:
            assert p.is_valid and p.equals(shapely.convex_hull(p))
            assert p.exterior.is_ccw
        assert sum(p.area for p in parts) == pytest.approx(sum(s.area for s in m.shapes),
                                                           rel=1e-12)
        assert shapely.symmetric_difference(shapely.union_all(parts), m.union).area < 1e-9


# =========================================================================================
# Map files
# =========================================================================================
IMR_SAMPLE = """\
[SCALE]
0.01

[BORDER]
100 200
2100 200
2100 1200
100 1200

[OBSTACLE]
600 400
600 700\t
900 700
900 400

[OBSTACLE]\r
1100 300
1500 300
1300 600
"""


def write(tmp_path: Path, text: str, name: str = "m.txt") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8", newline="")
    return path


def test_read_applies_scale_and_moves_the_border_to_the_origin(tmp_path):
    m = read_map(write(tmp_path, IMR_SAMPLE, "sample.txt"))
    assert (m.width, m.height, m.name) == (20.0, 10.0, "sample")
    square, triangle = m.polygons
    np.testing.assert_allclose(square, [[8, 2], [8, 5], [5, 5], [5, 2]], rtol=0, atol=1e-12)
    np.testing.assert_allclose(triangle, [[10, 1], [14, 1], [12, 4]], rtol=0, atol=1e-12)
    assert m.density == pytest.approx((9 + 6) / 200)


def test_read_rescales_each_axis(tmp_path):
    path = write(tmp_path, IMR_SAMPLE)
    m = read_map(path, field_size=100)
    assert (m.width, m.height) == (100.0, 100.0)
    np.testing.assert_allclose(m.polygons[0], [[40, 20], [40, 50], [25, 50], [25, 20]], rtol=0,
                               atol=1e-12)
    m = read_map(path, field_size=(40, 30))
    assert (m.width, m.height) == (40.0, 30.0)
    np.testing.assert_allclose(m.polygons[1], [[20, 3], [28, 3], [24, 12]], rtol=0, atol=1e-12)
    assert m.density == pytest.approx((9 + 6) / 200)
    with pytest.raises(MapError, match="field_size=-1"):
        read_map(path, field_size=-1)


def test_read_clips_obstacles_and_blocks_outside_a_non_rectangular_border(tmp_path):
    text = """[SCALE]\n1\n[BORDER]\n0 0\n10 0\n10 5\n5 5\n5 10\n0 10
[OBSTACLE]\n-2 -2\n2 -2\n2 2\n-2 2
[OBSTACLE]\n20 20\n21 20\n21 21
"""
    m = read_map(write(tmp_path, text))
    assert (m.width, m.height) == (10.0, 10.0)
    assert len(m.polygons) == 2  # the clipped corner square and the outside quarter
    assert m.density == pytest.approx((4 + 25) / 100)
    assert np.concatenate(m.polygons).min() >= 0 and np.concatenate(m.polygons).max() <= 10


def test_write_read_round_trip_is_exact(tmp_path, dense_map):
    path = tmp_path / "dense.txt"
    write_map(dense_map, path)
    back = read_map(path)
    assert_same_polygons(back, dense_map)
    assert back.name == "dense"
    assert os.listdir(tmp_path) == ["dense.txt"]


coord = st.floats(0.0, 1.0, allow_nan=False, exclude_min=True, exclude_max=True)


@settings(max_examples=30, deadline=None)
@given(st.floats(1e-3, 1e4), st.floats(1e-3, 1e4),
       st.lists(st.tuples(coord, coord, coord, coord, coord, coord), max_size=6))
def test_round_trip_is_exact_for_arbitrary_floats(tmp_path_factory, width, height, triangles):
    polygons = []
    for t in triangles:
        v = np.array(t).reshape(3, 2) * (width, height)
        if shapely.Polygon(v).is_valid and shapely.Polygon(v).area > 1e-6 * width * height:
            polygons.append(v)
    m = ObstacleMap(width, height, polygons)
    path = tmp_path_factory.mktemp("rt") / "m.txt"
    write_map(m, path)
    assert_same_polygons(read_map(path), m)


def test_write_is_atomic(tmp_path, monkeypatch):
    path = tmp_path / "m.txt"
    write_map(ObstacleMap(5, 5, [box(1, 1, 2, 2)]), path)
    before = path.read_text()

    def fail(*args):
        raise OSError("disk full")

    monkeypatch.setattr(maps.os, "replace", fail)
    with pytest.raises(OSError, match="disk full"):
        write_map(ObstacleMap(5, 5), path)
    assert path.read_text() == before
    assert os.listdir(tmp_path) == ["m.txt"]


def test_write_creates_a_missing_folder(tmp_path):
    write_map(ObstacleMap(5, 5), tmp_path / "new" / "m.txt")
    assert read_map(tmp_path / "new" / "m.txt").width == 5.0


GOOD_HEAD = "[SCALE]\n1\n[BORDER]\n0 0\n10 0\n10 10\n0 10\n"
MALFORMED = [
    ("[SCALE]\n1\n[BORDERS]\n", 3, r"unknown section '\[BORDERS\]'"),
    (GOOD_HEAD + "[OBSTACLE]\n1 1\n2 x\n", 10, "'x' is not a number"),
    (GOOD_HEAD + "[OBSTACLE]\n1 1 1\n", 9, r"expected two numbers 'x y' in \[OBSTACLE\], got 3"),
    (GOOD_HEAD + "[OBSTACLE]\n1\n", 9, "got 1"),
    (GOOD_HEAD + "[OBSTACLE]\n1 nan\n", 9, "'nan' is not a finite number"),
    ("[SCALE]\n1 2\n", 2, r"expected one number in \[SCALE\], got 2"),
    ("[SCALE]\n1\n2\n", 3, "single number"),
    ("[SCALE]\n[BORDER]\n0 0\n1 0\n1 1\n", 1, r"\[SCALE\] has no value"),
    ("[SCALE]\n0\n[BORDER]\n0 0\n1 0\n1 1\n", 2, "scale 0.0 must be positive"),
    ("[SCALE]\n-2\n[BORDER]\n0 0\n1 0\n1 1\n", 2, "scale -2.0 must be positive"),
    ("[BORDER]\n0 0\n1 0\n1 1\n", 4, r"missing \[SCALE\] section"),
    ("[SCALE]\n1\n\n", 3, r"missing \[BORDER\] section"),
    ("", 1, r"missing \[SCALE\] section"),
    ("0 0\n[SCALE]\n1\n", 1, "before the first section"),
    (GOOD_HEAD + "[BORDER]\n0 0\n", 8, r"second \[BORDER\] section"),
    (GOOD_HEAD + "\n[OBSTACLE]\n1 1\n2 2\n", 9, r"\[OBSTACLE\] has 2 vertices"),
    (GOOD_HEAD + "[OBSTACLE]\n1 1\n3 3\n3 1\n1 3\n", 8, "not a simple polygon .*Self-inters"),
    (GOOD_HEAD + "[OBSTACLE]\n1 1\n2 2\n3 3\n", 8, "not a simple polygon|zero area"),
    ("[SCALE]\n1\n[BORDER]\n0 0\n1 0\n", 3, r"\[BORDER\] has 2 vertices"),
]


@pytest.mark.parametrize(("text", "line", "message"), MALFORMED)
def test_malformed_files_name_file_and_line(tmp_path, text, line, message):
    path = write(tmp_path, text, "bad.txt")
    with pytest.raises(MapFormatError) as info:
        read_map(path)
    assert info.value.line == line and info.value.path == path
    assert str(info.value).startswith(f"{path}:{line}: ")
    assert re.search(message, str(info.value))


def test_format_error_survives_pickling(tmp_path):
    path = write(tmp_path, "[SCALE]\nx\n")
    with pytest.raises(MapFormatError) as info:
        read_map(path)
    copy = pickle.loads(pickle.dumps(info.value))
    assert (str(copy), copy.path, copy.line) == (str(info.value), path, 2)


def test_binary_file_is_a_clear_error(tmp_path):
    path = tmp_path / "m.txt"
    path.write_bytes(b"\xff\xfe\x00[SCALE]")
    with pytest.raises(MapError, match="not a UTF-8 text map file"):
        read_map(path)


# =========================================================================================
# Shipped maps
# =========================================================================================
NAME = re.compile(r"(train|test)/d(\d\.\d\d)_f(\d+)_s(\d{3})")


def test_shipped_map_lists():
    train, test = list_maps("train"), list_maps("test")
    assert len(train) == 60 and len(test) == 36
    seeds = {split: {int(NAME.fullmatch(n).group(4)) for n in names}
             for split, names in (("train", train), ("test", test))}
    assert not seeds["train"] & seeds["test"]
    groups = {NAME.fullmatch(n).group(2, 3) for n in train + test}
    assert groups == {(f"{d:.2f}", s) for d in (0.1, 0.2, 0.3, 0.4, 0.5, 0.6)
                      for s in ("100", "200")}
    with pytest.raises(MapError, match="split='validation'"):
        list_maps("validation")


def test_every_shipped_map_matches_its_name_and_is_traversable():
    for name in list_maps("train") + list_maps("test"):
        _, density, size, _ = NAME.fullmatch(name).groups()
        m = load_map(name)
        assert (m.width, m.height) == (float(size), float(size)), name
        assert abs(m.density - float(density)) <= DENSITY_TOL, name
        m.check_traversable(CLEARANCE)


def test_a_shipped_map_is_reproduced_from_its_name():
    name = list_maps("test")[0]
    _, density, size, seed = NAME.fullmatch(name).groups()
    stem = name.split("/")[1]
    fresh = generate_map(int(size), float(density), rng(int(seed)), name=stem)
    assert_same_polygons(load_map(name), fresh)


def test_load_map_accepts_names_stems_and_paths(tmp_path):
    name = list_maps("train")[3]
    stem = name.split("/")[1]
    reference = load_map(name)
    for alias in (stem, f"{stem}.txt", f"{name}.txt", maps.MAPS_DIR / f"{name}.txt"):
        assert_same_polygons(load_map(alias), reference)
    scaled = load_map(stem, field_size=50)
    assert scaled.width == 50.0 and scaled.density == pytest.approx(reference.density)
    path = write(tmp_path, IMR_SAMPLE)
    assert_same_polygons(load_map(str(path)), read_map(path))


def test_unknown_map_name_lists_valid_names():
    shipped = r"(train|test)/d\d\.\d\d_f\d+_s\d{3}"
    with pytest.raises(MapError, match=rf"unknown map 'd0.30_f100_s999'.*e\.g\. {shipped}, "):
        load_map("d0.30_f100_s999")
    with pytest.raises(MapError, match=rf"unknown map 'nothing-like-it'.*e\.g\. {shipped}, "):
        load_map("nothing-like-it")


_LINE = st.one_of(
    st.sampled_from(["[SCALE]", "[BORDER]", "[OBSTACLE]", "[OBSTACLES]", "", "1", "0.5",
                     "-1", "0 0", "10 0", "10 10", "0 10", "3 3", "nan 1", "1 2 3", "x y"]),
    st.tuples(st.integers(-5, 15), st.integers(-5, 15)).map(lambda p: f"{p[0]} {p[1]}"),
    st.text(alphabet="[]ABCELORST 0123456789.-e\t", max_size=12))


@settings(max_examples=150, deadline=None)
@given(st.lists(_LINE, max_size=30))
def test_reader_fuzz_gives_a_map_or_a_map_format_error(tmp_path_factory, lines):
    """Whatever the text, read_map returns a valid map or raises MapFormatError with a line."""
    path = tmp_path_factory.mktemp("fuzz") / "m.txt"
    path.write_text("\n".join(lines) + "\n")
    try:
        m = read_map(path)
    except MapFormatError as err:
        assert str(path) in str(err)
        return
    assert m.width > 0 and m.height > 0
    assert 0.0 <= m.density <= 1.0


def test_validation_split_holds_out_the_highest_seed_of_each_group():
    from aoass_env.maps import validation_split
    train = list_maps("train")
    fit, held = validation_split(train)
    assert sorted(fit + held) == sorted(train) and not set(fit) & set(held)
    groups = {NAME.fullmatch(n).group(2, 3) for n in train}
    assert len(held) == len(groups) == 12
    for name in held:
        _, d, f, seed = NAME.fullmatch(name).groups()
        same = [int(NAME.fullmatch(n).group(4)) for n in train
                if NAME.fullmatch(n).group(2, 3) == (d, f)]
        assert int(seed) == max(same)
    # a group of one map stays for fitting; the split does not depend on the order
    lone = ["train/d0.10_f100_s000", "train/d0.20_f100_s007", "train/d0.20_f100_s005"]
    assert validation_split(lone) == (["train/d0.10_f100_s000", "train/d0.20_f100_s005"],
                                      ["train/d0.20_f100_s007"])
