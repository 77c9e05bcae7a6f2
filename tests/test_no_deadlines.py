"""No property test has a hypothesis deadline: the first call of a numba kernel compiles it or loads it
from the on-disk cache, which takes a third of a second on a fresh machine and would fail the test."""

from __future__ import annotations

import ast
from pathlib import Path

from hypothesis import settings

TESTS = Path(__file__).resolve().parent


def test_the_loaded_profile_has_no_deadline() -> None:
    assert settings.default.deadline is None


def _deadlines(source: str) -> list[tuple[int, str]]:
    """(line, value) of every ``deadline=`` given to hypothesis' ``settings`` (a call or a profile)."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.Call):
            continue
        func = node.func
        name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
        if name not in ("settings", "register_profile"):
            continue
        for keyword in node.keywords:
            if keyword.arg == "deadline" and not (
                isinstance(keyword.value, ast.Constant) and keyword.value.value is None
            ):
                found.append((node.lineno, ast.unparse(keyword.value)))
    return found


def test_the_scan_finds_a_deadline() -> None:
    source = "@settings(max_examples=5, deadline=200)\ndef t(): ...\nx = dict(deadline=3)\n"
    assert _deadlines(source) == [(1, "200")]
    assert _deadlines("@settings(deadline=None)\ndef t(): ...\n") == []


def test_no_test_sets_a_deadline() -> None:
    offenders = [
        f"{path.relative_to(TESTS)}:{line}: deadline={value}"
        for path in sorted(TESTS.rglob("*.py"))
        for line, value in _deadlines(path.read_text(encoding="utf-8"))
    ]
    assert not offenders, "tests with a hypothesis deadline: " + "; ".join(offenders)
