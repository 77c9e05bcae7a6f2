"""Skips read the same everywhere: a missing file of ../shared by its resolved path, one install
hint for the [rl] extra (tests/skips.py holds both; no test words its own)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests.skips import RL_MISSING, SHARED, need_shared, shared_missing

TESTS = Path(__file__).resolve().parent
OWN_WORDING = re.compile(
    r"""(skip\(|reason=)\s*f?["'][^"']*(shared|stable-baselines3|\[rl\])""", re.IGNORECASE
)


def test_no_test_words_its_own_skip_for_shared_data_or_the_rl_extra() -> None:
    offenders = [
        f"{path.relative_to(TESTS)}:{n}"
        for path in sorted(TESTS.rglob("*.py"))
        if path.name not in ("skips.py", Path(__file__).name)
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1)
        if OWN_WORDING.search(line)
    ]
    assert offenders == []


def test_a_missing_shared_file_is_named_by_its_resolved_path() -> None:
    with pytest.raises(pytest.skip.Exception) as skipped:
        need_shared("maps/../maps/no_such_map.yaml")
    reason = str(skipped.value)
    assert (
        str((SHARED / "maps" / "no_such_map.yaml").resolve()) in reason
        and ".." not in reason.split(":")[0]
    )
    assert reason == shared_missing(SHARED / "maps" / "no_such_map.yaml")
    assert RL_MISSING.endswith("pip install torch==2.13.0 -e '.[rl]'")
