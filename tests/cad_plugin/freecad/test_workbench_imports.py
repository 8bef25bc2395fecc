"""The workbench's modules import each other along a DAG (no cycle), read from the source, no FreeCAD needed.

Units: none.

Every ``import`` and ``from ... import`` of ``cad_plugin/freecad/hyperstat_freecad`` is
collected with :mod:`ast`, including the ones inside functions (a lazy import is still an
arrow: it only hides a cycle until run time).  The graph must have no cycle, and the
layering the docstrings describe must hold: the view provider imports neither the panels
nor the commands, the operations import no GUI module.
"""

from __future__ import annotations

import ast
from pathlib import Path

from tests.conftest import ROOT

PACKAGE = ROOT / "cad_plugin" / "freecad" / "hyperstat_freecad"
NAME = "hyperstat_freecad"


def _module_of(node: ast.ImportFrom, module: str) -> list[str]:
    """Targets (workbench modules) of a ``from`` import inside ``module``."""
    if node.level:
        base = NAME  # every module of the package is top-level in it
        target = f"{base}.{node.module}" if node.module else base
    else:
        target = node.module or ""
    if not target.startswith(NAME):
        return []
    if target == NAME:  # from . import geometry
        return [f"{NAME}.{alias.name}" for alias in node.names]
    return [target]


def import_graph() -> dict[str, set[str]]:
    modules = {f"{NAME}.{p.stem}": p for p in PACKAGE.glob("*.py") if p.stem != "__init__"}
    graph: dict[str, set[str]] = {m: set() for m in modules}
    for module, path in modules.items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom):
                targets = _module_of(node, module)
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names if a.name.startswith(f"{NAME}.")]
            else:
                continue
            graph[module] |= {t for t in targets if t in modules and t != module}
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """A cycle as a list of modules (first == last), or None (depth-first search, three colours)."""
    colour = dict.fromkeys(graph, 0)
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        colour[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if colour[nxt] == 1:
                return stack[stack.index(nxt):] + [nxt]
            if colour[nxt] == 0:
                found = visit(nxt)
                if found:
                    return found
        stack.pop()
        colour[node] = 2
        return None

    for node in sorted(graph):
        if colour[node] == 0:
            found = visit(node)
            if found:
                return found
    return None


def test_the_cycle_finder_finds_a_planted_cycle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set(), "c": {"a", "b"}}) is None


def test_the_parser_sees_lazy_and_relative_imports():
    graph = import_graph()
    assert f"{NAME}.runner" in graph[f"{NAME}.operations"]  # from .runner import ...
    assert f"{NAME}.geometry" in graph[f"{NAME}.operations"]  # from . import geometry
    assert f"{NAME}.operations" in graph[f"{NAME}.panels"]  # imports inside methods count
    assert len(graph) >= 11


def test_workbench_imports_form_a_dag():
    graph = import_graph()
    assert find_cycle(graph) is None, find_cycle(graph)
    gui = {f"{NAME}.{m}" for m in ("panels", "commands", "jobs")}
    assert not graph[f"{NAME}.viewprovider"] & (gui | {f"{NAME}.operations"})
    assert not graph[f"{NAME}.operations"] & gui
    assert not graph[f"{NAME}.feature"] & ({f"{NAME}.operations"} | gui)
