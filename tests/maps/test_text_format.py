"""Tests of aoass_env.maps.text_format: reading, writing and malformed IMR-CIIRC map files."""

from __future__ import annotations

import os
import pickle
import re
import warnings

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env.maps import MapError, MapFormatError, ObstacleMap, read_map, write_map
from tests.maps.conftest import IMR_SAMPLE, assert_same_polygons, box, write


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
"""
    m = read_map(write(tmp_path, text))
    assert (m.width, m.height) == (10.0, 10.0)
    assert len(m.polygons) == 2  # the clipped corner square and the outside quarter
    assert m.density == pytest.approx((4 + 25) / 100)
    assert np.concatenate(m.polygons).min() >= 0 and np.concatenate(m.polygons).max() <= 10
    # an obstacle wholly outside the field was dropped without a word (a typo, a wrong scale)
    with pytest.raises(MapFormatError, match=r"outside\.txt:15: the obstacle lies outside the "
                                             r"field \(the border's bounding box, 10 x 10 m"):
        read_map(write(tmp_path, text + "[OBSTACLE]\n20 20\n21 20\n21 21\n", "outside.txt"))


@pytest.mark.parametrize("token", ["1_5", "\u0661", "nan", "inf", "0x10", "1e", ".", "+-1"])
def test_a_number_in_pythons_spelling_only_is_refused(tmp_path, token):
    """float() read '1_5' as 15 and Arabic-Indic digits as digits: an obstacle's vertex moved
    without a word (and was clipped to the field). A map number is ASCII decimal."""
    text = GOOD_HEAD + f"[OBSTACLE]\n1 1\n2 1\n{token} 2\n"
    with pytest.raises(MapFormatError, match=rf":11: {re.escape(repr(token))} is not a number "
                                             rf"\(decimal digits"):
        read_map(write(tmp_path, text))


def test_a_polygon_the_stretch_degenerates_is_one_line_naming_the_file(tmp_path):
    """A sliver valid at the file's own size collapses when stretched to field_size: the error
    printed the vertex array over several lines, without the file."""
    text = ("[SCALE]\n1\n[BORDER]\n0 0\n10 0\n10 10\n0 10\n[OBSTACLE]\n1 1\n"
            "1.0000000000000002 1\n1 1.0000000000000002\n")
    path = write(tmp_path, text, "sliver.txt")
    with pytest.raises(MapError) as err:
        read_map(path, field_size=3)
    message = str(err.value)
    assert "\n" not in message and message.startswith(f"{path}: obstacle 0: a polygon needs "
                                                       f">= 3 distinct finite vertices")


def test_a_map_that_would_not_read_back_the_same_is_not_written(tmp_path):
    """An ObstacleMap may hold a polygon outside its field; written, it read back clipped (or
    gone, wholly outside) although write_map promises the same polygons (helper-46)."""
    for polygon in ([(8, 8), (12, 8), (12, 12), (8, 12)], [(20, 20), (22, 20), (22, 22)]):
        m = ObstacleMap(10.0, 10.0, (np.array(polygon, float),), "outside")
        with pytest.raises(MapError, match=r"write_map: obstacle 0 of outside reaches outside "
                                           r"the 10 x 10 m field"):
            write_map(m, tmp_path / "outside.txt")
        assert not (tmp_path / "outside.txt").exists()


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

    monkeypatch.setattr(os, "replace", fail)
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
    (GOOD_HEAD + "[OBSTACLE]\n1 nan\n", 9, "'nan' is not a number"),
    (GOOD_HEAD + "[OBSTACLE]\n1 1e5000\n", 9, "'1e5000' is not a finite number"),
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
    # a line ends at \n, \r\n or \r only: a form feed or U+2028 read one line as two vertices,
    # and shifted the line numbers of the errors after it
    (GOOD_HEAD + "[OBSTACLE]\n1 1\f2 1\n2 2\n", 9, r"in \[OBSTACLE\], got 4"),
    (GOOD_HEAD + "[OBSTACLE]\n1 1\u20282 1\n2 2\n", 9, r"in \[OBSTACLE\], got 4"),
    (GOOD_HEAD + "\f\n[OBSTACLE]\n1 1\nx 2\n", 11, "'x' is not a number"),
    ("[SCALE]\r1\r[BORDER]\r0 0\r1 0\r", 3, r"\[BORDER\] has 2 vertices"),
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


def test_a_byte_order_mark_is_not_part_of_the_text(tmp_path):
    """A UTF-8 byte-order mark (some editors write one) used to make "[SCALE]" unreadable."""
    plain = read_map(write(tmp_path, IMR_SAMPLE, "plain.txt"))
    path = tmp_path / "bom.txt"
    path.write_bytes(b"\xef\xbb\xbf" + IMR_SAMPLE.encode())
    assert_same_polygons(read_map(path), plain)


def test_a_folder_is_a_clear_error(tmp_path):
    """A folder used to escape as IsADirectoryError."""
    with pytest.raises(MapError, match=rf"^{re.escape(str(tmp_path))}: not a readable map file "
                                       r"\(Is a directory\)$"):
        read_map(tmp_path)


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


def test_a_border_whose_extent_overflows_is_named_with_its_line(tmp_path):
    # the width overflowed to inf and the error named neither the file nor the line
    path = tmp_path / "huge.txt"
    path.write_text("[SCALE]\n1\n[BORDER]\n-1e308 0\n1e308 0\n1e308 1\n-1e308 1\n")
    with pytest.raises(MapFormatError, match=r"huge.txt:3: the border's extent overflows"):
        read_map(path)


def test_an_obstacle_whose_extent_overflows_is_named_with_its_line(tmp_path):
    # its area was inf, and clipping it to the field dropped it: a map with one obstacle fewer
    path = tmp_path / "huge.txt"
    path.write_text("[SCALE]\n1\n[BORDER]\n0 0\n100 0\n100 100\n0 100\n"
                    "[OBSTACLE]\n-1e308 10\n1e308 10\n1e308 20\n-1e308 20\n")
    with pytest.raises(MapFormatError, match=r"huge.txt:8: the obstacle's extent overflows"):
        read_map(path)


@pytest.mark.parametrize(("scale", "vertex", "line"), [("1e308", "100 0", 3), ("10", "1e308 0", 3),
                                                     ("1e300", "1e10 0", 3)])
def test_coordinates_that_overflow_with_the_scale_are_one_error_without_warnings(
        tmp_path, scale, vertex, line):
    # numpy warned "overflow encountered in multiply" and shapely then called the border "not
    # a simple polygon (Invalid Coordinate[inf 0])"
    path = tmp_path / "huge.txt"
    path.write_text(f"[SCALE]\n{scale}\n[BORDER]\n0 0\n{vertex}\n100 100\n0 100\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(MapFormatError, match=rf"huge.txt:{line}: \[BORDER\]'s coordinates "
                                                 r"times the scale overflow a float"):
            read_map(path)


def test_a_stretched_non_rectangular_border_blocks_the_stretched_outside(tmp_path):
    """The L-shaped border of the clipping test, stretched to 20 x 40 m: the missing corner
    [5, 10] x [5, 10] becomes the obstacle [10, 20] x [20, 40] (area 200 m^2, a quarter)."""
    text = "[SCALE]\n1\n[BORDER]\n0 0\n10 0\n10 5\n5 5\n5 10\n0 10\n"
    m = read_map(write(tmp_path, text), field_size=(20, 40))
    assert (m.width, m.height) == (20.0, 40.0)
    (outside,) = m.polygons
    assert shapely.Polygon(outside).equals(shapely.box(10.0, 20.0, 20.0, 40.0))
    assert m.density == pytest.approx(0.25)


def test_an_obstacle_past_the_far_edges_is_clipped_and_small_pieces_are_kept(tmp_path):
    """An obstacle reaching past the right edge with a vertex inside is clipped to the field
    (2 x 2 m left); one reaching past the top leaves a 0.5 x 0.5 m piece; a 0.5 x 0.5 m
    notch cut out of the border's corner is an obstacle too (areas under 1 m^2 count)."""
    text = ("[SCALE]\n1\n[BORDER]\n0 0\n10 0\n10 9.5\n9.5 9.5\n9.5 10\n0 10\n"
            "[OBSTACLE]\n8 2\n12 2\n12 4\n8 4\n"
            "[OBSTACLE]\n2 9.5\n2.5 9.5\n2.5 12\n2 12\n")
    m = read_map(write(tmp_path, text))
    assert (m.width, m.height) == (10.0, 10.0)
    shapes = sorted((shapely.Polygon(p) for p in m.polygons), key=lambda p: p.bounds)
    assert [p.bounds for p in shapes] == [(2.0, 9.5, 2.5, 10.0), (8.0, 2.0, 10.0, 4.0),
                                          (9.5, 9.5, 10.0, 10.0)]
    assert [p.area for p in shapes] == pytest.approx([0.25, 4.0, 0.25])


def test_a_written_map_file_ends_with_a_newline(tmp_path):
    path = tmp_path / "m.txt"
    write_map(ObstacleMap(10.0, 10.0, [box(1, 1, 2, 2)]), path)
    text = path.read_text(encoding="utf-8")
    assert text.endswith("\n") and not text.endswith("\n\n")
