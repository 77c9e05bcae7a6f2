"""A run drives at most a day of simulated time and a live view is paced at 0 or 0.01-1000 times
real time (mcl.experiments.run_bounds): 31 simulated years, or a pace that never passes the first step, are
refused in one line before anything runs."""

from __future__ import annotations

import argparse
import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mcl.experiments.opponents_run import OpponentRun
from mcl.experiments.run_bounds import MAX_DURATION, check_live_speed
from mcl.experiments.runs import RunSpec


@given(st.floats(allow_nan=True, allow_infinity=True))
def test_a_run_spec_takes_exactly_the_durations_of_a_day(duration: float) -> None:
    if 0 < duration <= MAX_DURATION:
        assert RunSpec(duration=duration).duration == duration
    else:
        with pytest.raises(ValueError, match=r"RunSpec\.duration = .* \(0, 86400\]"):
            RunSpec(duration=duration)


def test_31_simulated_years_are_refused_everywhere() -> None:
    with pytest.raises(ValueError, match="86400"):
        RunSpec(duration=1e9)
    with pytest.raises(ValueError, match=r"OpponentRun\.duration"):
        OpponentRun(duration=1e9)
    assert RunSpec(duration=MAX_DURATION).n_steps == round(MAX_DURATION / RunSpec().dt)


@given(st.floats(allow_nan=True, allow_infinity=True))
def test_live_speed_is_zero_or_a_pace_that_moves(speed: float) -> None:
    if speed == 0 or 0.01 <= speed <= 1000:
        assert check_live_speed("drive", speed) == speed
    else:
        with pytest.raises(ValueError, match=r"drive\.live_speed = .*\(or 0: unpaced\)"):
            check_live_speed("drive", speed)


def test_the_live_speed_bound_is_what_the_command_checks() -> None:
    from mcl.cli.common import live_speed

    assert live_speed("0") == 0 and live_speed("0.01") == 0.01
    refused = r"0 \(unpaced\) or in \[0.01, 1000\]"
    for text in ("1e-9", "-1", "nan", "1001"):
        with pytest.raises(argparse.ArgumentTypeError, match=refused):
            live_speed(text)
    assert not math.isnan(live_speed("1000"))


@pytest.mark.parametrize("filter_seed", [-1, 2.5, True, "3"])
def test_a_run_spec_takes_only_a_non_negative_whole_filter_seed(filter_seed) -> None:
    with pytest.raises(ValueError, match=r"RunSpec\.filter_seed = .* non-negative integer"):
        RunSpec(filter_seed=filter_seed)
    spec = RunSpec(seed=3, filter_seed=1003)
    assert spec.run_id == "run_seed3_filter1003" and RunSpec(seed=3).run_id == "run_seed3"
