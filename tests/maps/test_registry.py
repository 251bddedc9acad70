"""Tests of aoass_env.maps.registry: the shipped maps, their names and the validation split."""

from __future__ import annotations

import re

import numpy as np
import pytest

from aoass_env.maps import (
    DENSITY_TOL,
    MAPS_DIR,
    MapError,
    generate_map,
    list_maps,
    load_map,
    read_map,
    validation_split,
)
from tests.maps.conftest import CLEARANCE, IMR_SAMPLE, assert_same_polygons, rng, write

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


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"densities": (0.1, 0.2, 0.3)}, r"densities must be a pair of finite numbers \(low, high\), "
                                     r"got \(0.1, 0.2, 0.3\)"),   # the third was ignored
    ({"densities": 0.3}, "densities must be a pair of finite numbers"),
    ({"densities": [0.3]}, "densities must be a pair of finite numbers"),
    ({"densities": "ab"}, "densities must be a pair of finite numbers"),
    ({"densities": (float("nan"), 0.4)}, "densities must be a pair of finite numbers"),
    ({"densities": (0.4, 0.1)}, r"densities=\(0.4, 0.1\) must be \(low, high\) with "
                                r"0 <= low <= high <= 1"),
    ({"densities": (0.2, 7)}, r"0 <= low <= high <= 1"),
    ({"field_size": "100"}, r"field_size='100' must be a number in \(0.0, inf\) m"),
    ({"field_size": -100}, r"field_size=-100 must be a number in \(0.0, inf\) m"),
])
def test_list_maps_refuses_filters_it_cannot_apply(kwargs, message):
    """A filter that is not a field size or a (low, high) density range is named, where it
    used to match nothing, raise from inside, or (three densities) drop a value silently."""
    with pytest.raises(MapError, match=message):
        list_maps("train", **kwargs)
    assert list_maps("train", field_size=100.0, densities=[0.1, 0.1]) == \
        list_maps("train", field_size=100, densities=np.array([0.1, 0.1]))


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
    for alias in (stem, f"{stem}.txt", f"{name}.txt", MAPS_DIR / f"{name}.txt"):
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
    # neither a name nor a path: used to be Path()'s TypeError, naming nothing
    for thing in (None, 5):
        with pytest.raises(TypeError, match=r"name_or_path must be a shipped map's name or a map "
                                            rf"file's path, got {type(thing).__name__}"):
            load_map(thing)


def test_validation_split_holds_out_the_highest_seed_of_each_group():
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


def test_load_map_reads_a_file_once_until_it_changes(tmp_path):
    """Loading one file again gives the same (immutable) map object; an edited file is read
    afresh (issue 20: resets on named maps)."""
    import os

    name = list_maps("test")[0]
    assert load_map(name) is load_map(name.split("/")[1])
    assert load_map(name, field_size=50) is not load_map(name)
    path = write(tmp_path, IMR_SAMPLE)
    first = load_map(path)
    assert load_map(str(path)) is first
    stat = path.stat()
    os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns + 1_000_000_000))
    again = load_map(path)
    assert again is not first
    assert_same_polygons(again, first)


def test_a_map_name_that_filters_cannot_read_is_a_map_error(tmp_path, monkeypatch):
    """A file of another name in a shipped folder gave a bare ValueError ("could not convert
    string to float") when maps were filtered or split by their names."""
    import shutil

    from aoass_env.maps import registry

    (tmp_path / "train").mkdir()
    for name in ("d0.10_f100_s000", "d0.10_f100_s001"):
        shutil.copy(registry.MAPS_DIR / "train" / f"{name}.txt", tmp_path / "train")
    shutil.copy(registry.MAPS_DIR / "train" / "d0.10_f100_s000.txt",
                tmp_path / "train" / "my_field.txt")
    monkeypatch.setattr(registry, "MAPS_DIR", tmp_path)
    assert len(registry.list_maps("train")) == 3             # unfiltered: listed as it is
    with pytest.raises(MapError, match=r"my_field.txt: a shipped map's name must be "
                                       r"d<density>_f<field size>_s<seed>"):
        registry.list_maps("train", field_size=100)
    with pytest.raises(MapError, match=r"train/my_field: a shipped map's name must be"):
        registry.validation_split(registry.list_maps("train"))
    assert registry.validation_split(["train/d0.10_f100_s000", "train/d0.10_f100_s001"]) == (
        ["train/d0.10_f100_s000"], ["train/d0.10_f100_s001"])


def test_a_field_size_true_is_refused_after_a_1_m_map_was_loaded():
    """The loaded maps' cache keyed the size as given: True == 1, so after a 1 m load the same
    call with field_size=True returned that map instead of the error it gives alone."""
    name = list_maps("test")[0]
    with pytest.raises(MapError, match=r"field_size=True must be a number"):
        load_map(name, field_size=True)
    assert load_map(name, field_size=1).width == 1.0
    with pytest.raises(MapError, match=r"field_size=True must be a number"):
        load_map(name, field_size=True)
