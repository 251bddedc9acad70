import dataclasses
import math
import pickle

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env.config import AOASSConfig, ConfigError


def test_defaults_follow_table1():
    c = AOASSConfig()
    assert c.radio_range == 25.0
    assert c.beacon_interval == 2.0
    assert c.node_initial_energy == 2.0
    assert c.e_elec == 50e-9
    assert c.anchor_motion_energy == 0.8
    assert c.field_size == 100.0 and c.n_nodes == 100


@pytest.mark.parametrize("key,value,fragment", [
    ("field_size", -5, "field_size=-5"),
    ("field_size", float("nan"), "field_size"),
    ("obstacle_density", 0.7, "[0.0, 0.6]"),
    ("n_nodes", 0, "n_nodes=0"),
    ("n_nodes", 2.5, "integer"),
    ("radio_range", 0.0, "(0.0, 1000.0]"),
    ("radio_range", "25", "must be a number"),
    ("line_of_sight", 1, "True or False"),
    ("moving_obstacle_speed", (1.0,), "pair"),
    ("spiral_spacing", -1.0, "spiral_spacing"),
])
def test_bad_values_name_parameter_and_range(key, value, fragment):
    with pytest.raises(ConfigError) as err:
        AOASSConfig.from_kwargs(**{key: value})
    assert key in str(err.value)
    assert fragment in str(err.value)


def test_unknown_keyword_suggests_close_match():
    with pytest.raises(ConfigError, match="did you mean 'radio_range'"):
        AOASSConfig.from_kwargs(radio_rang=20)
    # the constructor itself used to raise the dataclass's bare TypeError
    with pytest.raises(ConfigError, match="unknown config keyword 'radio_rang'; did you mean "
                                          "'radio_range'"):
        AOASSConfig(radio_rang=20)
    config = AOASSConfig(radio_range=20)        # copies still go through the constructor
    assert pickle.loads(pickle.dumps(config)) == config
    assert dataclasses.replace(config, n_nodes=5).n_nodes == 5


def test_cross_field_checks():
    with pytest.raises(ConfigError, match="anchor_nominal_speed"):
        AOASSConfig(anchor_nominal_speed=3.0, anchor_max_speed=2.0)
    with pytest.raises(ConfigError, match="min must be <= max"):
        AOASSConfig(moving_obstacle_speed=(2.0, 1.0))
    with pytest.raises(ConfigError, match="map_clearance"):
        AOASSConfig(anchor_radius=1.0, map_clearance=1.5)
    with pytest.raises(ConfigError, match="spiral_origin"):
        AOASSConfig(spiral_origin=(150.0, 10.0))
    # on the border, inside the edge margin: used to pass here and fail deep in the spiral
    with pytest.raises(ConfigError, match=r"spiral_origin=\(0.0, 0.0\) must lie inside the "
                                          r"field shrunk by edge_margin=1.5: \[1.5, 98.5\] x"):
        AOASSConfig(spiral_origin=(0.0, 0.0))
    assert AOASSConfig(spiral_origin=(1.5, 98.5)).spiral_origin == (1.5, 98.5)


@pytest.mark.parametrize("kwargs, message", [
    # each used to validate, then fail at reset or in make with a message naming no field,
    # an OverflowError, a MemoryError or minutes of work
    (dict(anchor_radius=2.0, map_clearance=4.0),
     r"edge_margin=1.5 m must be at least anchor_radius=2.0 m"),
    (dict(beacon_interval=30.0), r"beacon_interval=30.0 m must be below radio_range=25.0 m"),
    (dict(edge_margin=25.0), r"edge_margin=25.0 m leaves no spiral spacing"),
    (dict(spiral_spacing=1e-3), r"the spiral would have about 2e\+05 legs"),
    (dict(waypoint_step=1e-5), r"1.25e\+08 waypoints \(at most 50000 and 2000000\)"),
    (dict(waypoint_step=1e-320), r"inf waypoints"),
    (dict(radio_range=4.0), r"coverage_cell=2.5 m is too large for radio_range=4 m"),
])
def test_configs_that_cannot_run_are_refused_by_name(kwargs, message):
    with pytest.raises(ConfigError, match=message):
        AOASSConfig(**kwargs)


def test_the_largest_documented_field_is_still_accepted():
    assert AOASSConfig(field_size=2000.0).field_size == 2000.0
    # beyond it the detour planner's 0.5 m grid alone took about 20 GiB at reset (5000 m)
    with pytest.raises(ConfigError, match=r"field_size=2500.0 must be a number in "
                                          r"\[10.0, 2000.0\] m"):
        AOASSConfig(field_size=2500.0)
    assert AOASSConfig(field_size=10.0, edge_margin=1.5).field_size == 10.0


def test_integer_valued_float_accepted_and_normalised():
    c = AOASSConfig.from_kwargs(n_nodes=300.0, field_size=200)
    assert c.n_nodes == 300 and isinstance(c.n_nodes, int)
    assert c.field_size == 200.0 and isinstance(c.field_size, float)


def test_replace_and_json_round_trip():
    c = AOASSConfig().replace(n_nodes=500, spiral_origin=[10, 20])
    assert c.n_nodes == 500 and c.spiral_origin == (10.0, 20.0)
    import json
    again = AOASSConfig.from_kwargs(**json.loads(c.to_json()))
    assert again == c


def test_describe_lists_every_field_with_doc():
    rows = AOASSConfig.describe()
    assert {r[0] for r in rows} >= {"field_size", "n_nodes", "w1", "w2", "w3"}
    assert all(r[3] for r in rows)


def test_substep_dt():
    c = AOASSConfig(dt=0.5, physics_substeps=5)
    assert math.isclose(c.substep_dt, 0.1)


def test_docs_table_matches_the_dataclass():
    from pathlib import Path
    doc = (Path(__file__).parents[1] / "docs" / "config.md").read_text()
    assert AOASSConfig.markdown() in doc


_VALUES = st.one_of(st.none(), st.booleans(), st.integers(-10, 10**6),
                    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=5),
                    st.tuples(st.floats(-5, 50), st.floats(-5, 50)))


@settings(max_examples=200, deadline=None)
@given(st.dictionaries(st.sampled_from([r[0] for r in AOASSConfig.describe()]), _VALUES,
                       max_size=4))
def test_fuzzed_keywords_give_a_config_or_a_config_error(kwargs):
    try:
        c = AOASSConfig.from_kwargs(**kwargs)
    except ConfigError as err:
        assert any(k in str(err) for k in kwargs) or "must" in str(err)
        return
    assert AOASSConfig.from_kwargs(**c.to_dict()) == c


def test_a_clearance_of_half_the_field_is_refused_when_the_config_is_built():
    # it used to validate and fail at every reset, naming generate_map's `clearance`
    with pytest.raises(ConfigError, match=r"map_clearance=6.0 m must be less than half of "
                                          r"field_size=10.0 m"):
        AOASSConfig(field_size=10.0, map_clearance=6.0)


def test_a_map_file_outside_the_field_size_range_is_named(tmp_path):
    import gymnasium as gym
    path = tmp_path / "small.txt"
    path.write_text("[SCALE]\n1\n[BORDER]\n0 0\n5 0\n5 5\n0 5\n")
    # the error used to blame field_size, which the user never gave
    with pytest.raises(ConfigError, match=r"small.txt.* is a 5 m field; a map's side must be "
                                          r"in \[10, 2000\] m"):
        gym.make("AOASS-v0", map=str(path))
