"""Tests of racecar_sim.vector_env: N cars in one process equal N single envs, step for step."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import racecar_sim  # noqa: F401  (registers RacecarSim-v0 with its vector entry point)
from racecar_sim.vector_env import RacecarVectorEnv

SETTINGS = {"map": "corridor", "dt": 0.03, "terminate_on_collision": True, "max_range": 12.0}


def assert_same(a, b, path: str = "") -> None:
    """Equal nested dicts of arrays: same keys, dtypes, shapes and values (bit for bit)."""
    if isinstance(a, tuple):
        assert isinstance(b, tuple) and len(a) == len(b), path
        for k, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_same(x, y, f"{path}[{k}]")
        return
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), f"{path}: keys {set(a) ^ set(b)}"
        for key in a:
            assert_same(a[key], b[key], f"{path}/{key}")
        return
    a, b = np.asarray(a), np.asarray(b)
    assert a.dtype == b.dtype, f"{path}: dtype {a.dtype} vs {b.dtype}"
    np.testing.assert_array_equal(a, b, err_msg=path)


@pytest.mark.parametrize("parallel", [False, True])
def test_vector_env_equals_sync_vector_env_of_single_envs(parallel: bool) -> None:
    n = 4
    fast = gym.make_vec(
        "RacecarSim-v0", num_envs=n, vectorization_mode="vector_entry_point",
        max_episode_steps=40, parallel=parallel, workers=2, **SETTINGS,
    )  # fmt: skip
    assert isinstance(fast, RacecarVectorEnv)
    sync = gym.make_vec(
        "RacecarSim-v0", num_envs=n, vectorization_mode="sync", max_episode_steps=40, **SETTINGS
    )
    assert fast.observation_space == sync.observation_space
    assert fast.action_space == sync.action_space
    assert fast.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert_same(fast.reset(seed=11), sync.reset(seed=11))
    rng = np.random.default_rng(0)
    ends = 0
    for t in range(150):
        # Fast and twisting: cars hit walls (terminations), others run out of time (truncations).
        actions = np.column_stack([rng.uniform(-0.5, 0.5, n), rng.uniform(-1.0, 6.0, n)])
        got, want = fast.step(actions), sync.step(actions)
        assert_same(got, want, f"step {t}")
        ends += int(got[2].sum() + got[3].sum())
    assert ends >= 5, "the run covered episode ends and next-step autoresets"
    fast.close()
    sync.close()


@pytest.mark.parametrize(
    ("setting", "value"), [("parallel", "false"), ("workers", 0), ("workers", "x"), ("workers", True)]
)
def test_bad_thread_settings_name_the_setting(setting: str, value) -> None:
    with pytest.raises(ValueError, match=setting):
        RacecarVectorEnv(2, **SETTINGS, **{setting: value})


@pytest.mark.parametrize("seed", [1.5, True, "12", [1, 2.5, 3], [1, 2]])
def test_bad_seeds_name_the_seed(seed) -> None:
    env = RacecarVectorEnv(3, **SETTINGS)
    with pytest.raises(ValueError, match="seed"):
        env.reset(seed=seed)


def test_reset_seeds_per_car_lists_and_mask() -> None:
    env = RacecarVectorEnv(3, **SETTINGS)
    single = gym.make("RacecarSim-v0", **SETTINGS)
    obs, info = env.reset(seed=[5, 6, 7])
    for i, seed in enumerate([5, 6, 7]):
        o, inf = single.reset(seed=seed)
        np.testing.assert_array_equal(obs["scan"][i], o["scan"])
        np.testing.assert_array_equal(info["pose"][i], inf["pose"])
    assert not np.array_equal(obs["scan"][0], obs["scan"][1])  # seeded per car
    env.step(np.zeros((3, 2)))
    before = env.envs[1].pose
    obs, info = env.reset(seed=[8, None, 9], options={"reset_mask": np.array([True, False, True])})
    np.testing.assert_array_equal(env.envs[1].pose, before)  # the masked-out car kept its state
    assert list(info["_pose"]) == [True, False, True]
    o, inf = single.reset(seed=9)
    np.testing.assert_array_equal(obs["scan"][2], o["scan"])


def test_bad_actions_and_settings_raise() -> None:
    env = RacecarVectorEnv(2, **SETTINGS)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros((3, 2)))
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([[0.0, np.nan], [0.0, 1.0]]))
    with pytest.raises(ValueError, match="masked"):
        env.step(np.ma.array(np.zeros((2, 2)), mask=[[False, True], [False, False]]))
    with pytest.raises(ValueError, match=r"RacecarVectorEnv.reset: options must be a dict"):
        env.reset(options=[1, 2])
    with pytest.raises(ValueError, match="num_envs"):
        RacecarVectorEnv(0, **SETTINGS)
    with pytest.raises(ValueError, match="unknown"):
        RacecarVectorEnv(2, map="corridor", wheel_count=4)


def test_auto_parallel_times_both_ways_and_changes_nothing() -> None:
    settings = {**SETTINGS, "n_beams": 4096}  # 4 cars x 4096 beams: enough rays for threads
    fast = RacecarVectorEnv(4, workers=2, **settings)  # parallel=None: picks by timing
    sync = gym.make_vec("RacecarSim-v0", num_envs=4, vectorization_mode="sync", **settings)
    assert_same(fast.reset(seed=3), sync.reset(seed=3))
    rng = np.random.default_rng(1)
    for t in range(60):
        actions = np.column_stack([rng.uniform(-0.4, 0.4, 4), rng.uniform(0.0, 3.0, 4)])
        assert_same(fast.step(actions), sync.step(actions), f"step {t}")
    serial, threaded = fast._cast_times
    assert serial and threaded, "both ways were timed"
    fast.close()


def test_cars_scraping_walls_equal_single_envs() -> None:
    """Cars that stay against walls (no termination) switch between free steps, batched for the
    vector env, and pymunk; a scan every few steps (lidar slower than the step)."""
    n = 3
    settings = {"map": "corridor", "dt": 0.01, "lidar_rate": 40.0, "terminate_on_collision": False}
    fast = gym.make_vec("RacecarSim-v0", num_envs=n, vectorization_mode="vector_entry_point",
                        parallel=False, **settings)  # fmt: skip
    sync = gym.make_vec("RacecarSim-v0", num_envs=n, vectorization_mode="sync", **settings)
    assert_same(fast.reset(seed=5), sync.reset(seed=5))
    rng = np.random.default_rng(1)
    hits = 0
    for t in range(300):
        actions = np.column_stack([rng.uniform(-0.6, 0.6, n), rng.uniform(0.5, 5.0, n)])
        got, want = fast.step(actions), sync.step(actions)
        assert_same(got, want, f"step {t}")
        hits += int(got[4]["collision"].sum())
    assert hits > 10, "the cars spent steps against walls"
    fast.close()
    sync.close()


def test_a_refused_first_reset_leaves_the_cars_needing_a_reset() -> None:
    from gymnasium.error import ResetNeeded

    env = RacecarVectorEnv(2, **SETTINGS)
    with pytest.raises(ValueError, match="pose"):
        env.reset(options={"pose": [1e4, 1e4, 0.0]})  # off the map: every car's reset refuses
    with pytest.raises(ResetNeeded, match=r"car\(s\) \[0, 1\]"):
        env.step(np.zeros((2, 2)))


@pytest.mark.parametrize("seed", [-1, [0, -1], 2.5, True, "a"])
def test_a_negative_or_non_integer_seed_is_one_value_error(seed) -> None:
    from racecar_sim.vector_env import car_seeds

    with pytest.raises(ValueError, match=r"seed must be a non-negative int, None, or a list of 2"):
        car_seeds(seed, 2)
    assert car_seeds([0, None], 2) == [0, None] and car_seeds(5, 2) == [5, 6]


def test_each_car_is_a_row_of_the_one_core() -> None:
    """The cars keep one clock, scan and odometry each (the vector env's core), not a copy: what a
    car says of itself is what the vector env reported for it, through autoresets too."""
    n = 3
    env = RacecarVectorEnv(n, max_episode_steps=7, **SETTINGS)
    obs, _ = env.reset(seed=5)
    for k in range(20):
        obs, _, _, _, infos = env.step(np.tile([0.2, 1.0 + 0.1 * k], (n, 1)))
        for i, car in enumerate(env.envs):
            assert car.fleet is env.fleet and car.car_index == i
            assert car.time == infos["time"][i]
            np.testing.assert_array_equal(car.last_scan, obs["scan"][i])
            np.testing.assert_array_equal(car.pose, infos["pose"][i])
    assert infos["time"].max() < 7 * SETTINGS["dt"] + 1e-9  # truncated and restarted
