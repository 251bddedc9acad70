"""Tests of aoass_env.maps.generator: density, traversability, determinism, the blocked set."""

from __future__ import annotations

import hashlib
from collections import OrderedDict

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env.maps import DENSITY_TOL, MapError, generate_map
from aoass_env.maps import generator as generator_module
from aoass_env.maps.generator import _SHAPE_CDF, _SHAPE_P, _BlockedSet, _Room, _room_left
from tests.maps.conftest import CLEARANCE, assert_same_polygons, rng

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


# sha256 of every polygon's little-endian float64 vertex bytes, and the generator's next draw:
# recorded before maps.py was split into a package; a refactor must keep them (the same random
# draws in the same order). Shapely/GEOS versions other than the project's may round the
# union differently.
PINNED = [
    ((100.0, 0.3, 123), 32, "2e4bb59e462ef561bd4308a16d3f977d8a1ad65e779a8bfffe0a2706d1f41c95",
     2916744217965580420),
    ((100.0, 0.6, 7), 22, "2170cf5fa882092c87ebbc88908a51edf7d26475a6c12ae7351469ede11211eb",
     2869186627131305152),
    (((80.0, 50.0), 0.2, 1), 46,
     "40f46d234fef9f69477c1a1d46556377d39f1d824ae09ab5dc6dce83240638bf", 8770192532678057744),
    # issue 20 (recorded with the generator of 086f580, before its speed-ups): the reset's
    # case, and a map whose room is summed four times (the lazy room's slow path)
    ((100.0, 0.4, 11), 31, "1f7c1fab1dcb0cf1afbf648a82a2842ac6a17c687695ac27575075c84c4a92d1",
     2971468913879839602),
    (((60.0, 120.0), 0.6, 2), 34,
     "3340a0f53ef6d8b618017fa3d2b8eaa1a5fa1f7d349d35e084defdced9d0c9b2", 4970061382958719394),
]


@pytest.mark.parametrize(("args", "count", "digest", "next_draw"), PINNED)
def test_generated_maps_are_pinned_bit_for_bit(args, count, digest, next_draw, monkeypatch):
    monkeypatch.setattr(generator_module, "_GENERATED", OrderedDict())   # really generate
    field_size, density, seed = args
    generator = rng(seed)
    m = generate_map(field_size, density, generator)
    sha = hashlib.sha256()
    for p in m.polygons:
        sha.update(np.ascontiguousarray(p, dtype="<f8").tobytes())
        sha.update(b"|")
    assert len(m.polygons) == count
    assert sha.hexdigest() == digest, f"shapely {shapely.__version__}, GEOS {shapely.geos_version}"
    assert generator.integers(0, 2**63) == next_draw


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
    ({"density": 0.61}, r"density=0\.61 must be a number in \[0\.0, 0\.6\]"),
    ({"density": float("nan")}, "density=nan"),
    ({"density": "0.3"}, "density='0.3'"),
    ({"density": True}, "density=True"),
    ({"field_size": 0}, "field_size=0"),
    ({"field_size": -5.0}, "field_size=-5.0"),
    ({"field_size": (100,)}, r"field_size=\(100,\)"),
    ({"field_size": (100, 0)}, r"field_size=0 must be a number in \(0\.0, inf\) m"),
    ({"field_size": "big"}, "field_size"),
    ({"clearance": 0.0}, "clearance=0.0"),
    ({"clearance": -1.0}, "clearance=-1.0"),
    ({"clearance": 50.0}, r"clearance=50.0 must be a number in \(0\.0, 50\.0\) m"),
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
    blocked = _BlockedSet(shapely.difference(shapely.box(-1, -1, 11, 11), field_box))
    accepted: list = []
    for x, y, w, h in rects:
        shape = shapely.intersection(shapely.box(x, y, x + w, y + h), field_box)
        members, pieces = blocked.contacts(shape)
        cuts = blocked.encloses(members, pieces)
        assert cuts == (free_regions([*accepted, shape]) != 1)
        if not cuts:
            blocked.add(shape, members)
            accepted.append(shape)



@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(1, 9), st.lists(cells, max_size=4), st.booleans()),
                min_size=1, max_size=30),
       st.floats(0.0, 300.0))
def test_lazy_room_answers_as_the_eager_sum(terms, minimum):
    """_Room.fits answers what chaining _room_left over the accepted terms answers (issue 20:
    the room is summed only when its lower bound cannot decide), near the minimum too. Each
    term is a grown square and its overlaps with a few rectangles, as in the generator."""
    lazy = _Room(300.0, minimum, 1e-6 * 100.0)
    eager = 300.0
    for side, rects, accept in terms:
        grown = shapely.box(0, 0, side, side)
        pieces = shapely.intersection(
            np.array([shapely.box(x, y, x + w, y + h) for x, y, w, h in rects], dtype=object),
            grown)
        pieces = pieces[~shapely.is_empty(pieces)]
        room_left = _room_left(eager, grown.area, pieces)
        assert lazy.fits(grown.area, pieces) == (room_left >= minimum)
        if accept:
            lazy.take(grown.area, pieces)
            eager = room_left

# =========================================================================================
# check_traversable, sample_free_points, inside_obstacle, convex_parts
# =========================================================================================


def test_shape_kind_lookup_draws_what_rng_choice_draws():
    """_unit_shape's cumulative-table lookup picks the shape rng.choice(p=...) would, from the
    same stream (generated maps stay the same)."""
    for seed in range(20):
        a, b = np.random.default_rng(seed), np.random.default_rng(seed)
        for _ in range(200):
            assert int(a.choice(len(_SHAPE_P), p=_SHAPE_P)) == \
                int(_SHAPE_CDF.searchsorted(b.random(), side="right"))
        assert a.random() == b.random()



def test_scalar_centre_draws_are_the_pair_draw():
    """The generator draws a centre's x and y with two scalar rng.uniform calls: the same
    numbers, from the same stream, as one rng.uniform((0, 0), (width, height)) (issue 20)."""
    for seed in range(20):
        a, b = np.random.default_rng(seed), np.random.default_rng(seed)
        for width, height in ((100.0, 100.0), (60.0, 120.0), (7.3, 1e3)):
            x, y = a.uniform((0.0, 0.0), (width, height))
            assert (x, y) == (b.uniform(0.0, width), b.uniform(0.0, height))
        assert a.random() == b.random()

def test_a_draw_from_the_same_generator_state_is_reused(monkeypatch):
    """A generator in a state that drew a map before gets that map (the same object) and ends
    in the state the draw would leave it in (issue 20: resets with a repeated seed)."""
    monkeypatch.setattr(generator_module, "_GENERATED", OrderedDict())
    first = rng(11)
    a = generate_map(100, 0.3, first)
    after = first.integers(0, 2**63, size=4)
    again = rng(11)
    assert generate_map(100, 0.3, again) is a
    np.testing.assert_array_equal(again.integers(0, 2**63, size=4), after)
    # another request from the same state is another draw
    b = generate_map(100, 0.3, rng(11), clearance=3.0)
    assert b is not a
    generator_module.clear_cache()      # forgotten: the same state draws the map anew
    assert generate_map(100, 0.3, rng(11)) is not a
    generator_module.clear_cache()
    fresh = rng(11)
    assert_same_polygons(generate_map(100, 0.3, fresh), a)
    np.testing.assert_array_equal(fresh.integers(0, 2**63, size=4), after)
    # a bounded cache
    for seed in range(generator_module._GENERATED_MAX + 2):
        generate_map(40, 0.1, rng(seed))
    assert len(generator_module._GENERATED) == generator_module._GENERATED_MAX
