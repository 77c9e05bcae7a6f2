"""RacecarRace-v0: one agent against scripted opponents, as a plain Gymnasium env."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import racecar_sim  # noqa: F401 - registers the envs
from tests.gym_checks import check_env_as_designed


def test_check_env_passes():
    env = gym.make("RacecarRace-v0", map="basement_loop", opponents=2, n_beams=61)
    check_env_as_designed(env.unwrapped, skip_render_check=True)


def test_opponents_race_on_their_own_drivers():
    env = gym.make(
        "RacecarRace-v0", map="basement_loop", opponents=2, opponent_driver=["pure_pursuit", "wall_follower"],
        opponent_speeds=[1.5, 2.0], n_beams=61,  # the blind pure pursuit slower, on pole
    )  # fmt: skip
    _, info = env.reset(seed=1)
    start = info["opponent_poses"].copy()
    for _ in range(80):  # 2 s, car 0 stays on the grid
        _, _, term, _, info = env.step(np.array([0.0, 0.0], dtype=np.float32))
        assert not term
    moved = np.hypot(*(info["opponent_poses"][:, :2] - start[:, :2]).T)
    assert (moved > 1.0).all()  # both opponents are racing


def test_make_vec_works():
    vec = gym.make_vec("RacecarRace-v0", num_envs=2, map="basement_loop", opponents=1, n_beams=61)
    obs, _ = vec.reset(seed=0)
    assert obs["scan"].shape == (2, 61)
    obs, rew, term, trunc, _ = vec.step(np.zeros((2, 2), dtype=np.float32))
    assert obs["scan"].shape == (2, 61) and term.shape == trunc.shape == (2,)
    assert rew.shape == (2,)
    vec.close()


def test_bad_opponent_settings_are_named():
    with pytest.raises(ValueError, match="opponent_driver 'rally' is not one of"):
        gym.make(
            "RacecarRace-v0", map="basement_loop", opponents=1, opponent_driver="rally", n_beams=61
        )
    with pytest.raises(ValueError, match="opponent_speeds must be 2 speeds"):
        gym.make(
            "RacecarRace-v0", map="basement_loop", opponents=2, opponent_speeds=[1.0], n_beams=61
        )
