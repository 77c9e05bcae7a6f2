"""Tracks (f1tenth CSV, derived from a loop map), laps, lap times, rank, and the grid."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
from race_helpers import QUIET, hall_map

from racecar_sim.race.env import RaceEnv
from racecar_sim.world.centerline import centerline_for_map
from racecar_sim.world.laps import LapCounter
from racecar_sim.world.track import MAX_TRACK_BYTES, Track


def circle(radius: float = 5.0, n: int = 400) -> Track:
    a = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
    return Track(np.stack([radius * np.cos(a), radius * np.sin(a)], axis=1))


def test_f1tenth_centerline_csv_loads_as_it_is(tmp_path):
    # f1tenth's racetrack format: a '#' header line, then x_m, y_m, w_tr_right_m, w_tr_left_m.
    path = tmp_path / "Track_centerline.csv"
    rows = ["# x_m,y_m,w_tr_right_m,w_tr_left_m"]
    a = np.linspace(0, 2 * math.pi, 50, endpoint=False)
    rows += [f"{10 * math.cos(t):.4f},{6 * math.sin(t):.4f},1.1,0.9" for t in a]
    path.write_text("\n".join(rows) + "\n")
    track = Track.from_csv(path)
    assert track.points.shape == (50, 2)
    assert track.width_at(3.0) == (1.1, 0.9)
    # An ellipse 10 x 6: Ramanujan's perimeter, less the polygon's shortfall (50 chords).
    h = ((10 - 6) / (10 + 6)) ** 2
    perimeter = math.pi * (10 + 6) * (1 + 3 * h / (10 + math.sqrt(4 - 3 * h)))
    assert track.length == pytest.approx(perimeter, rel=0.005)
    back = Track.from_csv(track.to_csv(tmp_path / "again.csv"))
    np.testing.assert_allclose(back.points, track.points, atol=1e-4)


def test_bad_track_files_are_named(tmp_path):
    with pytest.raises(ValueError, match=r"missing\.csv: not found"):
        Track.from_csv(tmp_path / "missing.csv")
    bad = tmp_path / "bad.csv"
    bad.write_text("# x_m,y_m\n1,2\nthree,4\n5,6\n")
    with pytest.raises(ValueError, match=r"bad\.csv: rows must be numbers"):
        Track.from_csv(bad)


def test_a_track_file_is_read_in_bounded_work(tmp_path):
    big = tmp_path / "big.csv"
    row = "1.0000,2.0000,0.5000,0.5000\n"
    big.write_text(row * (MAX_TRACK_BYTES // len(row) + 1))  # just over the limit
    with pytest.raises(ValueError, match=r"big\.csv: more than 1,000,000 bytes"):
        Track.from_csv(big)
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)  # opening it would wait for a writer forever
    for path in (fifo, tmp_path, "/dev/zero"):
        with pytest.raises(ValueError, match="not a regular file"):
            Track.from_csv(path)


def test_race_env_on_an_endless_track_file_is_one_clear_error():
    with pytest.raises(ValueError, match="track file /dev/zero: not a regular file"):
        RaceEnv("basement_loop", n_cars=2, track="/dev/zero")


def _drive(counter: LapCounter, angles: np.ndarray, dt: float = 0.1) -> None:
    for k, a in enumerate(angles, start=1):
        counter.update(np.array([[5 * math.cos(a), 5 * math.sin(a)]]), k * dt, dt)


def test_laps_and_lap_times_on_a_circle():
    track = circle()
    laps = LapCounter(track, 1)
    start = -0.05  # just behind the start line (angle 0 is the first point)
    laps.reset(np.array([[5 * math.cos(start), 5 * math.sin(start)]]))
    # 2.5 laps at 0.02 rad per 0.1 s step: a lap is 2 pi / 0.2 = 31.4 s (the first one 0.25 s more).
    angles = start + 0.02 * np.arange(1, int(2.5 * 2 * math.pi / 0.02))
    _drive(laps, angles)
    assert laps.laps[0] == 2
    lap_s = 2 * math.pi / 0.2
    np.testing.assert_allclose(laps.lap_times[0], [lap_s + 0.05 / 0.2, lap_s], rtol=1e-3)
    info = laps.info(laps.ranks(), 0)
    assert all(type(t) is float for t in info["lap_times"])  # printed as 31.66, not np.float64(...)
    assert "np." not in repr(info)
    assert info["progress"] == pytest.approx(
        track.length * (angles[-1] - start) / (2 * math.pi), rel=1e-3
    )


def test_driving_backwards_over_the_line_is_not_a_lap():
    laps = LapCounter(circle(), 1)
    laps.reset(np.array([[5.0 * math.cos(0.3), 5.0 * math.sin(0.3)]]))  # 0.3 rad past the line
    back = np.linspace(0.3, -0.6, 50)  # backwards over the line
    fwd = np.linspace(-0.6, 0.5, 60)  # forwards over it again
    _drive(laps, np.concatenate([back, fwd, back[::-1][:1]]))
    assert laps.laps[0] == 0 and laps.lap_times[0] == []
    # Backwards a whole lap, then forwards: still none until it passes where it had been + a lap.
    laps.reset(np.array([[5.0, 0.0]]))
    _drive(laps, np.linspace(0.0, -2 * math.pi - 0.5, 400))
    _drive(laps, np.linspace(-2 * math.pi - 0.5, 0.2, 400))
    assert laps.laps[0] == 0
    _drive(laps, np.linspace(0.2, 2 * math.pi + 0.1, 400))
    assert laps.laps[0] == 1


def test_rank_follows_the_distance_along_the_track():
    laps = LapCounter(circle(), 3)
    laps.reset(np.array([[5 * math.cos(a), 5 * math.sin(a)] for a in (-0.1, -0.2, -0.3)]))
    assert laps.ranks().tolist() == [1, 2, 3]
    # car 2 overtakes both
    laps.update(
        np.array([[5 * math.cos(a), 5 * math.sin(a)] for a in (-0.05, -0.15, 0.1)]), 1.0, 1.0
    )
    assert laps.ranks().tolist() == [2, 3, 1]


def test_derived_centerline_of_the_loop_map_keeps_off_the_walls():
    from racecar_sim.maps import resolve_map

    track = centerline_for_map("basement_loop")
    grid = resolve_map("basement_loop")
    clearance = grid.distance_at(track.points)
    assert clearance.min() > 0.6  # the hallways are ~2 m wide: the line keeps to their middle
    assert track.widths is not None and (track.widths.sum(axis=1) > 1.4).all()


def test_race_on_the_loop_counts_laps_and_the_grid_starts_behind_the_line():
    from racecar_sim.drivers import PurePursuit

    env = RaceEnv("basement_loop", n_cars=3, n_beams=61, **QUIET)
    obs, infos = env.reset(seed=0)
    track = env.track
    assert [infos[a]["rank"] for a in env.agents] == [1, 2, 3]
    s = [track.project(infos[a]["pose"][:2])[0] for a in env.agents]
    assert all(v > track.length / 2 for v in s)  # all behind the line (s wraps to the end)
    # Pole alone drives a lap at 4 m/s on pure pursuit.
    poses = env.poses
    env2 = RaceEnv("basement_loop", n_cars=1, n_beams=61, **QUIET)
    obs, infos = env2.reset(seed=0, options={"poses": poses[:1]})
    driver = PurePursuit(track.points, speed=4.0, loop=True, car=env.car_params)
    for _ in range(1400):  # 35 s
        obs, _, term, _, infos = env2.step({"car_0": driver(obs["car_0"], infos["car_0"]["pose"])})
        assert not term["car_0"]
        if infos["car_0"]["lap"] == 1:
            break
    assert infos["car_0"]["lap"] == 1
    lap_time = infos["car_0"]["lap_times"][0]
    # the lap from the grid: the track length (plus pole's distance to the line) at <= 4 m/s
    assert track.length / 4.0 < lap_time < track.length / 4.0 * 1.25
    # progress: from the grid slot to the line, then a lap (and at most one step of 10 cm past)
    to_line = track.length - s[0]
    assert 0 <= infos["car_0"]["progress"] - (to_line + track.length) < 0.11


def test_the_single_env_on_a_track_reports_laps_too(tmp_path):
    from racecar_sim.env import RacecarEnv

    track = centerline_for_map("basement_loop")
    csv = track.to_csv(tmp_path / "loop.csv")
    env = RacecarEnv("basement_loop", track=str(csv), n_beams=61)
    s0 = 5.0
    xy = track.point_at(s0)
    _, info = env.reset(seed=0, options={"pose": [xy[0], xy[1], track.heading_at(s0)]})
    assert (info["progress"], info["lap"], info["lap_times"], info["rank"]) == (0.0, 0, [], 1)
    for _ in range(20):
        _, _, _, _, info = env.step([0.0, 2.0])
    assert info["progress"] == pytest.approx(float(np.sum(0)) + info["time"] * 2.0, abs=0.4)


def test_the_single_env_takes_track_auto_as_the_race_does():
    import gymnasium as gym

    from racecar_sim.env import RacecarEnv

    env = gym.make("RacecarSim-v0", map="basement_loop", track="auto", n_beams=61).unwrapped
    race = RaceEnv("basement_loop", n_cars=1, n_beams=61)  # its default on a loop map
    np.testing.assert_array_equal(env.track.points, race.track.points)
    np.testing.assert_array_equal(env.track.points, centerline_for_map("basement_loop").points)
    track = env.track
    xy = track.point_at(5.0)
    _, info = env.reset(seed=0, options={"pose": [xy[0], xy[1], track.heading_at(5.0)]})
    assert (info["progress"], info["lap"], info["lap_times"], info["rank"]) == (0.0, 0, [], 1)
    for _ in range(20):
        _, _, _, _, info = env.step([0.0, 2.0])
    assert info["progress"] > 0.5
    with pytest.raises(ValueError, match="'hall' is not a loop map"):
        RacecarEnv(hall_map(), track="auto")


def test_the_grid_start_ignores_the_last_race_s_ghost_boxes():
    # car_1 left where the pole's slot is, next to the pole: its ghost box sits in car_0's pymunk
    # space at the slot; the next reset onto the grid must still find the slot free.
    env = RaceEnv("basement_loop", n_cars=4, n_beams=61, terminate_on_collision=False)
    env.reset(seed=0)
    grid = env.poses
    ahead = np.array([math.cos(grid[0, 2]), math.sin(grid[0, 2])])
    poses = grid.copy()
    poses[0, :2] += 0.65 * ahead  # the pole 0.65 m ahead of its slot
    poses[1] = grid[0]  # car_1 on the pole's slot, right behind it
    env.reset(seed=0, options={"poses": poses})
    env.step({a: np.zeros(2) for a in env.agents})
    assert (0, 1) in env.world.contacts._shown  # car_1's ghost is in car_0's space
    env.reset(seed=1)
    np.testing.assert_array_equal(env.poses, grid)
