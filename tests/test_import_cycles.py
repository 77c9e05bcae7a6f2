"""No two modules of racecar_sim and mcl import each other, directly or around a longer loop.

Every import counts: at the top, inside a function, and under ``if TYPE_CHECKING:`` (a cycle hidden
there is still two modules that need each other; the shared classes belong in a module below both).
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("racecar_sim", "mcl")


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imported(tree: ast.AST, name: str, is_package: bool, known: set[str]) -> set[str]:
    """Modules of ``known`` that the module ``name`` imports anywhere in ``tree``."""
    package = name if is_package else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            found.add(module)
            found.update(f"{module}.{alias.name}" for alias in node.names)  # from pkg import mod
    return {m for m in found if m in known and m != name}


def import_graph() -> dict[str, set[str]]:
    files = [f for package in PACKAGES for f in (ROOT / package).rglob("*.py")]
    names = {module_name(f): f for f in files}
    known = set(names)
    return {
        name: imported(ast.parse(f.read_text(encoding="utf-8")), name, f.name == "__init__.py", known)
        for name, f in names.items()
    }


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
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
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_scan_sees_the_packages() -> None:
    graph = import_graph()
    assert "mcl.experiments.runner" in graph["mcl.experiments.noise_sweep"]
    assert "racecar_sim.maps.grid" in graph["racecar_sim.maps"]


def test_the_scan_finds_a_cycle_hidden_behind_type_checking() -> None:
    tree = ast.parse("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from b import B\n")
    graph = {"a": imported(tree, "a", False, {"a", "b"}), "b": {"a"}}
    assert cycles(graph) == [["a", "b"]]
    inner = ast.parse("def f():\n    from .b import g\n")  # a function-level relative import
    assert imported(inner, "p.a", False, {"p.a", "p.b"}) == {"p.b"}


def test_no_import_cycles() -> None:
    found = cycles(import_graph())
    assert found == [], "modules that import each other: " + "; ".join(" <-> ".join(c) for c in found)
