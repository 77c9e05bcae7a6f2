"""docs/settings.md shows the bounds tables as the code holds them."""

from __future__ import annotations

from pathlib import Path

from mcl.experiments.run_bounds import RUN_BOUNDS
from mcl.filter.bounds import FILTER_BOUNDS
from racecar_sim.settings.bounds import RULES, markdown_table

DOC = Path(__file__).resolve().parents[2] / "docs" / "settings.md"


def test_the_page_shows_the_bounds_the_code_checks() -> None:
    text = DOC.read_text()
    assert markdown_table() in text
    assert markdown_table(FILTER_BOUNDS) in text
    assert markdown_table(RUN_BOUNDS) in text
    for rule, reason in RULES:
        assert f"| `{rule}` | {reason} |" in text
