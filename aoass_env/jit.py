"""Compiled kernels: numba's ``njit`` with an on-disk cache that is invalidated when a module the
kernel's module imports changes, not only its own file.

numba's cache (``cache=True``) keys a compiled function by its own source file alone: "changes
in symbols defined in a different file" are not detected (numba's documentation, "Cache
invalidation"). A kernel that calls a kernel of another module, or reads a constant imported
from one, is compiled with that module's code and values frozen in; after the other module
changes (a ``git pull``, an edited checkout, a package upgrade that keeps ``__pycache__``), the
stale machine code was loaded as it was: old numbers without a word, or a crash such as
``NRT_adapt_ndarray_to_python`` when a structure's layout changed.

:func:`njit` (``numba.njit(cache=True, ...)``) stamps every cached kernel of a tracked package
(:func:`track`; ``aoass_env`` is tracked on import) with the SHA-256 of the source of its own
module and of every module of the package the module imports, transitively. numba drops a
cache entry whose stamp differs, so a change in any of them recompiles the kernel on its next
load, and a change elsewhere (the evaluation, the agent) does not. Where the cache lives is
numba's choice as before (``__pycache__`` beside the source, else the user-wide cache, or
``NUMBA_CACHE_DIR``); the stamp changes, and the file names carry numba's version, so that two
environments with different numba versions sharing a checkout never read each other's files.
"""

from __future__ import annotations

import functools
import hashlib
import os
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numba
from numba.core import caching

__all__ = ["import_closure", "njit", "source_stamp", "track"]

#: Tracked packages: top-level name -> its folder (resolved).
_PACKAGES: dict[str, Path] = {}

# numba 0.59 names its locators with a leading underscore; later versions without.
_CacheImpl = getattr(caching, "CacheImpl", None) or caching._CacheImpl
_CacheLocator = caching._CacheLocator


def track(name: str, root: str | Path) -> None:
    """Stamp the cached kernels of package ``name`` (top-level, folder ``root``) with their
    import closure's source (module docstring). Idempotent."""
    if not re.fullmatch(r"[A-Za-z_]\w*", name):
        raise ValueError(f"track: name must be a top-level package name, got {name!r}")
    folder = Path(root).resolve()
    if not (folder / "__init__.py").is_file():
        raise ValueError(f"track: root {str(root)!r} holds no __init__.py (not a package folder)")
    _PACKAGES[name] = folder
    for memo in (_module_file, _imports, import_closure):
        memo.cache_clear()


@functools.cache
def _module_file(name: str) -> Path | None:
    """The source file of module ``name`` of a tracked package, or None (not a module of one)."""
    top, _, rest = name.partition(".")
    root = _PACKAGES.get(top)
    if root is None:
        return None
    base = root.joinpath(*rest.split(".")) if rest else root
    for candidate in (base.with_suffix(".py"), base / "__init__.py"):
        if candidate.is_file():
            return candidate
    return None


@functools.cache
def _imports(module: str) -> frozenset[str]:
    """The modules of ``module``'s package named by the import statements of its source:
    ``import P.a.b`` gives ``P.a.b``; ``from P.a import x`` gives ``P.a.x`` where that is a
    module, else ``P.a`` (where ``x`` is defined or re-exported). Statements anywhere in the
    file count (function-level imports, ``TYPE_CHECKING`` blocks): an over-approximation is
    safe, a missed module is not."""
    path = _module_file(module)
    if path is None:
        return frozenset()
    text = path.read_text(encoding="utf-8")
    p = re.escape(module.partition(".")[0])
    found: set[str] = set()
    for m in re.finditer(r"^[ \t]*import[ \t]+([^\n#;]+)", text, re.M):
        for part in m.group(1).split(","):
            words = part.split()
            if words and re.fullmatch(rf"{p}(?:\.\w+)*", words[0]):
                found.add(words[0])
    for m in re.finditer(rf"^[ \t]*from[ \t]+({p}(?:\.\w+)*)[ \t]+import[ \t]*"
                         r"(\([^)]*\)|[^\n#;]*)", text, re.M):
        parent = m.group(1)
        for part in m.group(2).strip("()").replace("\\\n", " ").split(","):
            words = part.split()
            if words and words[0].isidentifier():
                sub = f"{parent}.{words[0]}"
                found.add(sub if _module_file(sub) is not None else parent)
    return frozenset(found)


@functools.cache
def _file_digest(path: str, mtime_ns: int, size: int) -> bytes:
    """SHA-256 of a file's bytes (memoized by path, mtime and size, as numba does)."""
    return hashlib.sha256(Path(path).read_bytes()).digest()


def _digest(path: Path) -> bytes:
    st = os.stat(path)
    return _file_digest(str(path), st.st_mtime_ns, st.st_size)


@functools.cache
def import_closure(module: str) -> tuple[Path, ...]:
    """Source files (sorted) of ``module`` of a tracked package and of every module of that
    package it imports, transitively (:func:`_imports`). Empty when ``module`` is not in a
    tracked package."""
    seen: dict[str, Path] = {}
    todo = [module]
    while todo:
        name = todo.pop()
        path = _module_file(name)
        if path is None or name in seen:
            continue
        seen[name] = path
        todo.extend(_imports(name))
    return tuple(sorted(set(seen.values())))


def source_stamp(module: str) -> str:
    """Hex SHA-256 over the relative paths and contents of :func:`import_closure` (``module``)."""
    files = import_closure(module)
    if not files:
        raise ValueError(f"source_stamp: {module!r} is not a module of a tracked package "
                         f"(tracked: {', '.join(sorted(_PACKAGES)) or 'none'})")
    root = _PACKAGES[module.partition(".")[0]]
    h = hashlib.sha256()
    for path in files:
        h.update(path.relative_to(root).as_posix().encode() + b"\0" + _digest(path))
    return h.hexdigest()


class _ClosureStampLocator(_CacheLocator):
    """numba's own locator for a kernel of a tracked package (the first of numba's that takes
    it), with :func:`source_stamp` of the kernel's module added to the stamp."""

    def __init__(self, inner: Any, module: str) -> None:
        self._inner = inner
        self._module = module

    def ensure_cache_path(self) -> None:
        self._inner.ensure_cache_path()

    def get_cache_path(self) -> str:
        return self._inner.get_cache_path()

    def get_disambiguator(self) -> str:
        # numba's version in the file names: numba writes a kernel's index before its data file,
        # and numbers data files from 1 whatever the index's version, so a process reading the
        # index another process has just written loaded the data file that a different numba
        # left under the same name (two environments sharing a checkout: "LLVM bitcode parsing
        # error ... Producer: 'LLVM22.1.0' Reader: 'LLVM 14.0.6'")
        version = re.sub(r"\W", "_", numba.__version__)
        return f"{self._inner.get_disambiguator()}-numba{version}"

    def get_source_stamp(self) -> Any:
        return ("closure", self._inner.get_source_stamp(), source_stamp(self._module))

    @classmethod
    def from_function(cls, py_func: Callable[..., Any], py_file: str) -> Any:
        module = getattr(py_func, "__module__", None) or ""
        if module.partition(".")[0] not in _PACKAGES or not import_closure(module):
            return None
        for base in _NUMBA_LOCATORS:
            inner = base.from_function(py_func, py_file)
            if inner is not None:
                return cls(inner, module)
        return None


# by name, so that a reload of this module does not wrap its previous class
_NUMBA_LOCATORS = tuple(k for k in _CacheImpl._locator_classes
                        if k.__name__ != _ClosureStampLocator.__name__)
_CacheImpl._locator_classes = [_ClosureStampLocator, *_NUMBA_LOCATORS]


def njit(*args: Any, **kwargs: Any) -> Any:
    """``numba.njit`` with ``cache=True``, used bare (``@njit``) or with numba's options
    (``@njit(error_model="numpy")``); the cache entry is dropped when the kernel's import
    closure changes (module docstring)."""
    if "cache" in kwargs:
        raise TypeError("njit: cache is always on here; use numba.njit for an uncached kernel")
    return numba.njit(*args, cache=True, **kwargs)


track("aoass_env", Path(__file__).parent)
