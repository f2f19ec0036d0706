"""The core reads bottom-up: no module of fusionkit imports, at module level, one that (through others) imports it
back. Imports inside functions (lazy, e.g. of the pipeline by the CLI) are left out: they run after loading."""

from __future__ import annotations

import ast
from pathlib import Path

CORE = Path(__file__).resolve().parents[2] / "fusionkit"


def module_graph(root: Path) -> dict[str, set[str]]:
    """{module: the modules of the package it imports at module level} (`from . import x` counts as x)."""
    names = {}
    for p in root.rglob("*.py"):
        parts = p.relative_to(root.parent).with_suffix("").parts
        names[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = p
    graph: dict[str, set[str]] = {m: set() for m in names}
    for module, path in names.items():
        package = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, ast.ImportFrom):
                base = package[:len(package) - node.level + 1] if node.level else []
                target = ".".join(base + ([node.module] if node.module else []))
                submodules = [f"{target}.{a.name}" for a in node.names if f"{target}.{a.name}" in names]
                graph[module].update(submodules or ([target] if target in names else []))
            elif isinstance(node, ast.Import):
                graph[module].update(a.name for a in node.names if a.name in names)
        graph[module].discard(module)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))
    for v in graph:
        if v not in index:
            visit(v)
    return out


def test_the_core_has_no_import_cycle():
    graph = module_graph(CORE)
    assert len(graph) > 80 and "fusionkit.graph.builder" in graph["fusionkit.graph.context"]
    assert cycles(graph) == []


def test_a_cycle_is_found(tmp_path):
    package = tmp_path / "pkg"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "a.py").write_text("from .b import x\ny = 1\n")
    (package / "b.py").write_text("from . import c\nx = 2\n")
    (package / "c.py").write_text("from .a import y\n")
    assert cycles(module_graph(package)) == [["pkg.a", "pkg.b", "pkg.c"]]
