"""Tests of aoass_env.beacon_log: recorder, schema validation, atomic save and load."""

from __future__ import annotations

import json
import os
import zipfile

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aoass_env.beacon_log import (
    SCHEMA_VERSION,
    BeaconLog,
    BeaconLogError,
    BeaconLogRecorder,
    episode_config_json,
)
from aoass_env.config import AOASSConfig
from aoass_env.maps import ObstacleMap
from aoass_env.network import Network
from aoass_env.radio import Radio

KEYS = ("version", "config_json", "field", "obstacle_vertices", "obstacle_offsets", "nodes",
        "beacons", "receptions", "node_links", "anchor_path", "node_energy", "anchor_energy",
        "radio_range", "collisions")
SQUARE = [(2, 2), (4, 2), (4, 4), (2, 4)]
ELL = [(10, 10), (16, 10), (16, 12), (12, 12), (12, 16), (10, 16)]


def make_log(extras=None) -> BeaconLog:
    obstacle_map = ObstacleMap(20, 18, [SQUARE, ELL])
    nodes = np.array([(1, 1), (6, 3), (14, 14), (18, 2), (8, 8)], dtype=float)
    rec = BeaconLogRecorder(config_json=episode_config_json(AOASSConfig(), seed=3,
                                                            method="aoass"),
                            obstacle_map=obstacle_map, nodes=nodes, radio_range=5.0)
    rec.add_path_point(0.0, np.array([0.5, 0.5]))
    assert rec.add_beacon(0.0, np.array([0.5, 0.5]), np.array([0])) == 0
    rec.add_path_point(0.5, np.array([3.0, 0.5]))
    assert rec.add_beacon(0.5, np.array([3.0, 0.5]), np.array([0, 1])) == 1
    assert rec.add_beacon(0.5, np.array([3.0, 0.6]), np.array([], dtype=np.int64)) == 2
    rec.add_path_point(1.0, np.array([7.0, 7.0]))
    assert rec.add_beacon(1.0, np.array([7.0, 7.0]), np.array([1, 4])) == 3
    assert rec.n_beacons == 4
    return rec.finish(node_energy=np.array([2, 2, 0, 0, 1]) * 1.28e-5, anchor_energy=5.6,
                      collisions=1, node_links=np.array([[0, 1], [1, 4]]), extras=extras)


def write_npz(path, arrays) -> None:
    with open(path, "wb") as f:
        np.savez(f, **arrays)


def test_recorder_builds_the_schema():
    log = make_log()
    assert log.version == SCHEMA_VERSION == 1
    np.testing.assert_array_equal(log.field, [20.0, 18.0])
    np.testing.assert_array_equal(log.obstacle_offsets, [0, 4, 10])
    np.testing.assert_array_equal(log.obstacle_vertices[:4], SQUARE)
    np.testing.assert_array_equal(log.beacons, [[0, 0.5, 0.5], [0.5, 3, 0.5], [0.5, 3, 0.6],
                                                [1, 7, 7]])
    np.testing.assert_array_equal(log.receptions, [[0, 0], [1, 0], [1, 1], [3, 1], [3, 4]])
    np.testing.assert_array_equal(log.anchor_path[:, 0], [0.0, 0.5, 1.0])
    assert (log.anchor_energy, log.radio_range, log.collisions) == (5.6, 5.0, 1)
    assert (log.n_nodes, log.n_beacons) == (5, 4)
    assert log.config["seed"] == 3 and log.config["method"] == "aoass"
    assert log.config["config"]["radio_range"] == 25.0
    arrays = log.arrays()
    assert tuple(arrays) == KEYS
    for key in ("receptions", "node_links", "obstacle_offsets", "collisions", "version"):
        assert arrays[key].dtype == np.int64, key
    for key in ("field", "nodes", "beacons", "node_energy", "anchor_energy", "radio_range"):
        assert arrays[key].dtype == np.float64, key
    assert arrays["config_json"].dtype.kind == "U" and arrays["config_json"].shape == ()


def test_obstacle_map_is_reconstructed():
    m = make_log().obstacle_map
    assert (m.width, m.height) == (20.0, 18.0)
    assert len(m.polygons) == 2
    np.testing.assert_array_equal(m.polygons[1], ELL)


def test_arrays_are_read_only():
    log = make_log(extras={"rssi": np.arange(3.0)})
    for array in (log.nodes, log.receptions, log.extras["rssi"]):
        with pytest.raises(ValueError):
            array[0] = 0


def test_round_trip_keeps_every_key_and_extras(tmp_path):
    log = make_log(extras={"rssi": np.linspace(-90, -40, 5), "note": np.array("hello"),
                           "flags": np.array([True, False])})
    path = tmp_path / "episode.npz"
    log.save(path)
    back = BeaconLog.load(path)
    a, b = log.arrays(), back.arrays()
    assert list(a) == list(b)
    for key in a:
        assert a[key].dtype == b[key].dtype, key
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    assert back.config_json == log.config_json and isinstance(back.config_json, str)
    assert isinstance(back.collisions, int) and isinstance(back.anchor_energy, float)
    assert str(back.extras["note"]) == "hello"
    np.testing.assert_array_equal(back.obstacle_map.polygons[0], log.obstacle_map.polygons[0])


def test_save_writes_exactly_the_given_name_atomically(tmp_path):
    log = make_log()
    path = tmp_path / "episode.log"  # no ".npz" appended
    log.save(path)
    log.save(str(path))  # replacing an existing file works
    assert sorted(os.listdir(tmp_path)) == ["episode.log"]
    assert BeaconLog.load(path).n_beacons == 4


def test_failed_save_keeps_the_old_file_and_leaves_no_temp(tmp_path, monkeypatch):
    path = tmp_path / "episode.npz"
    make_log().save(path)
    before = path.read_bytes()

    def broken(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez", broken)
    with pytest.raises(OSError, match="disk full"):
        make_log(extras={"x": np.zeros(2)}).save(path)
    assert path.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == ["episode.npz"]


def test_empty_episode_round_trips(tmp_path):
    rec = BeaconLogRecorder(config_json="{}", obstacle_map=ObstacleMap(10, 10),
                            nodes=np.zeros((0, 2)), radio_range=25.0)
    log = rec.finish(node_energy=np.zeros(0), anchor_energy=0.0, collisions=0, node_links=[])
    log.save(tmp_path / "e.npz")
    back = BeaconLog.load(tmp_path / "e.npz")
    assert back.obstacle_vertices.shape == (0, 2) and back.obstacle_offsets.tolist() == [0]
    assert back.receptions.shape == (0, 2) and back.node_links.shape == (0, 2)
    assert back.beacons.shape == (0, 3) and back.anchor_path.shape == (0, 3)


def good_arrays() -> dict[str, np.ndarray]:
    return make_log().arrays()


BOWTIE = np.array([(2, 2), (4, 4), (4, 2), (2, 4)], dtype=float)
CORRUPTIONS = [
    ("version", np.int64(2), "unsupported version 2"),
    ("version", np.array("1"), "dtype"),
    ("config_json", np.array("{not json"), "not valid JSON"),
    ("config_json", np.array("[1, 2]"), "JSON object"),
    # these escaped as RecursionError, a bare ValueError, or were read as floats
    ("config_json", np.array("[" * 100_000), "not valid JSON (nested too deeply to read)"),
    ("config_json", np.array('{"a": ' + "9" * 5000 + "}"), "integer string conversion"),
    ("config_json", np.array('{"a": NaN}'), "not valid JSON (NaN is not a JSON value)"),
    ("config_json", np.array('{"a": -Infinity}'), "-Infinity is not a JSON value"),
    ("config_json", np.int64(5), "dtype"),
    ("field", np.array([20.0]), "expected (2,)"),
    ("field", np.array([20.0, -1.0]), "positive"),
    # a float-maximum field overflowed the positions' bound to inf and loaded
    ("field", np.array([20.0, 1e308]), "at most 2000 m"),
    ("field", np.array([np.nan, 1.0]), "non-finite"),
    ("obstacle_vertices", np.zeros((10, 3)), "expected (V, 2)"),
    ("obstacle_vertices", np.full((10, 2), np.inf), "non-finite"),
    ("obstacle_vertices", np.concatenate([BOWTIE, ELL]).astype(float), "simple polygon"),
    ("obstacle_offsets", np.array([1, 4, 10]), "start at 0"),
    ("obstacle_offsets", np.array([0, 4, 9]), "end at V=10"),
    ("obstacle_offsets", np.array([0, 2, 10]), "by >= 3"),
    ("obstacle_offsets", np.array([0.0, 4.0, 10.0]), "dtype"),
    ("obstacle_offsets", np.zeros(0, np.int64), "expected (P+1,)"),
    ("nodes", np.zeros((5, 3)), "expected (N, 2)"),
    ("nodes", np.array([[0, 0], [1, np.inf], [2, 2], [3, 3], [4, 4]], float), "non-finite"),
    ("beacons", np.zeros((4, 2)), "expected (B, 3)"),
    ("beacons", np.array([[0, 1, 1], [2, 1, 1], [1, 1, 1], [3, 1, 1]], float),
     "decreases from row 1"),
    ("receptions", np.array([[0, 0], [4, 1]]), "beacon index out of [0, B=4) in row 1"),
    ("receptions", np.array([[0, 0], [1, 5]]), "node index out of [0, N=5) in row 1"),
    ("receptions", np.array([[-1, 0]]), "beacon index"),
    ("receptions", np.array([[0.0, 0.0]]), "dtype"),
    ("node_links", np.array([[0, 1], [3, 2]]), "row 1 is not a pair i < j"),
    ("node_links", np.array([[2, 2]]), "not a pair i < j"),
    ("node_links", np.array([[1, 4], [0, 1], [1, 4]]), "row 2 repeats an earlier pair"),
    ("node_links", np.array([[0, 1], [0, 2], [0, 1], [0, 1]]), "row 2 repeats an earlier"),
    ("node_links", np.array([[0, 5]]), "node index out of [0, N=5)"),
    ("node_links", np.array([[-1, 2]]), "node index"),
    ("node_links", np.array([0, 1]), "expected (E, 2)"),
    ("anchor_path", np.array([[1, 0, 0], [0, 0, 0]], float), "decreases from row 0"),
    ("anchor_path", np.zeros((3, 2)), "expected (T, 3)"),
    ("node_energy", np.zeros(4), "N=5"),
    ("node_energy", np.array([0, 0, -1e-5, 0, 0]), "negative energy at node 2"),
    ("node_energy", np.array([0, 0, np.nan, 0, 0]), "non-finite"),
    ("anchor_energy", np.float64(-1.0), "negative"),
    ("anchor_energy", np.zeros(2), "expected ()"),
    ("radio_range", np.float64(0.0), "positive"),
    ("radio_range", np.array(True), "dtype"),
    ("collisions", np.int64(-1), "negative"),
    ("collisions", np.float64(1.5), "dtype"),
]


@pytest.mark.parametrize(("key", "value", "message"), CORRUPTIONS,
                         ids=[f"{c[0]}-{i}" for i, c in enumerate(CORRUPTIONS)])
def test_each_corrupted_key_is_named(tmp_path, key, value, message):
    arrays = good_arrays()
    arrays[key] = value
    path = tmp_path / "bad.npz"
    write_npz(path, arrays)
    with pytest.raises(BeaconLogError) as info:
        BeaconLog.load(path)
    assert info.value.key == key
    assert f"key {key!r}" in str(info.value) and message in str(info.value)
    assert str(path) in str(info.value)
    # The constructor applies the same validation.
    schema = {k: v for k, v in arrays.items()}
    with pytest.raises(BeaconLogError) as info:
        BeaconLog(**schema)
    assert info.value.key == key


@pytest.mark.parametrize("key", KEYS)
def test_missing_key_is_named(tmp_path, key):
    arrays = good_arrays()
    del arrays[key]
    write_npz(tmp_path / "bad.npz", arrays)
    with pytest.raises(BeaconLogError, match="missing") as info:
        BeaconLog.load(tmp_path / "bad.npz")
    assert info.value.key == key


def test_truncated_and_foreign_files(tmp_path):
    good = tmp_path / "good.npz"
    make_log().save(good)
    data = good.read_bytes()
    for name, content in (("half.npz", data[: len(data) // 2]), ("tail.npz", data[:-30]),
                          ("empty.npz", b""), ("text.npz", b"hello, not a zip file\n" * 5),
                          ("noise.npz", np.random.default_rng(0).bytes(4000))):
        (tmp_path / name).write_bytes(content)
        with pytest.raises(BeaconLogError, match=name):
            BeaconLog.load(tmp_path / name)
    np.save(tmp_path / "array.npy", np.zeros(3))
    with pytest.raises(BeaconLogError, match="not an .npz archive"):
        BeaconLog.load(tmp_path / "array.npy")
    with pytest.raises(FileNotFoundError):
        BeaconLog.load(tmp_path / "absent.npz")


def test_corrupted_member_is_an_error(tmp_path):
    path = tmp_path / "log.npz"
    make_log().save(path)
    data = bytearray(path.read_bytes())
    at = data.index(b"\x93NUMPY", data.index(b"nodes.npy"))  # header of the 'nodes' member
    data[at:at + 6] = b"GARBGE"
    path.write_bytes(bytes(data))
    with pytest.raises(BeaconLogError, match="cannot read") as info:
        BeaconLog.load(path)
    assert info.value.key == "nodes"


def test_a_multi_line_numpy_error_is_reported_on_one_line(tmp_path):
    # numpy refuses a .npy header over 10000 bytes with a three-line message
    path = tmp_path / "log.npz"
    nodes = good_arrays()["nodes"]
    make_log().save(path)
    with zipfile.ZipFile(path) as z:
        members = {name: z.read(name) for name in z.namelist()}
    header = f"{{'descr': '<f8', 'fortran_order': False, 'shape': {nodes.shape}, }}"
    header += " " * (20000 - len(header)) + "\n"
    members["nodes.npy"] = (b"\x93NUMPY\x02\x00" + len(header).to_bytes(4, "little")
                            + header.encode() + nodes.tobytes())
    with zipfile.ZipFile(path, "w") as z:
        for name, content in members.items():
            z.writestr(name, content)
    with pytest.raises(BeaconLogError, match="Header info length") as info:
        BeaconLog.load(path)
    assert info.value.key == "nodes" and "\n" not in str(info.value)


def test_object_extras_and_bad_extra_names_are_rejected(tmp_path):
    with pytest.raises(BeaconLogError, match="Python objects"):
        make_log(extras={"stuff": np.array([{"a": 1}], dtype=object)})
    for name in ("nodes", "", "a/b"):
        with pytest.raises(BeaconLogError, match="extra key"):
            make_log(extras={name: np.zeros(1)})
    # np.savez's own arguments: "allow_pickle" used to vanish on save, "file" to crash it
    for name in ("file", "allow_pickle"):
        with pytest.raises(BeaconLogError, match=f"extra key '{name}' must be .* not file or "
                                                 f"allow_pickle .np.savez's own arguments."):
            make_log(extras={name: np.zeros(1)})
    make_log(extras={"files": np.zeros(1)}).save(tmp_path / "ok.npz")
    assert set(BeaconLog.load(tmp_path / "ok.npz").extras) == {"files"}
    arrays = good_arrays()
    arrays["pickled"] = np.array([None, 1], dtype=object)
    write_npz(tmp_path / "obj.npz", arrays)
    with pytest.raises(BeaconLogError) as info:
        BeaconLog.load(tmp_path / "obj.npz")
    assert info.value.key == "pickled"


def test_recorder_rejects_bad_steps():
    rec = BeaconLogRecorder(config_json="{}", obstacle_map=ObstacleMap(10, 10),
                            nodes=np.zeros((3, 2)), radio_range=5.0)
    rec.add_beacon(1.0, np.array([1.0, 1.0]), np.array([0, 2]))
    with pytest.raises(BeaconLogError, match="before the previous") as info:
        rec.add_beacon(0.5, np.array([1.0, 1.0]), np.array([0]))
    assert info.value.key == "beacons"
    with pytest.raises(BeaconLogError, match=r"\[0, 3\)"):
        rec.add_beacon(2.0, np.array([1.0, 1.0]), np.array([3]))
    with pytest.raises(BeaconLogError, match="1-D node indices"):
        rec.add_beacon(2.0, np.array([1.0, 1.0]), np.array([0.5]))
    with pytest.raises(BeaconLogError, match="finite time"):
        rec.add_beacon(float("nan"), np.array([1.0, 1.0]), np.array([0]))
    with pytest.raises(BeaconLogError, match="finite time") as info:
        rec.add_path_point(0.0, np.array([1.0, 2.0, 3.0]))
    assert info.value.key == "anchor_path"
    assert rec.n_beacons == 1
    with pytest.raises(BeaconLogError, match="N=3") as info:
        rec.finish(node_energy=np.zeros(2), anchor_energy=0.0, collisions=0,
                   node_links=np.zeros((0, 2), np.int64))
    assert info.value.key == "node_energy"
    for kwargs, key in (({"config_json": "[]"}, "config_json"),
                        ({"radio_range": -1.0}, "radio_range"),
                        ({"nodes": np.zeros((2, 3))}, "nodes")):
        args = {"config_json": "{}", "obstacle_map": ObstacleMap(10, 10),
                "nodes": np.zeros((3, 2)), "radio_range": 5.0, **kwargs}
        with pytest.raises(BeaconLogError) as info:
            BeaconLogRecorder(**args)
        assert info.value.key == key


def test_episode_config_json():
    text = episode_config_json(AOASSConfig(n_nodes=50), seed=None, method="spiral")
    data = json.loads(text)
    assert data["config"]["n_nodes"] == 50 and data["seed"] is None
    assert data["method"] == "spiral"
    assert AOASSConfig.from_kwargs(**data["config"]) == AOASSConfig(n_nodes=50)


def test_radio_network_and_recorder_agree(tmp_path):
    config = AOASSConfig(field_size=30.0, n_nodes=40, radio_range=8.0)
    rng = np.random.default_rng(2)
    obstacle_map = ObstacleMap(30, 30, [SQUARE, ELL])
    nodes = rng.uniform(0, 30, (40, 2))
    radio = Radio.from_config(nodes, obstacle_map, config)
    net = Network(40, config)
    rec = BeaconLogRecorder(config_json=episode_config_json(config, seed=2, method="test"),
                            obstacle_map=obstacle_map, nodes=nodes,
                            radio_range=config.radio_range)
    prev = np.array([1.0, 1.0])
    for k, p in enumerate(rng.uniform(0, 30, (25, 2))):
        net.charge_motion(float(np.hypot(*(p - prev))))
        heard = radio.receivers(p)
        net.record_beacon(p, heard)
        rec.add_beacon(0.5 * k, p, heard)
        rec.add_path_point(0.5 * k, p)
        prev = p
    log = rec.finish(node_energy=net.node_energy, anchor_energy=net.anchor_energy,
                     collisions=0, node_links=radio.node_links())
    log.save(tmp_path / "run.npz")
    back = BeaconLog.load(tmp_path / "run.npz")
    assert len(back.receptions) == net.receptions
    np.testing.assert_array_equal(np.bincount(back.receptions[:, 1], minlength=40), net.heard)
    np.testing.assert_array_equal(back.node_links, radio.node_links())
    assert back.anchor_energy + back.node_energy.sum() == pytest.approx(net.energy_total,
                                                                        rel=1e-12)


@settings(max_examples=60, deadline=None)
@given(st.data())
def test_damaged_files_fail_with_beacon_log_error(tmp_path_factory, data):
    """Flipped or cut bytes anywhere in a saved log: a BeaconLogError, or a valid log."""
    path = tmp_path_factory.mktemp("damage") / "log.npz"
    make_log().save(path)
    raw = bytearray(path.read_bytes())
    if data.draw(st.booleans(), label="truncate"):
        raw = raw[:data.draw(st.integers(0, len(raw) - 1), label="keep")]
    else:
        for _ in range(data.draw(st.integers(1, 8), label="flips")):
            raw[data.draw(st.integers(0, len(raw) - 1))] ^= data.draw(st.integers(1, 255))
    path.write_bytes(bytes(raw))
    try:
        log = BeaconLog.load(path)
    except BeaconLogError:
        return
    assert log.n_beacons >= 0


_SPECIAL = (0.0, -0.0, 1e-300, -1e-300, 1.5, -2.5, 1e308, -1e308, float("inf"), float("-inf"),
            float("nan"))


@settings(max_examples=300, deadline=None)
@given(t=st.one_of(st.sampled_from(_SPECIAL), st.floats(allow_nan=True, allow_infinity=True)),
       x=st.one_of(st.sampled_from(_SPECIAL), st.floats(allow_nan=True, allow_infinity=True)),
       y=st.one_of(st.sampled_from(_SPECIAL), st.floats(allow_nan=True, allow_infinity=True)),
       last=st.one_of(st.none(), st.floats(allow_nan=False, allow_infinity=True)))
def test_a_path_point_of_python_floats_is_recorded_as_the_array_path_records_it(t, x, y, last):
    # the tuple of Python floats takes a path without arrays: the same row, or the same error
    def record(position):
        rec = BeaconLogRecorder(config_json="{}", obstacle_map=ObstacleMap(10, 10),
                                nodes=np.zeros((1, 2)), radio_range=5.0)
        if last is not None:
            rec._path.append((last, 0.0, 0.0))
        try:
            rec.add_path_point(t, position)
        except BeaconLogError as exc:      # the message up to the position's own repr
            return str(exc).split("position=")[0], exc.key
        row = rec._path[-1]
        assert all(type(v) is float for v in row)
        return [v.hex() for v in row]

    assert record((x, y)) == record(np.array([x, y]))
