"""aoass_env.jit: the compiled kernels' cache is dropped when a module they import changes.

numba's own cache keys a kernel by its file alone; the end-to-end test below edits a callee's
module and a constant's module of a throw-away package between processes and checks that the
caller returns the new answer (numba's plain ``cache=True`` returns the old one), and that an
unrelated edit keeps the cache.
"""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import numba
import pytest

import aoass_env
from aoass_env import jit

PACKAGE = Path(aoass_env.__file__).parent


def _modules() -> list[str]:
    names = []
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        names.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return names


def _ast_imports(module: str) -> set[str]:
    """The reference for jit._imports: the same rule, read from the syntax tree."""
    tree = ast.parse(jit._module_file(module).read_text(encoding="utf-8"))
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.split(".")[0] == "aoass_env"}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module \
                and node.module.split(".")[0] == "aoass_env":
            for a in node.names:
                sub = f"{node.module}.{a.name}"
                found.add(sub if jit._module_file(sub) is not None else node.module)
    return found


@pytest.mark.parametrize("module", _modules())
def test_imports_read_as_the_syntax_tree_reads_them(module):
    assert jit._imports(module) == _ast_imports(module)


def test_closure_follows_imports_transitively():
    closure = {p.relative_to(PACKAGE).as_posix()
               for p in jit.import_closure("aoass_env.safety.filter_period")}
    # filter_period calls orca's and unicycle's kernels, which call trig's
    assert {"safety/filter_period.py", "safety/orca.py", "safety/unicycle.py",
            "trig.py", "jit.py"} <= closure
    assert "evaluation/report.py" not in closure
    assert jit.import_closure("numpy") == ()


def test_every_kernel_of_the_package_goes_through_jit():
    offenders = [str(p.relative_to(PACKAGE)) for p in PACKAGE.rglob("*.py")
                 if p.name != "jit.py" and ("numba.njit" in (t := p.read_text(encoding="utf-8"))
                                            or "numba.jit" in t)]
    assert offenders == []


def test_bad_input_is_named():
    with pytest.raises(TypeError, match="cache is always on"):
        jit.njit(cache=False)
    with pytest.raises(ValueError, match="top-level package name"):
        jit.track("a.b", PACKAGE)
    with pytest.raises(ValueError, match="no __init__.py"):
        jit.track("nowhere", PACKAGE / "maps" / "generator.py")
    with pytest.raises(ValueError, match="not a module of a tracked package"):
        jit.source_stamp("numpy.linalg")


_PROBE = {
    "__init__.py": """
        from pathlib import Path
        from aoass_env.jit import track
        track("jitprobe", Path(__file__).parent)
        """,
    "constants.py": "SCALE = 2.0\n",
    "inner.py": """
        from aoass_env.jit import njit

        @njit
        def g(x):
            return x + 1.0
        """,
    "outer.py": """
        from aoass_env.jit import njit
        from jitprobe.constants import SCALE
        from jitprobe.inner import g

        @njit
        def f(x):
            return g(x) * SCALE
        """,
    "other.py": "UNRELATED = 1\n",
}

_RUN = """
import jitprobe.outer as o
print(o.f(1.0), sum(o.f.stats.cache_hits.values()))
"""


def _run(root: Path, numba_version: str | None = None) -> tuple[float, int]:
    """The probe's answer and cache hits in a fresh process; ``numba_version`` stands in for
    another numba installed in another environment sharing the checkout."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env.update(PYTHONPATH=os.pathsep.join([str(root), str(PACKAGE.parent)]),
               PYTHONDONTWRITEBYTECODE="1")
    fake = "" if numba_version is None else f"import numba; numba.__version__ = {numba_version!r}\n"
    out = subprocess.run([sys.executable, "-c", fake + _RUN], cwd=root, env=env,
                         capture_output=True, text=True, timeout=300, check=True).stdout.split()
    return float(out[0]), int(out[1])


def test_a_kernel_recompiles_when_a_module_it_imports_changes(tmp_path):
    pkg = tmp_path / "jitprobe"
    pkg.mkdir()
    for name, text in _PROBE.items():
        (pkg / name).write_text(textwrap.dedent(text), encoding="utf-8")
    assert _run(tmp_path) == (4.0, 0)            # compiled and written
    assert _run(tmp_path) == (4.0, 1)            # loaded from the cache
    (pkg / "inner.py").write_text(textwrap.dedent(_PROBE["inner.py"]).replace("1.0", "2.0"),
                                  encoding="utf-8")
    assert _run(tmp_path) == (6.0, 0)            # the callee's module changed
    (pkg / "constants.py").write_text("SCALE = 3.0\n", encoding="utf-8")
    assert _run(tmp_path) == (9.0, 0)            # the constant's module changed
    (pkg / "other.py").write_text("UNRELATED = 2\n", encoding="utf-8")
    assert _run(tmp_path) == (9.0, 1)            # not imported by outer: the cache stays


def test_two_numba_versions_sharing_a_checkout_keep_their_own_files(tmp_path):
    # numba writes a kernel's index before its data file and numbers data files from 1 whatever
    # version wrote them: with shared names, a process could read a fresh index pointing at the
    # other version's data (CI's lowest-versions venv hit LLVM's "bitcode parsing error" so),
    # and each version's run overwrote the other's index
    pkg = tmp_path / "jitprobe"
    pkg.mkdir()
    for name, text in _PROBE.items():
        (pkg / name).write_text(textwrap.dedent(text), encoding="utf-8")
    other = "0.0.1"
    assert _run(tmp_path, other) == (4.0, 0)
    assert _run(tmp_path) == (4.0, 0)
    assert _run(tmp_path, other) == (4.0, 1)     # the other version's index was left alone
    assert _run(tmp_path) == (4.0, 1)
    files = [p.name for p in (pkg / "__pycache__").iterdir() if p.suffix in (".nbi", ".nbc")]
    ours = "numba" + re.sub(r"\W", "_", numba.__version__)
    assert files and all(("numba0_0_1" in f) != (ours in f) for f in files), files
    assert {"numba0_0_1" in f for f in files} == {True, False}


def test_a_reload_keeps_one_closure_locator_in_front():
    import importlib

    from numba.core import caching
    impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl
    importlib.reload(jit)
    names = [k.__name__ for k in impl._locator_classes]
    assert names[0] == "_ClosureStampLocator" and names.count("_ClosureStampLocator") == 1
    assert jit.import_closure("aoass_env.pairwise")
