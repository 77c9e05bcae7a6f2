"""The search filter watching on after a jump (``LostParams.search_watch``), on an honest kidnap:
the car in ``basement_fixed_aligned.yaml`` with the cluttered scene and the ``mit_racecar``
noise, the filter holding the out-of-date ``stata_basement.yaml``, the defaults.

Cluttered kidnap seed 3 (carried at 10 s, the filter's third draw, seed + 2000): the first burst
finds a place 17 m from the car whose fit (0.92) takes the flag down 0.3 s after the kidnap, and
the search settles on it too. Ended there, the search leaves the filter on that place until its
fit collapses 6 s later, and the bursts then take a place 85 m off; watching on, the search
keeps its other places, moves to the car's as the drive refutes the first (6.5 s after the
kidnap), and the filter takes it (found 6.9 s after the kidnap where measured)."""

from __future__ import annotations

import math

import pytest

from mcl.experiments.lost_flag import time_to_find
from mcl.experiments.recorded import RecordedDrive, localize_recorded
from tests.honest_world import honest_drive

KIDNAP_AT = 10.0


@pytest.fixture(scope="module")
def kidnap_drive() -> RecordedDrive:
    return honest_drive("cluttered", seed=3, duration=30.0, kidnap_at=KIDNAP_AT)


def _found_after(drive: RecordedDrive, settings: dict | None) -> float:
    """Seconds from the kidnap until the error stays under 0.5 m for 2 s (NaN: never)."""
    run = localize_recorded(drive, settings, seed=3 + 2000)
    return time_to_find(drive.time, run.position_error, KIDNAP_AT, 2.0)


def test_a_search_that_watches_on_finds_the_car_a_look_alike_held(kidnap_drive) -> None:
    assert _found_after(kidnap_drive, None) <= 15.0


def test_a_search_that_ends_on_the_look_alike_leaves_the_filter_there(kidnap_drive) -> None:
    assert math.isnan(_found_after(kidnap_drive, {"lost": {"search_watch": False}}))
