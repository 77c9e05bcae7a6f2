"""No property test has a hypothesis deadline: the first call of a numba kernel compiles it or loads it
from the on-disk cache, which takes a third of a second on a fresh machine and would fail the test."""

from __future__ import annotations

import re
from pathlib import Path

from hypothesis import settings

TESTS = Path(__file__).resolve().parent


def test_the_loaded_profile_has_no_deadline() -> None:
    assert settings.default.deadline is None


def test_no_test_sets_a_deadline() -> None:
    offenders = []
    for path in sorted(TESTS.rglob("*.py")):
        if path == Path(__file__).resolve():
            continue
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            for value in re.findall(r"\bdeadline\s*=\s*([^,)\s]+)", line):
                if value != "None":
                    offenders.append(f"{path.relative_to(TESTS)}:{number}: deadline={value}")
    assert not offenders, "tests with a hypothesis deadline: " + "; ".join(offenders)
