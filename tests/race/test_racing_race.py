"""RacecarRace-v0 with opponents that race: the grid, following where the track is too narrow,
passing where it is wide, passing a parked car."""

from __future__ import annotations

import numpy as np

from racecar_sim.race.single import RacecarRaceEnv
from racecar_sim.world.centerline import centerline_for_map
from racecar_sim.world.track import Track

PARKED = np.zeros(2, dtype=np.float32)


def _car_contacts(env: RacecarRaceEnv) -> list[str]:
    return [c for info in env.car_infos.values() for c in info["contacts"] if c != "wall"]


def _race(env: RacecarRaceEnv, seconds: float, options=None) -> tuple[list[np.ndarray], list[str]]:
    """Car 0 parked; returns each step's progress along the track (unwrapped) and every contact."""
    env.reset(seed=0, options=options)
    counter = env.race.laps
    u, contacts = [], []
    for _ in range(round(seconds / env.race.dt)):
        _, _, terminated, _, info = env.step(PARKED)
        u.append(counter.u.copy())
        contacts += _car_contacts(env) + [c for c in info["contacts"] if c == "wall"]
        assert not terminated
    return u, contacts


def test_the_grid_is_single_file_slowest_first_and_the_agent_last() -> None:
    env = RacecarRaceEnv("basement_loop", opponents=3, opponent_speeds=[2.8, 2.0, 2.4], n_beams=61)
    _, info = env.reset(seed=0)
    track = env.track
    s, lateral, _ = track.locate(np.vstack([info["pose"][:2], info["opponent_poses"][:, :2]]))
    ahead = np.array([track.advance(s[0], v) for v in s])  # metres ahead of the agent
    assert list(np.argsort(-ahead)) == [2, 3, 1, 0]  # 2.0 m/s on pole, then 2.4, 2.8, the agent
    assert np.abs(lateral).max() < 1e-6
    assert (ahead[1:] > 0).all() and (np.diff(np.sort(ahead)) > env.car_params.length).all()


def test_a_faster_opponent_follows_where_the_track_is_too_narrow_to_pass() -> None:
    line = centerline_for_map("basement_loop").points
    narrow = Track(line, np.full((len(line), 2), 0.4))  # room for one car
    env = RacecarRaceEnv("basement_loop", opponents=2, opponent_speeds=[2.0, 3.0], track=narrow,
                         terminate_on_collision=False, n_beams=61)  # fmt: skip
    u, contacts = _race(env, 30.0)
    u = np.array(u)
    assert contacts == []
    assert (u[:, 2] < u[:, 1]).all()  # never passes
    assert u[-1, 2] - u[0, 2] > 0.9 * (u[-1, 1] - u[0, 1])  # but keeps up


def test_a_faster_opponent_passes_where_the_track_is_wide() -> None:
    env = RacecarRaceEnv("basement_loop", opponents=2, opponent_speeds=[2.0, 3.0],
                         terminate_on_collision=False, n_beams=61)  # fmt: skip
    u, contacts = _race(env, 30.0)
    assert contacts == []
    assert u[0][2] < u[0][1] and u[-1][2] > u[-1][1] + 5.0


def test_opponents_pass_a_parked_agent_without_touching_it() -> None:
    env = RacecarRaceEnv("basement_loop", opponents=2, opponent_speeds=[2.4, 3.0],
                         terminate_on_collision=False, n_beams=61)  # fmt: skip
    track = env.track
    grid = env.grid.copy()
    s_park = 15.0  # the agent parked 0.25 m left of the centerline, 15 m past the start line
    grid[0] = [*track.offset_point(s_park, 0.25), track.heading_at(s_park)]
    u, contacts = _race(env, 20.0, options={"poses": grid})
    assert contacts == []
    assert (u[-1][1:] > u[-1][0] + 2.0).all()  # both got by
