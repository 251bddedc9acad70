"""The package's layers point down, and no module imports itself through others.

Every import of ``aoass_env`` and ``agents`` modules counts: at module level, inside functions
(lazy imports) and under ``TYPE_CHECKING``. The layers, bottom up (the developers' guide,
"Shape of the code"): pure maths and infrastructure -> config -> maps, radio, world, network,
beacon logs -> planning -> simulator -> environment and wrappers -> localization ->
evaluation; ``agents`` stands beside evaluation and never imports it.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("aoass_env", "agents")

#: Layer of each module by its longest matching name prefix (0 = bottom).
LAYERS = {
    "aoass_env.atomic": 0, "aoass_env.metrics": 0, "aoass_env.trajectory": 0,
    "aoass_env.pairwise": 0, "aoass_env.jit": 0,
    "aoass_env.backends": 0, "aoass_env.data": 0, "aoass_env.safety": 0, "aoass_env.validators": 0,
    "aoass_env.trig": 0, "aoass_env.segments": 0,
    "aoass_env.localization.multilateration": 0, "aoass_env.localization.ragged": 0,
    "aoass_env.config": 1,
    "aoass_env.maps": 2, "aoass_env.clearance": 2, "aoass_env.radio": 2, "aoass_env.world": 2,
    "aoass_env.rays": 2,
    "aoass_env.network": 2, "aoass_env.beacon_log": 2,
    "aoass_env.planning": 3,
    "aoass_env.simulator": 4,
    "aoass_env.env": 5, "aoass_env.action": 5, "aoass_env.observation": 5, "aoass_env.reward": 5,
    "aoass_env.render": 5, "aoass_env.wrappers": 5, "aoass_env.registration": 5,
    "aoass_env.localization": 6,
    "aoass_env.evaluation": 7,
    "agents": 7,
    "aoass_env": 8,            # the package itself re-exports the public names
}


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for package in PACKAGES
            for p in sorted((ROOT / package).rglob("*.py"))}


def _imports(name: str, path: Path, known: set[str]) -> set[str]:
    """The project modules ``name`` imports anywhere in its source."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            targets = [base] + [f"{base}.{alias.name}" for alias in node.names]
        for target in targets:
            while target and target not in known:
                target = target.rpartition(".")[0]
            if target and target != name:
                found.add(target)
    return found


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    return {name: _imports(name, path, set(modules)) for name, path in modules.items()}


def _layer(name: str) -> int:
    return LAYERS[_prefix(name)]


def _prefix(name: str) -> str:
    return max((p for p in LAYERS if name == p or name.startswith(p + ".")), key=len)


def test_every_module_has_a_layer_of_its_own():
    """Each module falls under a named layer, not only under its package root (a new module
    must be placed in the table, or it would pass as the top layer)."""
    assert sorted(n for n in _graph() if n != "aoass_env" and _prefix(n) == "aoass_env") == []


def test_imports_point_down():
    upward = sorted(f"{a} (layer {_layer(a)}) imports {b} (layer {_layer(b)})"
                    for a, deps in _graph().items() for b in deps if _layer(b) > _layer(a))
    assert upward == []


def test_agents_never_import_the_evaluation():
    graph = _graph()
    assert sorted((a, b) for a, deps in graph.items() if a.startswith("agents")
                  for b in deps if b.startswith("aoass_env.evaluation")) == []


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_import_cycles():
    assert _cycles(_graph()) == []


@pytest.mark.parametrize("graph, cycle", [
    ({"a": {"b"}, "b": {"a"}}, [["a", "b"]]),
    ({"a": {"b"}, "b": {"c"}, "c": set()}, []),
    ({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}, [["a", "b", "c"]]),
])
def test_the_cycle_finder_finds_cycles(graph, cycle):
    assert _cycles(graph) == cycle


def test_the_graph_sees_lazy_and_type_checking_imports():
    graph = _graph()
    # a function-level import (the policy's algorithms, loaded only when used)
    assert "agents.hyperparams" in graph["aoass_env.evaluation.methods"]
    # a TYPE_CHECKING import
    assert "aoass_env.localization.episode" in graph["aoass_env.localization.dvhop"]
