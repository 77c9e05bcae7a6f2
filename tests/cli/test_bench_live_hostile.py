"""The live-view benchmark's verdict allows for a noisy machine (mcl.bench.live_hostile)."""

from __future__ import annotations

import statistics

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mcl.bench.live_hostile import median_interval, verdict

ratios = st.lists(st.floats(0.5, 2.0), min_size=1, max_size=30)


@given(ratios)
def test_the_interval_holds_the_median_and_lies_within_the_rounds(values) -> None:
    low, high = median_interval(values)
    assert min(values) <= low <= statistics.median(values) <= high <= max(values)


def test_rounds_that_agree_give_a_narrow_interval_and_a_firm_verdict() -> None:
    assert median_interval([1.02] * 8) == (1.02, 1.02)
    assert verdict([1.01, 1.03, 1.02, 1.04, 1.00, 1.05]) == "met"
    assert verdict([1.21, 1.15, 1.18, 1.25, 1.16, 1.19]) == "NOT met"


def test_rounds_that_scatter_about_the_bound_are_not_resolved() -> None:
    # the 2-core VM's 20 s drives (2026-12-02, 10 quiet rounds): median 1.160, from 1.026 to 1.303
    rounds = [1.026, 1.235, 1.095, 1.136, 1.158, 1.255, 1.303, 1.166, 1.161, 1.140]
    assert verdict(rounds[:3]).startswith("not resolved")
    assert verdict(rounds) == "NOT met"


def test_no_rounds_is_an_error() -> None:
    with pytest.raises(ValueError, match="at least one"):
        median_interval([])
