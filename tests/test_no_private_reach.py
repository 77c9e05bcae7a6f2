"""No module of racecar_sim or mcl reaches into another object's underscore names.

A class's ``_name`` is its own business: ``self._name`` and ``cls._name`` (and ``super()._name``,
the same object's inherited member) are fine; ``other._name`` is not, whether ``other`` is another
object of ours, a module (``argparse._HelpAction``) or a library's object. What another class needs
belongs to the owner's public face (a method or property named by what it does). Dunder names
(``obj.__class__``) are public by Python's own rules.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("racecar_sim", "mcl")
OWN = ("self", "cls")


def is_private(name: str) -> bool:
    """An underscore name that is not a dunder."""
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def is_own(node: ast.expr) -> bool:
    """``self``, ``cls`` or ``super()``: the object whose class the code belongs to."""
    if isinstance(node, ast.Name):
        return node.id in OWN
    return (
        isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "super"
    )


def reach_ins(source: str) -> list[tuple[int, str]]:
    """(line, ``obj._name``) of every attribute access to another object's underscore name."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Attribute) and is_private(node.attr) and not is_own(node.value):
            found.append((node.lineno, ast.unparse(node)))
    return sorted(found)


def package_reach_ins() -> list[str]:
    hits = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            rel = path.relative_to(ROOT)
            for line, text in reach_ins(path.read_text(encoding="utf-8")):
                hits.append(f"{rel}:{line}: {text}")
    return hits


@pytest.mark.parametrize(
    ("source", "expected"),
    [
        ("self._a = 1\ncls._b\nsuper()._c()", []),
        ("other._a", [(1, "other._a")]),
        ("self.physics._free[0] = 1", [(1, "self.physics._free")]),
        ("obj.__class__\nobj.public\nobj._", [(3, "obj._")]),
        ("argparse._HelpAction", [(1, "argparse._HelpAction")]),
        ("f()._x\nitems[0]._y", [(1, "f()._x"), (2, "items[0]._y")]),
    ],
)
def test_reach_ins_are_found(source: str, expected: list[tuple[int, str]]) -> None:
    assert reach_ins(source) == expected


def test_no_module_reaches_into_another_objects_underscore_names() -> None:
    hits = package_reach_ins()
    assert not hits, (
        f"{len(hits)} private reach-ins (add a public method or property):\n" + "\n".join(hits)
    )
