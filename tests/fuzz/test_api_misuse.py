"""The API misuse families' oracle (tests/fuzz/api_runners.py): it fails a call that is taken
although it must be refused, refused although it must be taken, or refused unclearly."""

from __future__ import annotations

import pytest
from gymnasium.error import ResetNeeded

from tests.fuzz import api_cases
from tests.fuzz.api_runners import _Judge


def _raise(exc: Exception):
    def fn():
        raise exc

    return fn


def test_the_oracle_fails_what_is_taken_or_refused_wrongly() -> None:
    judge = _Judge()
    with pytest.raises(AssertionError, match="accepted although it must be refused"):
        judge.call("x", True, False, lambda: 1)
    with pytest.raises(AssertionError, match="accepted although the env needs a reset"):
        judge.call("x", None, True, lambda: 1)
    with pytest.raises(AssertionError, match="refused a valid call"):
        judge.call("x", False, False, _raise(ValueError("no")))
    with pytest.raises(AssertionError, match="ResetNeeded without a reason"):
        judge.call("x", None, False, _raise(ResetNeeded("reset")))
    with pytest.raises(AssertionError, match="not ResetNeeded"):
        judge.call("x", False, True, _raise(ValueError("a valid call needing a reset")))
    with pytest.raises(AssertionError, match="not one short line"):
        judge.call("x", True, False, _raise(ValueError("two\nlines")))
    with pytest.raises(TypeError):  # anything else is left as it is: a finding
        judge.call("x", True, False, _raise(TypeError("'list' object has no attribute 'keys'")))
    assert judge.refusals == []
    assert judge.call("x", None, False, lambda: 1) == 1
    assert judge.call("x", True, True, _raise(ResetNeeded("reset first"))) is None
    with pytest.raises(ResetNeeded, match="reset first"):
        judge.end()  # the case counts as a clean error


def test_the_families_are_seeded_and_reach_every_hostile_value() -> None:
    assert api_cases.race_api_cases(3, 20) == api_cases.race_api_cases(3, 20)
    assert api_cases.localization_api_cases(3, 20) != api_cases.localization_api_cases(4, 20)
    race = api_cases.race_api_cases(1, 1000)
    values = [op["actions"].get("value") for c in race for op in c["ops"] if "actions" in op]
    assert all(v in values for v, _ in api_cases.VALUES)
    loc = api_cases.localization_api_cases(1, 300)
    kinds = {op["options"].get("init_pose") for c in loc for op in c["ops"] if "options" in op}
    assert set(api_cases._POSES) <= kinds
    assert {c["wraps"] for c in loc} == {"single", "vector", "race", "none"}
