"""The documentation site builds with ``mkdocs build --strict``: a broken link, a link to a
missing anchor, or an API reference to a name that does not exist fails the suite. (A page not yet
in the nav is reported, not failed, so that a new page can land before its nav entry.)"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def test_every_nav_entry_is_a_page() -> None:
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8").split("\nnav:", 1)[1]
    listed = set(re.findall(r":\s*([\w/.-]+\.md)\s*$", nav, re.M))
    pages = {p.relative_to(ROOT / "docs").as_posix() for p in (ROOT / "docs").rglob("*.md")}
    assert len(listed) >= 10 and listed - pages == set(), "nav entries without a page"


def test_mkdocs_build_strict(tmp_path: Path) -> None:
    pytest.importorskip("mkdocs", reason="mkdocs is not installed (pip install -e '.[docs]')")
    pytest.importorskip("material", reason="mkdocs-material is not installed (extra [docs])")
    pytest.importorskip("mkdocstrings", reason="mkdocstrings is not installed (extra [docs])")
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
        env={k: v for k, v in os.environ.items() if "MKDOCS_2_WARNING" not in k},
    )
    assert result.returncode == 0, result.stderr[-3000:]
    # the build prints its own lines only: no theme banner (mkdocs-material 9.7 on adds one)
    assert "zensical" not in (result.stdout + result.stderr).lower()
    assert (tmp_path / "site" / "index.html").is_file()
    assert (tmp_path / "site" / "api" / "mcl" / "index.html").is_file()
    raw = re.compile(r":(?:class|func|meth|mod|data|attr|exc|obj):(?:`|<code>)")
    pages = sorted((tmp_path / "site").rglob("*.html"))
    assert len(pages) > 20
    shown = [p.relative_to(tmp_path / "site").as_posix() for p in pages if raw.search(p.read_text("utf-8"))]
    assert shown == [], f"pages that show a raw Sphinx role instead of a link: {shown}"


def test_docstrings_use_mkdocstrings_cross_references_not_sphinx_roles() -> None:
    """The API pages render [Name][module.Name]; a Sphinx role would show as raw text."""
    raw = re.compile(r":(?:class|func|meth|mod|data|attr|exc|obj):`")
    found = [
        f"{path.relative_to(ROOT)}:{n}"
        for folder in ("mcl", "racecar_sim", "scripts")
        for path in sorted((ROOT / folder).rglob("*.py"))
        for n, line in enumerate(path.read_text("utf-8").splitlines(), 1)
        if raw.search(line)
    ]
    assert found == [], found
