"""The racing opponents' pieces: where cars are on the track (Traffic), where a lane fits
(LaneRoom), and the driver's choices (follow, pass, give way, hold the line) on a circular track;
then races on basement_loop where they follow, pass and give way without contact."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from racecar_sim.maps import resolve_map
from racecar_sim.race.lanes import LaneRoom
from racecar_sim.race.racing_driver import RacingDriver
from racecar_sim.race.racing_rules import RacingRules
from racecar_sim.race.traffic import Traffic
from racecar_sim.settings.config import CarParams
from racecar_sim.world.centerline import centerline_for_map
from racecar_sim.world.track import Track, with_widths

CAR = CarParams()
RADIUS = 10.0
_ANGLES = np.linspace(0.0, 2 * math.pi, 252, endpoint=False)
CIRCLE = np.stack([RADIUS * np.cos(_ANGLES), RADIUS * np.sin(_ANGLES)], axis=1)  # anticlockwise


def circle(half_width: float, narrow: tuple[float, float] | None = None) -> Track:
    """The circle track, ``half_width`` metres free each side (0.35 m on the arc lengths
    ``narrow`` when given)."""
    widths = np.full((len(CIRCLE), 2), half_width)
    if narrow is not None:
        s = Track(CIRCLE).length * _ANGLES / (2 * math.pi)
        widths[(s >= narrow[0]) & (s < narrow[1])] = 0.35
    return Track(CIRCLE, widths)


def pose(track: Track, s: float, lateral: float = 0.0) -> np.ndarray:
    """The rear-axle pose ``lateral`` metres left of the track at arc length ``s``, along it."""
    return np.array([*track.offset_point(s, lateral), track.heading_at(s)])


def traffic(track: Track, cars: list[tuple[float, float, float]]) -> Traffic:
    """Traffic of cars at (s, lateral, speed along the track), the speeds seen over 0.1 s."""
    t = Traffic(track, len(cars), CAR, smoothing=1.0)
    t.reset(np.array([pose(track, s - 0.1 * v, lat) for s, lat, v in cars]))
    t.update(np.array([pose(track, s, lat) for s, lat, _ in cars]), 0.1)
    return t


# ---------------------------------------------------------------------- the track's frame
def test_locate_gives_arc_length_and_the_side() -> None:
    track = circle(1.0)
    angle = 1.0
    inside = (RADIUS - 0.3) * np.array([math.cos(angle), math.sin(angle)])  # left of anticlockwise
    outside = (RADIUS + 0.2) * np.array([math.cos(angle), math.sin(angle)])
    s, lateral, _ = track.locate(np.array([inside, outside]))
    assert s == pytest.approx([track.length * angle / (2 * math.pi)] * 2, abs=0.02)
    assert lateral == pytest.approx([0.3, -0.2], abs=0.01)
    back = track.offset_point(s[0], lateral[0])
    assert back == pytest.approx(inside, abs=1e-6)


@given(st.lists(st.floats(0.0, 62.0), min_size=2, max_size=6))
def test_gaps_point_from_each_car_to_every_other(arc) -> None:
    track = circle(1.0)
    t = Traffic(track, len(arc), CAR)
    t.reset(np.array([pose(track, s) for s in arc]))
    half = track.length / 2
    assert (np.abs(t.gaps) <= half).all()
    assert np.allclose(np.mod(t.s[:, None] + t.gaps - t.s[None, :] + half, track.length), half)
    apart = np.abs(np.abs(t.gaps) - half) > 1e-6  # not exactly half a lap apart
    assert np.allclose((t.gaps + t.gaps.T)[apart], 0.0)


def test_speeds_are_the_progress_seen_between_updates() -> None:
    track = circle(1.0)
    t = Traffic(track, 2, CAR)
    t.reset(np.array([pose(track, 0.0), pose(track, 30.0, 0.3)]))
    for k in range(1, 41):  # 1 s: car 0 at 2 m/s, car 1 backwards at 0.5 m/s, across the seam
        time = 0.025 * k
        t.update(np.array([pose(track, 2.0 * time), pose(track, 30.0 - 0.5 * time, 0.3)]), time)
    assert t.speed == pytest.approx([2.0, -0.5], abs=0.02)
    assert t.gaps[0, 1] == pytest.approx(30.0 - 0.5 - 2.0, abs=0.05)


def test_a_lane_reaches_as_far_as_the_track_is_wide_enough() -> None:
    track = circle(1.0, narrow=(20.0, 30.0))
    room = LaneRoom(track, CAR.width, 0.12)
    centre, aside = room.reach(10.0, np.array([0.0, 0.5]), horizon=25.0)
    assert centre == 25.0  # 0.35 m each side holds a car on the centerline
    assert aside == pytest.approx(10.0, abs=0.5)  # up to the narrow part
    assert room.reach(25.0, np.array([0.5]), 25.0)[0] == 0.0
    assert room.reach(40.0, np.array([-0.5, 0.5]), 10.0) == pytest.approx([10.0, 10.0])


# ---------------------------------------------------------------------- the choices
def test_a_driver_follows_a_slower_car_where_it_cannot_pass() -> None:
    narrow = circle(0.35)
    close = RacingDriver(
        traffic(narrow, [(5.0, 0.0, 2.5), (5.0 + CAR.length + 1.0, 0.0, 2.0)]), 0, 3.0
    )
    assert close.decide() < 2.0  # closer than its safe gap: slower than the car ahead
    assert close.target == 0.0
    far = RacingDriver(
        traffic(narrow, [(5.0, 0.0, 2.5), (5.0 + CAR.length + 6.0, 0.0, 2.0)]), 0, 3.0
    )
    assert far.decide() == 3.0  # a long gap: its own speed
    stuck = RacingDriver(
        traffic(narrow, [(5.0, 0.0, 0.5), (5.0 + CAR.length + 0.1, 0.0, 0.0)]), 0, 3.0
    )
    assert stuck.decide() == 0.0  # bumper to bumper behind a stopped car


def test_a_driver_moves_to_a_free_lane_to_pass_where_the_track_is_wide() -> None:
    rules = RacingRules()
    wide = circle(1.0)
    driver = RacingDriver(
        traffic(wide, [(5.0, 0.0, 2.5), (5.0 + CAR.length + 1.0, 0.0, 2.0)]), 0, 3.0
    )
    speed = driver.decide()
    assert abs(driver.target) >= CAR.width + rules.side_gap  # clear of the car it passes
    assert speed > 2.0


def test_a_pass_is_not_started_into_a_narrowing() -> None:
    track = circle(1.0, narrow=(12.0, 30.0))  # 5 m of wide track ahead, then narrow
    driver = RacingDriver(
        traffic(track, [(5.0, 0.0, 2.5), (5.0 + CAR.length + 1.0, 0.0, 2.0)]), 0, 3.0
    )
    assert driver.decide() < 2.0
    assert driver.target == 0.0


@pytest.mark.parametrize(("behind", "away"), [(0.0, -1), (0.3, -1), (-0.3, 1)])
def test_a_car_with_another_close_behind_makes_room_on_the_other_side(behind, away) -> None:
    cars = [(5.0, behind, 2.5), (5.0 + CAR.length + 1.0, 0.0, 2.0)]
    leader = RacingDriver(traffic(circle(1.0), cars), 1, 2.0)
    leader.decide()
    assert np.sign(leader.target) == away
    held = RacingDriver(traffic(circle(0.35), cars), 1, 2.0)
    held.decide()
    assert held.target == 0.0  # too narrow to make room


def test_a_driver_does_not_cut_in_front_of_a_car_beside_it() -> None:
    rules = RacingRules()
    cars = [(10.0, 0.45, 2.0), (9.8, -0.1, 2.5)]  # car 1 beside car 0, just behind
    driver = RacingDriver(traffic(circle(1.0), cars), 0, 2.0)
    driver.decide()
    assert driver.target >= -0.1 + CAR.width + rules.side_gap - 1e-9


def test_the_last_check_stops_short_of_a_car_across_the_lane() -> None:
    track = circle(1.0)
    t = Traffic(track, 2, CAR)
    across = pose(track, 6.0)
    across[2] += math.pi / 2
    t.reset(np.array([pose(track, 5.0), across]))
    driver = RacingDriver(t, 0, 3.0)
    assert driver.clear_speed() < 2.0
    t.reset(np.array([pose(track, 5.0), pose(track, 6.0, 0.6)]))
    assert driver.clear_speed() == math.inf  # beside the lane


def test_rules_refuse_bad_numbers_naming_them() -> None:
    with pytest.raises(ValueError, match=r"RacingRules\.headway"):
        RacingRules(headway=-1.0)
    with pytest.raises(ValueError, match="min_gap"):
        RacingRules(min_gap=1.0, standstill_gap=0.5)
    with pytest.raises(ValueError, match=r"RacingDriver\.rules"):
        RacingDriver(traffic(circle(1.0), [(0.0, 0.0, 0.0)]), 0, rules={"lane_stp": 0.1})
    with pytest.raises(ValueError, match=r"RacingDriver\.index"):
        RacingDriver(traffic(circle(1.0), [(0.0, 0.0, 0.0)]), 1)


def test_a_track_without_widths_gets_them_measured_on_the_map() -> None:
    line = Track(centerline_for_map("basement_loop").points)  # as from a two-column CSV
    measured = with_widths(line, resolve_map("basement_loop")).widths
    assert measured is not None and measured.shape == line.points.shape
    across = measured.sum(axis=1)
    assert (across > 1.5).all() and (across < 2.3).all()  # the map's corridors: 1.7-2.1 m
    assert with_widths(circle(1.0), resolve_map("basement_loop")).widths.max() == 1.0  # kept
