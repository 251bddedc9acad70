"""A module of this repository as it was at an earlier commit, for the benchmarks that time the
current code against it in one process (``reset.py``, ``detour_search.py``), why git
cannot give one (``lookahead_speed.py`` and the replay benchmarks), and the order in which
a benchmark's sides run in each of its timing rounds (:func:`in_turn`).

The benchmark scripts import it as a sibling (``python3 benchmarks/<name>.py`` puts their folder
first on ``sys.path``).
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path
from types import ModuleType
from typing import TypeVar

T = TypeVar("T")

ROOT = Path(__file__).resolve().parents[1]


def git_problem(ref: str, path: str) -> str | None:
    """Why ``git show REF:path`` cannot read ``path`` (relative to the repository root) as of
    commit ``ref``, on one line, or None when it can."""
    try:
        if subprocess.run(["git", "rev-parse", "--verify", "--quiet", "--end-of-options",
                           f"{ref}^{{commit}}"], cwd=ROOT, capture_output=True).returncode:
            return "no such commit in this repository"
        if subprocess.run(["git", "cat-file", "-e", f"{ref}:{path}"], cwd=ROOT,
                          capture_output=True).returncode:
            return f"has no {path} (it predates it)"
    except OSError as err:
        return f"cannot run git ({err.strerror or err})"
    return None


def module_at(commit: str, path: str, folder: Path) -> ModuleType:
    """The module ``path`` (relative to the repository root) as it was at ``commit``, written to
    ``folder`` and imported under its own name (its imports are today's tree's); SystemExit
    with one line when git cannot read it there (:func:`git_problem`)."""
    problem = git_problem(commit, path)
    if problem:
        raise SystemExit(f"--against {commit}: {problem}")
    try:
        source = subprocess.run(["git", "show", f"{commit}:{path}"], cwd=ROOT, check=True,
                                capture_output=True, text=True).stdout
    except (OSError, subprocess.CalledProcessError) as err:
        raise SystemExit(f"--against {commit}: cannot read {path} there with git ({err})") \
            from None
    file = folder / f"{Path(path).stem}_{commit}.py"
    file.write_text(source)
    spec = importlib.util.spec_from_file_location(f"at_{commit}_{Path(path).stem}", file)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module        # dataclasses look their module up while it runs
    spec.loader.exec_module(module)
    return module


def in_turn(round_: int, *sides: T) -> list[T]:
    """``sides`` in the order they run in timing round ``round_`` (0, 1, ...): rotated left by
    ``round_`` places, so each side runs first once every ``len(sides)`` rounds (with two, the
    first side leads the even rounds and the second the odd ones): none always pays or gains
    from going first (caches, the machine's drift)."""
    k = round_ % len(sides)
    return [*sides[k:], *sides[:k]]
