"""The shipped folders travel with the package: found in a checkout, copied into a wheel."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from aoass_env.data import SHIPPED, shipped_dir

ROOT = Path(__file__).resolve().parents[1]


def test_a_checkout_finds_its_top_level_folders():
    assert [shipped_dir(name) for name in SHIPPED] == [ROOT / name for name in SHIPPED]


def test_an_unknown_folder_is_refused_by_name():
    with pytest.raises(ValueError, match="name='tests' must be one of"):
        shipped_dir("tests")


def test_setup_copies_exactly_the_shipped_folders():
    """setup.py (which cannot import the package it builds) names the same folders."""
    tree = ast.parse((ROOT / "setup.py").read_text())
    assigned = {t.id: node.value for node in tree.body if isinstance(node, ast.Assign)
                for t in node.targets if isinstance(t, ast.Name)}
    assert ast.literal_eval(assigned["SHIPPED"]) == SHIPPED


def test_license_and_typing_marker_ship():
    assert "Copyright (c) 2026 the AOASS authors" in (ROOT / "LICENSE").read_text()
    assert (ROOT / "aoass_env" / "py.typed").is_file() and (ROOT / "agents" / "py.typed").is_file()
