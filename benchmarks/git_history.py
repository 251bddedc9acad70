"""A module of this repository as it was at an earlier commit, for the benchmarks that time the
current code against it in one process (``reset.py``, ``detour_search.py``).

The benchmark scripts import it as a sibling (``python3 benchmarks/<name>.py`` puts their folder
first on ``sys.path``).
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[1]


def module_at(commit: str, path: str, folder: Path) -> ModuleType:
    """The module ``path`` (relative to the repository root) as it was at ``commit``, written to
    ``folder`` and imported under its own name (its imports are today's tree's); SystemExit
    with one line when git cannot read it there."""
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
