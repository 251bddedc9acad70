"""The one rule for numbers (issue 18): aoass_env.validators and the entry points that use it."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from agents.sections import HyperparameterError, check_section
from aoass_env.config import AOASSConfig
from aoass_env.maps import MapError, ObstacleMap, generate_map
from aoass_env.planning.baselines.m_anchoro import free_samples
from aoass_env.safety.kalman import MultiTargetTracker
from aoass_env.safety.orca import orca_lines
from aoass_env.validators import (
    argparse_number,
    first_difference,
    float_array,
    index_array,
    integer,
    one_line,
    positive,
    real,
    torch_load_problem,
    vec2,
)
from aoass_env.world import World

NUMBERS = [np.float32(1.5), np.float64(1.5), np.int64(100), np.int32(7), 2, 2.0]
NOT_NUMBERS = [True, False, np.bool_(True), "2", b"2", 2 + 0j, None, [1.0], math.nan,
               -math.inf, math.inf, np.float32("nan")]


class Custom(ValueError):
    """An error type a caller asks for."""


@pytest.mark.parametrize("value", NUMBERS)
def test_real_accepts_python_and_numpy_numbers(value: Any) -> None:
    out = real("x", value)
    assert type(out) is float and out == float(value)
    assert positive("x", value) == float(value)


@pytest.mark.parametrize("value", NOT_NUMBERS)
@pytest.mark.parametrize("check", [real, positive, integer])
def test_bools_strings_complex_none_and_non_finite_are_refused(check: Callable[..., Any],
                                                                value: Any) -> None:
    with pytest.raises(Custom, match=r"^speed=.* must be ") as err:
        check("speed", value, error=Custom)
    assert repr(value) in str(err.value)


@pytest.mark.parametrize("value, expected", [
    (32, 32), (32.0, 32), (np.int64(100), 100), (np.float32(4.0), 4), (np.uint8(3), 3)])
def test_integer_takes_whole_numbers(value: Any, expected: int) -> None:
    out = integer("n", value)
    assert type(out) is int and out == expected


@pytest.mark.parametrize("value", [1.5, np.float32(0.5), "3", True, np.bool_(False)])
def test_integer_refuses_fractions_and_non_numbers(value: Any) -> None:
    with pytest.raises(ValueError, match=r"^n=.* must be an integer in \(-inf, inf\)"):
        integer("n", value)


@pytest.mark.parametrize("call, message", [
    (lambda: real("gate", 1.0, "probability", low=0.0, high=1.0, low_open=True,
                  high_open=True, error=Custom), r"gate=1\.0 .* in \(0\.0, 1\.0\) probability"),
    (lambda: positive("radius", 0.0, "m", error=Custom), r"radius=0\.0 .* in \(0\.0, inf\) m"),
    (lambda: positive("gap", 11.0, "m", high=10.0, error=Custom), r"gap=11\.0 .* \(0\.0, 10\.0\]"),
    (lambda: integer("n", -1, low=0, error=Custom), r"n=-1 must be an integer in \[0, inf\)"),
    (lambda: vec2("position", (1.0, "2"), "m", error=Custom), r"position must be a pair"),
    (lambda: vec2("position", np.zeros(3), "m", error=Custom), r"position .* shape \(3,\)"),
])
def test_errors_name_the_parameter_and_range_in_the_requested_type(
        call: Callable[[], Any], message: str) -> None:
    with pytest.raises(Custom, match=message):
        call()


def test_vec2_takes_sequences_and_arrays_of_numbers() -> None:
    for value in ((1, 2.0), [np.float32(1.0), np.int64(2)], np.array([1.0, 2.0]),
                  np.array([1, 2], dtype=np.int32)):
        out = vec2("p", value)
        assert out == (1.0, 2.0) and all(type(v) is float for v in out)
    for bad in ((1.0,), (1.0, math.nan), (True, 1.0), "12", None, np.zeros((2, 1))):
        with pytest.raises(ValueError, match="p must be a pair"):
            vec2("p", bad)


@given(st.one_of(st.integers(-10**6, 10**6), st.floats(allow_nan=True, allow_infinity=True),
                 st.booleans(), st.text(max_size=3), st.none(),
                 st.floats(width=32).map(np.float32), st.integers(-10**6, 10**6).map(np.int64)))
def test_one_rule_property(value: Any) -> None:
    """real() accepts exactly the finite non-bool reals, and returns their float value."""
    is_number = (isinstance(value, (int, float, np.integer, np.floating))
                 and not isinstance(value, (bool, np.bool_)) and math.isfinite(float(value)))
    try:
        out = real("v", value)
    except ValueError as err:
        assert not is_number and str(err).startswith("v=")
    else:
        assert is_number and out == float(value)


# --- the entry points converted to the one rule ----------------------------------------------
_MAP = ObstacleMap(20.0, 20.0)


def _orca(radius: Any) -> Any:
    return orca_lines((0.0, 0.0), (0.0, 0.0), radius, 2.0)


def _tracker(dt: Any) -> Any:
    return MultiTargetTracker(dt, position_noise=0.1, velocity_noise=None)


def _map(density: Any) -> Any:
    return generate_map(40, density, np.random.default_rng(0), clearance=2.0)


def _spacing(spacing: Any) -> Any:
    return free_samples(_MAP, spacing)


def _speed_cmd(speed: Any) -> Any:
    world = World(AOASSConfig(n_moving_obstacles=0), _MAP, np.random.default_rng(0),
                  start=(10.0, 10.0))
    return world.step(speed, 0.0)


def _batch_size(batch_size: Any) -> Any:
    from agents.recurrent_td3 import RecurrentTD3
    return check_section({"batch_size": batch_size}, RecurrentTD3, "f.yml.td3-lstm")


ENTRY_POINTS = [
    pytest.param(_orca, 0.7, 1, ValueError, "radius", id="orca_lines radius"),
    pytest.param(_tracker, 0.1, 1, ValueError, "dt", id="tracker dt"),
    pytest.param(_map, 0.1, 0, MapError, "density", id="generate_map density"),
    pytest.param(_spacing, 2.5, 2, ValueError, "spacing", id="baseline spacing"),
    pytest.param(_speed_cmd, 0.5, 1, ValueError, "speed_cmd", id="world step speed_cmd"),
]


@pytest.mark.parametrize("call, good, whole, error, name", ENTRY_POINTS)
def test_entry_points_take_numpy_scalars(call: Callable[[Any], Any], good: float, whole: int,
                                         error: type[Exception], name: str) -> None:
    call(np.float32(good))
    call(np.int64(whole))


@pytest.mark.parametrize("bad", ["2", True])
@pytest.mark.parametrize("call, good, whole, error, name", ENTRY_POINTS)
def test_entry_points_refuse_strings_and_bools(call: Callable[[Any], Any], good: float,
                                               whole: int, error: type[Exception], name: str,
                                               bad: Any) -> None:
    with pytest.raises(error, match=f"{name}={bad!r} must be a number"):
        call(bad)


def test_hyperparameter_sections_follow_the_rule() -> None:
    assert _batch_size(np.int64(32))["batch_size"] == 32
    assert _batch_size(32.0)["batch_size"] == 32
    for bad in ("32", True, 32.5):
        with pytest.raises(HyperparameterError, match=r"f\.yml\.td3-lstm\.batch_size=.* integer"):
            _batch_size(bad)


@pytest.mark.parametrize(("kind", "low", "low_open", "text", "valid"), [
    (int, 1, False, "1", True), (int, 1, False, "0", False), (int, 0, False, "0", True),
    (int, 1, False, "1.5", False), (int, 1, False, "two", False), (int, 1, False, "", False),
    (float, 0, True, "0.001", True), (float, 0, True, "0", False), (float, 0, True, "-1", False),
    (float, 0, False, "0", True), (float, 0, False, "nan", False), (float, 0, False, "inf", False),
])
def test_argparse_number_takes_finite_values_in_range_and_names_the_flag_otherwise(
        capsys, kind, low, low_open, text, valid):
    parser = argparse.ArgumentParser(prog="tool")
    parser.add_argument("--count", type=argparse_number(kind, low, low_open))
    if valid:
        value = parser.parse_args(["--count", text]).count
        assert type(value) is kind and value == kind(text)
        return
    with pytest.raises(SystemExit):
        parser.parse_args(["--count", text])
    error = capsys.readouterr().err.strip().splitlines()[-1]
    what = "an integer" if kind is int else "a finite number"
    assert error == (f"tool: error: argument --count: must be {what} "
                     f"{'>' if low_open else '>='} {low:g}, got {text!r}")


def test_float_array_names_entries_that_are_not_numbers() -> None:
    assert float_array("xy", [[1, 2], [3.5, np.float32(4)]]).dtype == np.float64
    for value, why in (([["a", 1]], "could not convert string to float: 'a'"),
                       ([[1, 2], [3]], "setting an array element with a sequence"),
                       ([{"x": 1}], "float() argument must be")):
        with pytest.raises(ValueError) as info:
            float_array("xy", value)
        assert str(info.value).startswith(f"xy must be an array of numbers ({why}")
        assert "\n" not in str(info.value)


def test_one_line_joins_a_library_message_into_one_line() -> None:
    assert one_line(ValueError("Weights only load failed.\n\n  Unsupported operand 103\n")) \
        == "Weights only load failed. Unsupported operand 103"
    assert one_line("already one line") == "already one line"
    assert one_line(EOFError()) == "EOFError" and one_line("") == ""
    assert one_line("\x1b[1mbold\x1b[0m\n\ttext") == "bold text"


def test_torch_load_problem_keeps_the_reason_and_drops_the_advice(tmp_path) -> None:
    """torch's weights-only refusals in their three shapes (no pickle, a blocked module, a
    global not allowlisted), each several lines advising weights_only=False."""
    import os

    import torch

    class RunsCode:
        def __reduce__(self):
            return (os.system, ("true",))

    class Calls:
        def __reduce__(self):
            return (math.hypot, (3.0, 4.0))   # not print: Ray replaces it once imported

    (tmp_path / "garbage").write_bytes(b"garbage")
    torch.save({"x": RunsCode()}, tmp_path / "code")
    torch.save({"x": Calls()}, tmp_path / "call")
    (tmp_path / "empty").write_bytes(b"")
    reasons = {}
    for name in ("garbage", "code", "call", "empty"):
        with pytest.raises(Exception) as info:
            torch.load(tmp_path / name, weights_only=True)
        reasons[name] = torch_load_problem(info.value)
    assert reasons["garbage"] == "weights-only load refused: Unsupported operand 103"
    assert reasons["code"].startswith("weights-only load refused: Trying to load unsupported "
                                      "GLOBAL ") and reasons["code"].endswith(" is blocked")
    assert reasons["call"] == ("weights-only load refused: Unsupported global: GLOBAL math.hypot "
                               "was not an allowed global by default")
    assert reasons["empty"] == "EOFError"
    assert all("weights_only" not in r and "\n" not in r for r in reasons.values())
    assert torch_load_problem(ValueError("another\nproblem")) == "another problem"


def test_first_difference_names_the_first_key_in_sorted_order() -> None:
    assert first_difference({"a": 1, "b": [2]}, {"b": [2], "a": 1}) is None
    assert first_difference({"b": 2.0, "c": 3, "a": 1}, {"a": 1, "b": 2.5, "d": "x"}) == \
        ("b", "2.0", "2.5", ["c", "d"])
    assert first_difference({}, {"n": None}) == ("n", "unset", "None", [])
    assert first_difference({"n": 1}, {"n": True}) is None   # equal values, as == sees them


def test_finite_array_names_the_array_and_what_is_wrong() -> None:
    from aoass_env.validators import finite_array
    assert finite_array("a", [[1, 2]], "m", (None, 2)).dtype == np.float64
    for value, match in ((np.array([[np.nan, 0.0]]), "a must be finite"),
                         (np.zeros((1, 3)), r"a must be an array of shape \(n, 2\) \(m\)"),
                         (np.zeros(2), r"shape \(n, 2\)"),
                         (np.array([True, False]), "got bool values|got dtype bool"),
                         (["1", "2"], "a must be an array of numbers"),
                         ([[1.0], [2.0, 3.0]], "a must be an array of numbers")):
        with pytest.raises(ValueError, match=match):
            finite_array("a", value, "m", (None, 2))



def test_real_takes_a_python_float_by_its_fast_path_with_the_same_rule() -> None:
    """The fast path for a plain float (no ABC test) keeps every bound and the non-finite
    refusals; other numbers still go the general way."""
    assert real("x", 1.5, "m", low=0.0) == 1.5 and real("x", np.float32(0.5)) == 0.5
    for value, kwargs in ((math.nan, {}), (math.inf, {}), (-1.0, {"low": 0.0}),
                          (0.0, {"low": 0.0, "low_open": True}), (2.0, {"high": 1.0}),
                          (True, {})):
        with pytest.raises(ValueError, match="x="):
            real("x", value, "m", **kwargs)


def test_index_array_takes_distinct_in_range_integers_only():
    assert index_array("nodes", [3, 0, 2], 4).tolist() == [3, 0, 2]
    assert index_array("nodes", np.array([1], np.uint8), 4).dtype == np.int64
    assert index_array("nodes", [], 4).shape == (0,)
    for bad, message in (([1.0], "integer indices in \\[0, 4\\), got dtype float64"),
                         ([True], "integer indices"), (["1"], "integer indices"),
                         ([-1], "indices in \\[0, 4\\), got -1"), ([4], "got 4"),
                         ([2, 2], "not repeat an index"), ([[1]], "a 1-D array")):
        with pytest.raises(ValueError, match=f"nodes must (.* )?{message}"):
            index_array("nodes", bad, 4)


def test_argparse_number_with_an_upper_bound():
    parse = argparse_number(int, 0, high=10)
    assert parse("10") == 10
    with pytest.raises(argparse.ArgumentTypeError,
                       match=r"must be an integer in \[0, 10\], got '11'"):
        parse("11")
