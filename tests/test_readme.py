"""The README's and the docs pages' Python examples run as written (so the documentation cannot
drift from the API).

Every ```python block of README.md and docs/*.md runs, in a fresh folder, unless the line before it
is an HTML comment ``<!-- not run: REASON -->`` saying why it cannot (needs torch, a cluster, ...).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
BLOCK = re.compile(r"(?:<!-- not run: (?P<reason>[^>]*?) -->\n)?```python\n(?P<code>.*?)```", re.S)


def blocks(page: Path) -> list[tuple[str, str | None]]:
    """(code, reason it is not run or None) of each python block of ``page``."""
    return [(m["code"], m["reason"]) for m in BLOCK.finditer(page.read_text(encoding="utf-8"))]


CASES = [
    pytest.param(page, index, code, reason, id=f"{page.relative_to(ROOT)}:{index}")
    for page in PAGES
    for index, (code, reason) in enumerate(blocks(page))
]


def test_readme_has_python_examples() -> None:
    assert len(blocks(ROOT / "README.md")) >= 1


def test_a_skip_marker_needs_a_reason() -> None:
    text = "<!-- not run: needs torch -->\n```python\nx = 1\n```\n```python\ny = 2\n```"
    assert [m["reason"] for m in BLOCK.finditer(text)] == ["needs torch", None]


@pytest.mark.parametrize(("page", "index", "code", "reason"), CASES)
def test_example_runs(
    page: Path, index: int, code: str, reason: str | None, tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    if reason is not None:
        assert reason.strip(), f"{page.name} block {index}: say why it is not run"
        pytest.skip(f"{page.name} block {index} is marked not run: {reason}")
    monkeypatch.chdir(tmp_path)  # examples may write logs relative to the working directory
    namespace: dict[str, object] = {"__name__": "readme_example"}
    exec(compile(code, f"{page.name} python block {index}", "exec"), namespace)
    if page.name == "README.md":
        assert "env" in namespace  # each README example builds an env and drives it
        left = sorted(p.name for p in tmp_path.iterdir())
        assert left in ([], ["out"]), f"the example leaves {left} in the checkout (write under out/)"
