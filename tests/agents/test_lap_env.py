"""What an agent relies on (no torch needed): pose_estimate under vector envs, seeding,
info["localization"] on every step, the lap task's observation, reward and laps, the loop's
geometry; and the PPO example end to end when stable-baselines3 is installed."""

from __future__ import annotations

import csv
import math

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import racecar_sim  # noqa: F401  (registers RacecarSim-v0)
from mcl import LocalizationWrapper
from mcl.agents.lap_env import LapTask, LapTaskConfig, make_lap_env, make_vector_env
from mcl.agents.track import Track, track_for_map
from tests.skips import NO_SB3, RL_MISSING

FAST = {"n_beams": 181}
FILTER = {"filter": {"n_particles": 100}}


def _localized_vector_env(n: int = 2) -> gym.vector.VectorEnv:
    return gym.make_vec(
        "RacecarSim-v0",
        num_envs=n,
        vectorization_mode="sync",
        wrappers=[lambda env: LocalizationWrapper(env, FILTER)],
        **FAST,
    )


# ---------------------------------------------------------------------- the contract
def test_vector_env_observes_pose_estimate_and_localization_every_step() -> None:
    venv = _localized_vector_env()
    space = venv.single_observation_space
    assert isinstance(space, gym.spaces.Dict) and space["pose_estimate"].shape == (3,)
    assert venv.observation_space["pose_estimate"].shape == (2, 3)
    obs, info = venv.reset(seed=[3, 4])
    assert obs in venv.observation_space
    assert info["_localization"].all()
    ends = 0
    for _ in range(150):  # full speed ahead: cars hit walls and are reset automatically
        obs, _, terminated, truncated, info = venv.step(np.array([[0.0, 3.0]] * 2))
        assert obs["pose_estimate"].shape == (2, 3) and np.isfinite(obs["pose_estimate"]).all()
        assert info["_localization"].all(), "every step, also the reset after an end"
        loc = info["localization"]
        assert np.isfinite(loc["position_error"]).all() and (loc["n_particles"] > 0).all()
        assert (np.abs(obs["pose_estimate"][:, 2]) <= math.pi).all()
        ends += int(terminated.sum() + truncated.sum())
    assert ends >= 1, "the test drove no car into a wall: autoreset was not exercised"
    venv.close()


def test_vector_env_seeding_repeats_each_car_and_differs_between_cars() -> None:
    runs = []
    for _ in range(2):
        venv = _localized_vector_env()
        obs, _ = venv.reset(seed=[7, 8])
        trace = [obs["pose_estimate"].copy()]
        for k in range(40):
            obs, *_ = venv.step(np.array([[0.2 * math.sin(k / 5), 1.5]] * 2))
            trace.append(obs["pose_estimate"].copy())
        runs.append(np.array(trace))
        venv.close()
    np.testing.assert_array_equal(runs[0], runs[1])
    assert not np.allclose(runs[0][:, 0], runs[0][:, 1]), "two seeds gave the same drive"


def test_lap_vector_env_space_and_seeding() -> None:
    config = LapTaskConfig(env=tuple(FAST.items()), n_particles=100)
    traces = []
    for _ in range(2):
        venv = make_vector_env(config, n_envs=2)
        assert venv.single_observation_space.shape == (40 + 10 + 3 + 2 + 2,)
        obs, _ = venv.reset(seed=[1, 2])
        out = [obs]
        for _ in range(10):
            obs, *_ = venv.step(np.zeros((2, 2), dtype=np.float32))
            out.append(obs)
        traces.append(np.array(out))
        assert np.isfinite(traces[-1]).all() and (np.abs(traces[-1]) <= 2.0).all()
        venv.close()
    np.testing.assert_array_equal(traces[0], traces[1])
    assert not np.array_equal(traces[0][:, 0], traces[0][:, 1])


# ---------------------------------------------------------------------- the lap task
def _pursue(obs: np.ndarray) -> np.ndarray:
    """Steer at the 2 m look-ahead point of the observation (a hand-made lap policy)."""
    x, y = obs[44], obs[45]
    return np.array([np.clip(1.5 * math.atan2(y, x) / 0.42, -1, 1), 0.0])


def test_reward_is_true_progress_and_a_lap_is_counted() -> None:
    config = LapTaskConfig(
        env=tuple(FAST.items()),
        pose_source="truth",
        start_s=0.0,
        terminate_on_collision=False,
        episode_seconds=45,
    )
    env = make_lap_env(config)
    track = env.get_wrapper_attr("track")
    obs, info = env.reset(seed=0)
    total, last = 0.0, info["pose"]
    driven = 0.0
    while True:
        obs, reward, terminated, truncated, info = env.step(_pursue(obs))
        assert not info["collision"]
        total += reward
        driven += float(np.hypot(*(info["pose"][:2] - last[:2])))
        last = info["pose"]
        if terminated or truncated:
            break
    lap = info["lap"]
    assert total == pytest.approx(lap["progress"])
    assert lap["laps"] >= 1 and 10.0 < lap["lap_times"][0] < 45.0
    # progress along the loop is close to the distance driven (the car follows the loop)
    assert 0.85 * driven < lap["progress"] <= 1.05 * driven
    assert lap["progress"] > track.length


def test_pose_source_changes_only_the_pose_features() -> None:
    base = {"env": tuple(FAST.items()), "start_s": 10.0, "localize": True, "n_particles": 100}
    obs_t, _ = make_lap_env(LapTaskConfig(pose_source="truth", **base)).reset(seed=5)
    obs_e, _ = make_lap_env(LapTaskConfig(pose_source="estimate", **base)).reset(seed=5)
    np.testing.assert_array_equal(obs_t[:40], obs_e[:40])  # the same scan
    np.testing.assert_array_equal(obs_t[53:], obs_e[53:])  # odometry, last action
    assert not np.array_equal(obs_t[40:53], obs_e[40:53])  # the pose differs by MCL's error
    np.testing.assert_allclose(obs_t[40:53], obs_e[40:53], atol=0.2)


def test_a_wall_contact_costs_the_penalty_and_ends_a_training_episode() -> None:
    config = LapTaskConfig(
        env=tuple(FAST.items()), start_s=0.0, pose_source="truth", collision_penalty=5.0
    )
    env = make_lap_env(config)
    _, info = env.reset(seed=0)
    for _ in range(400):  # hard left into the island wall
        before = info["lap"]["progress"]
        _, reward, terminated, _, info = env.step(np.array([1.0, 1.0]))
        if terminated:
            break
        assert reward == pytest.approx(info["lap"]["progress"] - before)
    assert terminated and info["collision"] and info["lap"]["collisions"] == 1
    assert reward == pytest.approx(info["lap"]["progress"] - before - 5.0)


def test_estimate_source_needs_the_localization_wrapper() -> None:
    with pytest.raises(ValueError, match="LocalizationWrapper"):
        LapTask(gym.make("RacecarSim-v0", **FAST), LapTaskConfig(pose_source="estimate"))
    with pytest.raises(ValueError, match="pose_source"):
        LapTaskConfig(pose_source="gps")
    with pytest.raises(ValueError, match=r"LapTaskConfig\.n_particles = 0"):
        LapTaskConfig(n_particles=0)
    with pytest.raises(ValueError, match="min_speed < max_speed"):
        LapTaskConfig(min_speed=3.0, max_speed=2.0)


# ---------------------------------------------------------------------- the loop
SQUARE = Track(np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]]))


@settings(max_examples=60, deadline=None)
@given(s=st.floats(0.0, 39.999), offset=st.floats(-0.9, 0.9))
def test_projection_inverts_point_at_and_signs_the_offset(s, offset) -> None:
    heading = SQUARE.heading_at(s)
    left = np.array([-math.sin(heading), math.cos(heading)])
    corner_gap = min(s % 10.0, 10.0 - s % 10.0)
    point = SQUARE.point_at(s) + offset * left
    got_s, lateral = SQUARE.project(point)
    if corner_gap > abs(offset) + 1e-6:  # away from corners the nearest loop point is unique
        assert SQUARE.advance(s, got_s) == pytest.approx(0.0, abs=1e-9)
        assert lateral == pytest.approx(offset, abs=1e-9)


@given(a=st.floats(0.0, 39.9), b=st.floats(0.0, 39.9))
def test_advance_is_the_short_way_round(a, b) -> None:
    d = SQUARE.advance(a, b)
    assert -20.0 <= d <= 20.0
    laps = (a + d - b) / 40.0
    assert laps == pytest.approx(round(laps), abs=1e-9)  # a + d lands on b
    if abs(d) < 19.999:
        assert SQUARE.advance(b, a) == pytest.approx(-d)


def test_default_loop_goes_round_the_island_ahead_of_the_start() -> None:
    track = track_for_map("basement_loop")
    assert 70.0 < track.length < 100.0  # the 30 m x 20 m hallway loop
    ahead = track.ahead(np.array([9.0, 2.5, 0.0]), track.project([9.0, 2.5])[0], [2.0])
    assert ahead[0, 0] > 1.5 and abs(ahead[0, 1]) < 0.5  # 2 m ahead along the south hallway


# ---------------------------------------------------------------------- end to end
@pytest.mark.slow
def test_train_agent_end_to_end_with_tiny_timesteps(tmp_path) -> None:
    if NO_SB3:
        pytest.skip(RL_MISSING)
    from mcl.cli.train_agent import main

    code = main(
        [
            "--timesteps", "64", "--envs", "2", "--eval-seeds", "1", "--eval-seconds", "2",
            "--video-seconds", "0.5", "--eval-filters", "100,20x4", "--out", str(tmp_path),
        ]
    )  # fmt: skip
    assert code == 0
    for source in ("truth", "estimate"):
        assert (tmp_path / source / "model.zip").is_file()
        assert (tmp_path / source / "train.json").is_file()
    with (tmp_path / "eval.csv").open() as f:
        rows = list(csv.DictReader(f))
    tests = ["truth", "no pose", "estimate (100 particles)", "estimate (20 particles x 4 beams)"]
    assert [r["tested_on"] for r in rows] == tests * 2
    assert [r["policy"] for r in rows] == ["true pose"] * 4 + ["MCL estimate"] * 4
    assert rows[0]["mean_error"] == "nan" and float(rows[2]["mean_error"]) < 1.0
    assert all(float(r["seconds"]) == pytest.approx(2.0) for r in rows)
    assert (tmp_path / "learning_curve.png").stat().st_size > 1000
    assert (tmp_path / "agent.mp4").is_file() or (tmp_path / "agent_frames").is_dir()
