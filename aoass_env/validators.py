"""Checks of user-given values, with one rule for numbers, and validated config dataclasses.

**One rule for numbers.** A number is a Python or numpy real number (``int``, ``float``,
``np.int64``, ``np.float32``, ...); ``bool`` and ``np.bool_``, strings (even ``"2"``), complex
numbers and ``None`` are not. It must be finite and, where a range is given, inside it. An
integer parameter also takes a real number with no fractional part (``32.0``, as YAML or JSON may
write it). Every check raises the caller's error type (``ValueError`` by default) with a one-line
message naming the parameter, its valid range and its unit.

**Validated configs.** :class:`ValidatedConfig` is the base of every config dataclass
(:class:`~aoass_env.config.AOASSConfig`, the safety stack's
:class:`~aoass_env.safety.config.TrackerConfig` and :class:`~aoass_env.safety.config.SafetyConfig`):
each field is declared with :func:`param` (default, one-line meaning, unit, valid range) and is
checked from that metadata, so the documentation and the checks cannot drift apart; unknown
keywords get a did-you-mean error; :meth:`ValidatedConfig.markdown` is the docs table.

**One-line messages.** :func:`one_line` embeds a library's error text in a one-line message,
:func:`torch_load_problem` keeps only the reason of torch's weights-only refusal (never its
advice to load with ``weights_only=False``), :func:`float_array` names an array argument
whose entries are not numbers, and :func:`first_difference` names where a recorded setting
differs from today's.
"""

from __future__ import annotations

import argparse
import dataclasses
import difflib
import inspect
import json
import math
import re
from collections.abc import Callable, Iterable, Mapping
from dataclasses import field
from numbers import Integral, Real
from pathlib import Path
from typing import Any, ClassVar, TypeVar

import numpy as np

__all__ = ["ConfigError", "ValidatedConfig", "finite_array", "first_difference", "float_array",
           "index_array", "integer", "number_array", "one_line", "param", "parse_json", "positive",
           "real", "torch_load_problem", "unknown_key_message", "vec2"]


class ConfigError(ValueError):
    """A configuration value is missing, of the wrong type or out of its valid range."""


def unknown_key_message(key: Any, valid: Iterable[str], what: str = "config keyword") -> str:
    """The error text for an unknown ``key``: a did-you-mean suggestion and the valid names."""
    names = list(valid)
    close = difflib.get_close_matches(str(key), names, n=1)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    return f"unknown {what} {key!r}{hint} (valid: {', '.join(names)})"


def keyword_names(function: Callable[..., Any]) -> tuple[str, ...]:
    """The names ``function`` takes as keywords (not ``self``, not ``**kwargs``)."""
    kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    return tuple(name for name, p in inspect.signature(function).parameters.items()
                 if p.kind in kinds and name != "self")


_COLOUR_CODE = re.compile(r"\x1b\[[0-9;]*m")


def one_line(error: BaseException | str) -> str:
    """The text of ``error`` (an exception from a library, or a string) on one line: runs of
    whitespace, line breaks included, become one space and terminal colour codes go; an
    exception without text gives its type's name. For embedding in a one-line message."""
    text = " ".join(_COLOUR_CODE.sub("", str(error)).split())
    return text or (type(error).__name__ if isinstance(error, BaseException) else "")


def first_difference(recorded: Mapping[str, Any], current: Mapping[str, Any]
                     ) -> tuple[str, str, str, list[str]] | None:
    """Where two settings mappings differ: the first differing key in sorted order, its value
    in ``recorded`` and in ``current`` (``repr``, or "unset" where the key is missing) and the
    other differing keys; None when they agree."""
    keys = [k for k in sorted({*recorded, *current})
            if recorded.get(k, ...) != current.get(k, ...)]
    if not keys:
        return None
    def shown(mapping: Mapping[str, Any]) -> str:
        return repr(mapping[keys[0]]) if keys[0] in mapping else "unset"
    return keys[0], shown(recorded), shown(current), keys[1:]


def parse_json(text: str) -> Any:
    """``text`` parsed as strict JSON (``NaN`` and ``Infinity``, Python's extensions, refused);
    a ValueError with a one-line reason for anything unreadable, also for nesting too deep for
    the parser or an integer longer than Python converts (which escape ``json.loads`` as
    RecursionError and a bare ValueError)."""
    def refuse(name: str) -> Any:
        raise ValueError(f"{name} is not a JSON value")

    try:
        return json.loads(text, parse_constant=refuse)
    except RecursionError:
        raise ValueError("nested too deeply to read") from None
    except ValueError as exc:
        raise ValueError(one_line(exc)) from None


def torch_load_problem(error: BaseException) -> str:
    """Why ``torch.load(..., weights_only=True)`` refused a file, on one line. Of a weights-only
    refusal (a pickle of Python objects, or no pickle at all) only torch's reason is kept: its
    text around it advises ``weights_only=False``, which would run code from the file."""
    lines = [line.strip() for line in _COLOUR_CODE.sub("", str(error)).splitlines()
             if line.strip()]
    if not lines or not lines[0].startswith("Weights only load failed"):
        return one_line(error)
    marker = "WeightsUnpickler error:"
    text = "\n".join(lines[1:])
    if marker in text:        # the reason's line, then how to allowlist it: its first sentence
        reason = (text.split(marker, 1)[1].strip().splitlines() or [""])[0].split(". ")[0]
    else:                          # the reason on lines of its own between torch's advice
        reason = " ".join(line for line in lines[1:] if not line.startswith(
            ("(1)", "(2)", "Please file an issue", "Check the documentation")))
    return f"weights-only load refused: {one_line(reason.rstrip('.'))}" if reason \
        else "weights-only load refused"


# --- numbers -----------------------------------------------------------------------------------
def argparse_number(kind: type, low: float, low_open: bool = False,
                    high: float | None = None) -> Callable[[str], Any]:
    """An argparse ``type``: a finite ``kind`` (int or float) >= ``low`` (> ``low`` if
    ``low_open``) and <= ``high`` where given. argparse's one-line error names the flag; the
    message says what is valid."""
    def parse(text: str) -> Any:
        try:
            value = kind(text)
        except ValueError:
            value = None
        if value is None or not math.isfinite(value) or value < low or (low_open and
                                                                         value == low) or (
                high is not None and value > high):
            what = "an integer" if kind is int else "a finite number"
            if high is None:
                valid = f"{'>' if low_open else '>='} {low:g}"
            else:   # an integer bound in full (2**32 - 1, not 4.29497e+09)
                top = high if kind is int else f"{high:g}"
                valid = f"in {'(' if low_open else '['}{low:g}, {top}]"
            raise argparse.ArgumentTypeError(f"must be {what} {valid}, got {text!r}")
        return value
    parse.__name__ = kind.__name__
    return parse


def _interval(low: float | None, high: float | None, low_open: bool, high_open: bool) -> str:
    left = "(" if low_open or low is None else "["
    right = ")" if high_open or high is None else "]"
    lo = "-inf" if low is None else f"{low}"
    hi = "inf" if high is None else f"{high}"
    return f"{left}{lo}, {hi}{right}"


def _is_number(value: Any) -> bool:
    return isinstance(value, Real) and not isinstance(value, (bool, np.bool_))


def real(name: str, value: Any, unit: str = "", *, low: float | None = None,
         high: float | None = None, low_open: bool = False, high_open: bool = False,
         doc: str = "", error: type[Exception] = ValueError) -> float:
    """``value`` as a Python float when it is a finite real number in the range (see the
    module docstring); else ``error`` naming ``name``, the range, ``unit`` and ``doc``."""
    if type(value) is float or _is_number(value):     # a Python float skips the ABC test
        v = float(value)
        if math.isfinite(v) and not (
                (low is not None and (v <= low if low_open else v < low))
                or (high is not None and (v >= high if high_open else v > high))):
            return v
    _fail(name, value, unit, low, high, low_open, high_open, doc, error, "a number")


def integer(name: str, value: Any, unit: str = "", *, low: float | None = None,
            high: float | None = None, doc: str = "",
            error: type[Exception] = ValueError) -> int:
    """``value`` as a Python int when it is a whole real number in [low, high]; else ``error``
    naming ``name`` (see :func:`real`)."""
    if _is_number(value) and (isinstance(value, Integral) or float(value).is_integer()):
        v = int(value)
        if (low is None or v >= low) and (high is None or v <= high):
            return v
    _fail(name, value, unit, low, high, False, False, doc, error, "an integer")


def positive(name: str, value: Any, unit: str = "", *, high: float | None = None,
             error: type[Exception] = ValueError) -> float:
    """``value`` as a float when it is a finite real number > 0 (and <= ``high``)."""
    return real(name, value, unit, low=0.0, low_open=True, high=high, error=error)


def number_array(name: str, value: Any, unit: str = "") -> np.ndarray:
    """``value`` as a float64 array when its entries are numbers (integers or floats: not
    booleans, strings or objects); else a ValueError naming ``name``. NaN and infinities
    pass (see :func:`finite_array`)."""
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be an array of numbers ({one_line(exc)})") from None
    if raw.dtype.kind not in "iuf":
        raise ValueError(f"{name} must be an array of numbers{_unit(unit)}, got dtype "
                         f"{raw.dtype}")
    return raw.astype(np.float64, copy=False)


def index_array(name: str, value: Any, size: int) -> np.ndarray:
    """``value`` as an (n,) int64 array of distinct indices in [0, ``size``); else a ValueError
    naming ``name`` (floats, even whole ones, booleans and negative indices are refused: an
    index must not be rounded or wrap around)."""
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be an array of indices ({one_line(exc)})") from None
    if raw.dtype.kind not in "iu" and raw.size:
        raise ValueError(f"{name} must be integer indices in [0, {size}), got dtype {raw.dtype}")
    if raw.ndim > 1:
        raise ValueError(f"{name} must be a 1-D array of indices, got shape {raw.shape}")
    index = raw.reshape(-1).astype(np.int64)
    outside = (index < 0) | (index >= size)
    if outside.any():
        raise ValueError(f"{name} must be indices in [0, {size}), got {index[outside][0]}")
    if len(np.unique(index)) < len(index):
        raise ValueError(f"{name} must not repeat an index")
    return index


def finite_array(name: str, value: Any, unit: str = "", shape: tuple[int | None, ...] | None
                 = None) -> np.ndarray:
    """:func:`number_array` with every entry finite and, when ``shape`` is given, of that
    shape (None: any length on that axis); else a ValueError naming ``name``."""
    array = number_array(name, value, unit)
    if shape is not None and (array.ndim != len(shape) or any(
            want is not None and got != want for got, want in zip(array.shape, shape,
                                                                  strict=True))):
        axes = ", ".join("n" if n is None else str(n) for n in shape)
        raise ValueError(f"{name} must be an array of shape ({axes}){_unit(unit)}, got "
                         f"shape {array.shape}")
    if not np.isfinite(array).all():
        raise ValueError(f"{name} must be finite{_unit(unit)} (no NaN or infinity)")
    return array


def float_array(name: str, value: Any, error: type[Exception] = ValueError) -> np.ndarray:
    """``value`` as a float64 array (``np.asarray``); ``error`` naming ``name`` when its
    entries are not numbers (strings, objects, ragged lists)."""
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise error(f"{name} must be an array of numbers ({one_line(exc)})") from None


def vec2(name: str, value: Any, unit: str = "", *,
         error: type[Exception] = ValueError) -> tuple[float, float]:
    """A pair of finite real numbers (a sequence or a (2,) array) as two Python floats."""
    # the usual cases first, in a few operations: a (2,) float64 array, two Python floats
    if type(value) is np.ndarray and value.shape == (2,) and value.dtype == np.float64:
        x, y = value.tolist()
        if -math.inf < x < math.inf and -math.inf < y < math.inf:
            return x, y
    elif type(value) is tuple and len(value) == 2:
        x, y = value
        if type(x) is float and type(y) is float and -math.inf < x < math.inf \
                and -math.inf < y < math.inf:
            return x, y
    items = value.tolist() if isinstance(value, np.ndarray) and value.shape == (2,) else value
    if isinstance(items, (list, tuple)) and len(items) == 2 and all(
            _is_number(v) and math.isfinite(float(v)) for v in items):
        return float(items[0]), float(items[1])
    shape = getattr(value, "shape", None)
    got = f"shape {shape}" if shape is not None else repr(value)
    raise error(f"{name} must be a pair of finite numbers{_unit(unit)}, got {got}")


def _unit(unit: str) -> str:
    return f" ({unit})" if unit else ""


def _fail(name: str, value: Any, unit: str, low: float | None, high: float | None,
          low_open: bool, high_open: bool, doc: str, error: type[Exception], what: str) -> Any:
    interval = _interval(low, high, low_open, high_open)
    units = f" {unit}" if unit else ""
    meaning = f" ({doc})" if doc else ""
    raise error(f"{name}={value!r} must be {what} in {interval}{units}{meaning}")


# --- validated config dataclasses ---------------------------------------------------------------
def param(default: Any, doc: str, *, unit: str = "", low: float | None = None,
          high: float | None = None, low_open: bool = False, high_open: bool = False,
          kind: str = "float", optional: bool = False, choices: tuple[str, ...] = ()) -> Any:
    """A config field with its meaning, unit and valid values as metadata. ``kind``: float,
    int, bool, str (a path or a name), choice (one of ``choices``), range (a (min, max) pair in
    the range), point (a pair of numbers)."""
    meta = {"doc": doc, "unit": unit, "low": low, "high": high, "low_open": low_open,
            "high_open": high_open, "kind": kind, "optional": optional, "choices": choices}
    if isinstance(default, (list, tuple)):
        return field(default=tuple(default), metadata=meta)
    return field(default=default, metadata=meta)


def _valid_text(meta: dict[str, Any]) -> str:
    if meta["kind"] == "choice":
        return " | ".join(meta["choices"])
    if meta["low"] is None and meta["high"] is None:
        return meta["kind"]
    return _interval(meta["low"], meta["high"], meta["low_open"], meta["high_open"])


def _validate(f: dataclasses.Field, value: Any) -> Any:
    """The value of field ``f`` checked against its metadata; :class:`ConfigError` naming it."""
    meta, name, kind = f.metadata, f.name, f.metadata["kind"]
    if value is None:
        if meta["optional"]:
            return None
        raise ConfigError(f"{name} must not be None ({meta['doc']})")
    number = {"unit": meta["unit"], "low": meta["low"], "high": meta["high"],
              "doc": meta["doc"], "error": ConfigError}
    interval = {"low_open": meta["low_open"], "high_open": meta["high_open"]}
    if kind == "bool":
        if not isinstance(value, (bool, np.bool_)):
            raise ConfigError(f"{name}={value!r} must be True or False")
        return bool(value)
    if kind == "str":
        if not isinstance(value, (str, Path)):
            raise ConfigError(f"{name}={value!r} must be a path or a name")
        return str(value)
    if kind == "choice":
        if value not in meta["choices"]:
            raise ConfigError(f"{name}={value!r} must be one of {', '.join(meta['choices'])} "
                              f"({meta['doc']})")
        return str(value)
    if kind in ("range", "point"):
        if isinstance(value, np.ndarray):
            value = value.tolist()
        if not isinstance(value, (list, tuple)) or len(value) != 2:
            raise ConfigError(f"{name}={value!r} must be a pair of numbers")
        if kind == "point":
            return tuple(real(name, v, meta["unit"], error=ConfigError) for v in value)
        return tuple(real(name, v, **number, **interval) for v in value)
    if kind == "int":
        return integer(name, value, **number)
    return real(name, value, **number, **interval)


Config = TypeVar("Config", bound="ValidatedConfig")


class ValidatedConfig:
    """Base of the config dataclasses (``@dataclass(frozen=True)`` subclasses whose fields are
    declared with :func:`param`): every field is validated on construction, then
    :meth:`_check` (a subclass's checks across fields) runs."""

    #: What the config is called in error messages ("config keyword", "safety keyword", ...).
    KEYWORD: ClassVar[str] = "config keyword"

    def __new__(cls, *args: Any, **kwargs: Any) -> Any:
        """Unknown keywords get a did-you-mean :class:`ConfigError` (before the dataclass's
        ``__init__`` would raise a bare TypeError)."""
        names = [f.name for f in dataclasses.fields(cls)]
        for key in kwargs:
            if key not in names:
                raise ConfigError(unknown_key_message(key, names, cls.KEYWORD))
        return super().__new__(cls)

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            object.__setattr__(self, f.name, _validate(f, getattr(self, f.name)))
        self._check()

    def _check(self) -> None:
        """Checks across fields (none by default); raise :class:`ConfigError`."""

    @classmethod
    def from_kwargs(cls: type[Config], **kwargs: Any) -> Config:
        """Build a config from keywords; unknown keywords get a did-you-mean error (as from
        the constructor itself)."""
        return cls(**kwargs)

    @classmethod
    def coerce(cls: type[Config], value: Any, name: str) -> Config:
        """``value`` as a config: the config itself, a mapping of its keywords, or None (the
        defaults); :class:`ConfigError` naming ``name`` otherwise."""
        if value is None:
            return cls()
        if isinstance(value, cls):
            return value
        if isinstance(value, Mapping):
            keys = [k for k in value if not isinstance(k, str)]
            if keys:        # ** raised a bare "keywords must be strings", naming nothing
                raise ConfigError(f"{name}: keys must be {cls.__name__}'s keyword names "
                                  f"(strings), got {keys[0]!r}")
            return cls.from_kwargs(**value)
        raise ConfigError(f"{name} must be a {cls.__name__} or a mapping of its keywords, got "
                          f"{type(value).__name__}")

    def replace(self: Config, **kwargs: Any) -> Config:
        """A copy with some fields changed (validated like :meth:`from_kwargs`)."""
        return self.from_kwargs(**{**self.to_dict(), **kwargs})

    def to_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)

    @classmethod
    def describe(cls) -> list[tuple[str, Any, str, str]]:
        """(name, default, unit, doc) of every field, for docs and `--help` tables."""
        return [(f.name, f.default, f.metadata["unit"], f.metadata["doc"])
                for f in dataclasses.fields(cls)]

    @classmethod
    def markdown(cls) -> str:
        """The parameter table of the config's docs page (a test keeps the two identical)."""
        rows = ["| parameter | default | unit | valid | meaning |", "|---|---|---|---|---|"]
        for f in dataclasses.fields(cls):
            meta = f.metadata
            valid = _valid_text(meta) + (" or None" if meta["optional"] else "")
            rows.append(f"| `{f.name}` | {f.default!r} | {meta['unit']} | {valid} | "
                        f"{meta['doc']} |")
        return "\n".join(rows)
