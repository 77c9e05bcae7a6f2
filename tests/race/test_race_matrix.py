"""60 s races of 2-6 scripted cars on both bundled loop maps: no contact, and the faster cars
finish more laps (a subset; the full matrix of 1-5 opponents x 10 seeds x both maps is
scripts/race_matrix.py, its numbers in docs/racing.md)."""

from __future__ import annotations

import pytest

from racecar_sim.race.scripted_race import (
    ScriptedRaceResult,
    matrix_table,
    ordered_share,
    run_scripted_race,
    speed_order,
)


def _result(map_name: str, speeds, laps, progress, passes: int = 0) -> ScriptedRaceResult:
    return ScriptedRaceResult(map=map_name, opponents=len(speeds) - 1, seed=0, seconds=60.0,
                              speeds=tuple(speeds), laps=tuple(laps), progress=tuple(progress),
                              car_contacts=0, wall_contacts=0, passes=passes)  # fmt: skip


def test_the_share_in_speed_order_and_the_table_count_per_map_and_field() -> None:
    in_order = _result("a", (3.0, 2.0, 2.5), (2, 1, 1), (170.0, 120.0, 140.0), passes=3)
    one_swap = _result("a", (3.0, 2.0, 2.5), (1, 1, 1), (130.0, 120.0, 140.0), passes=2)
    assert speed_order(in_order) == [1, 2, 0]
    assert ordered_share(in_order) == 1.0
    assert ordered_share(one_swap) == pytest.approx(2 / 3)  # car 0 behind car 2
    other = _result("b", (2.4, 2.0), (1, 1), (140.0, 120.0), passes=1)
    rows = matrix_table([in_order, one_swap, other]).splitlines()[2:]
    assert [r.split("|")[1:4] for r in rows] == [[" a ", " 2 ", " 2 "], [" b ", " 1 ", " 1 "]]
    assert "| 1.0 / 1.0 / 1.5 |" in rows[0]  # laps, slowest to fastest, mean of the two
    assert "| 2.5 (2-3) |" in rows[0] and rows[0].endswith("| 83% |")


@pytest.mark.slow
@pytest.mark.parametrize(
    ("map_name", "opponents", "seed"),
    [("basement_loop", 3, 0), ("basement_loop", 5, 1), ("office", 2, 2), ("office", 4, 3)],
)
def test_scripted_races_have_no_contact_and_finish_in_order_of_speed(
    map_name, opponents, seed
) -> None:
    r = run_scripted_race(map_name, opponents, seed, 60.0, n_beams=61)
    assert (r.car_contacts, r.wall_contacts) == (0, 0)
    order = speed_order(r)
    laps = [r.laps[i] for i in order]
    progress = [r.progress[i] for i in order]
    assert laps == sorted(laps)  # a faster car never finishes fewer laps
    assert progress[-1] > progress[0] + 30.0  # laps are 50-81 m: equal laps are common
    assert r.passes >= opponents  # car 0 starts last and is the fastest: it passes them all


@pytest.mark.slow
def test_the_racing_pages_example_is_a_race() -> None:
    """docs/racing.md: three opponents at 2.0, 2.5 and 3.0 m/s on basement_loop, car 0 at
    3.5 m/s, from the grid behind the start line (slowest first, car 0 last)."""
    r = run_scripted_race("basement_loop", 3, 0, 60.0, speeds=(3.5, 2.0, 2.5, 3.0), drawn=False,
                          n_beams=61)  # fmt: skip
    assert (r.car_contacts, r.wall_contacts) == (0, 0)
    order = speed_order(r)
    assert [r.progress[i] for i in order] == sorted(r.progress)  # finished in order of speed
    assert r.passes >= 6  # so every faster car passed every slower one, which started ahead
