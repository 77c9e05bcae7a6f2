"""The lap task on the batched simulator (mcl.agents.batched) equals a sync vector env of single lap
envs car by car: observations, rewards, episode ends, terminal observations (needs stable-baselines3)."""

from __future__ import annotations

import numpy as np
import pytest

from tests.skips import RL_MISSING

pytest.importorskip("stable_baselines3", reason=RL_MISSING)

from stable_baselines3.common.vec_env import DummyVecEnv

from mcl.agents.batched import BatchedLapVecEnv
from mcl.agents.lap_env import LapTaskConfig, make_lap_env


def test_batched_lap_env_equals_single_lap_envs() -> None:
    config = LapTaskConfig(pose_source="truth", env=(("n_beams", 181),), episode_seconds=3.0)
    batched = BatchedLapVecEnv(config, 3)
    single = DummyVecEnv([lambda: make_lap_env(config)] * 3)
    batched.seed(5)
    single.seed(5)
    np.testing.assert_array_equal(batched.reset(), single.reset())
    rng = np.random.default_rng(0)
    ends = {"terminated": 0, "truncated": 0}
    for k in range(300):
        actions = rng.uniform(-1, 1, (3, 2)).astype(np.float32)
        actions[0] = [1.0, 1.0]  # car 0 turns hard into a wall again and again
        obs_b, rew_b, done_b, info_b = batched.step(actions)
        obs_s, rew_s, done_s, info_s = single.step(actions)
        np.testing.assert_array_equal(obs_b, obs_s, err_msg=f"step {k}")
        np.testing.assert_allclose(rew_b, rew_s, rtol=1e-6, atol=1e-6)
        np.testing.assert_array_equal(done_b, done_s)
        for b, s in zip(info_b, info_s, strict=True):
            if "terminal_observation" in s:
                np.testing.assert_array_equal(b["terminal_observation"], s["terminal_observation"])
                assert b["TimeLimit.truncated"] == s.get("TimeLimit.truncated", False)
                ends["truncated" if b["TimeLimit.truncated"] else "terminated"] += 1
            assert b["lap"] == s["lap"]
    assert ends["terminated"] >= 1 and ends["truncated"] >= 1  # both kinds of end exercised


def test_batched_lap_env_refuses_the_estimate() -> None:
    with pytest.raises(ValueError, match="no localization"):
        BatchedLapVecEnv(LapTaskConfig(pose_source="estimate"), 2)
