"""A trained lap policy as a race driver: the observation is the lap task's on the pose given,
its action becomes [steer, speed] (capped at the car's speed), the model's config.json is read,
and (with stable-baselines3) a policy trained by the project races from the command line."""

from __future__ import annotations

import csv
import json
from dataclasses import asdict

import numpy as np
import pytest

from mcl.agents.lap_env import LapTask, LapTaskConfig
from mcl.agents.policy_driver import PolicyDriver, load_policy_driver, task_of_model
from tests.skips import NO_SB3, RL_MISSING

pytest.importorskip("pettingzoo", reason="RaceEnv needs the [race] extra (pettingzoo)")
from racecar_sim.race.env import RaceEnv

NEEDS_SB3 = pytest.mark.skipif(NO_SB3, reason=RL_MISSING)


@pytest.fixture(scope="module")
def race() -> RaceEnv:
    env = RaceEnv("basement_loop", n_cars=2)
    env.reset(seed=0)
    return env


def test_the_policy_sees_the_lap_task_on_the_given_pose_and_its_action_is_capped(race) -> None:
    seen: list[np.ndarray] = []

    def full_left_full_speed(obs: np.ndarray) -> np.ndarray:
        seen.append(obs)
        return np.array([1.0, 1.0])

    config = LapTaskConfig(pose_source="truth")
    task = LapTask(race.cars[1], config, track=race.track)
    driver = PolicyDriver(full_left_full_speed, task, speed=2.5)
    obs = {"scan": np.full(1080, 3.0), "odom": np.zeros(3)}
    pose = race.poses[1]
    action = driver(obs, pose)
    assert action.dtype == np.float32
    assert action[0] == pytest.approx(race.car_params.max_steer)
    assert action[1] == pytest.approx(2.5)  # the task's 4 m/s capped at the car's speed
    reference = LapTask(race.cars[1], config, track=race.track)
    reference.begin({"pose": pose})
    np.testing.assert_array_equal(seen[0], reference.observe(obs, {"pose": pose}))
    moved = pose + np.array([0.5, 0.0, 0.0])
    driver(obs, moved)  # the previous action is in the next observation, the pose is the new one
    reference.command(np.array([1.0, 1.0]))
    np.testing.assert_array_equal(seen[1], reference.observe(obs, {"pose": moved}))


def test_a_pose_is_needed_unless_the_policy_drives_on_the_scan_alone(race) -> None:
    obs = {"scan": np.full(1080, 3.0), "odom": np.zeros(3)}
    task = LapTask(race.cars[0], LapTaskConfig(pose_source="truth"), track=race.track)
    with pytest.raises(ValueError, match="needs the car's pose"):
        PolicyDriver(lambda o: np.zeros(2), task)(obs)
    estimate = {**obs, "pose_estimate": race.poses[0]}
    assert PolicyDriver(lambda o: np.zeros(2), task)(estimate).shape == (2,)
    blind = LapTask(race.cars[0], LapTaskConfig(pose_source="none"), track=race.track)
    assert PolicyDriver(lambda o: np.zeros(2), blind)(obs).shape == (2,)


def test_the_task_is_read_from_config_json_beside_the_model(tmp_path) -> None:
    model = tmp_path / "model.zip"
    with pytest.raises(FileNotFoundError, match=r"config\.json is missing"):
        task_of_model(model)
    task = LapTaskConfig(pose_source="none", scan_bins=30, max_speed=3.0)
    (tmp_path / "config.json").write_text(json.dumps({"task": [asdict(task)]}, default=str))
    assert task_of_model(model) == task
    (tmp_path / "config.json").write_text(json.dumps({"ppo": {}}))
    with pytest.raises(ValueError, match="does not hold a lap task"):
        task_of_model(model)
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_policy_driver(tmp_path / "other.zip", None, None)  # type: ignore[arg-type]


@NEEDS_SB3
@pytest.mark.slow
def test_a_trained_policy_races_from_the_command_line(tmp_path, capsys) -> None:
    from mcl.agents.ppo import PPOSettings, train
    from mcl.cli.main import main

    settings = PPOSettings(n_envs=2, n_steps=64, batch_size=64, n_epochs=1)
    report = train(LapTaskConfig(pose_source="truth"), 128, tmp_path / "truth", settings=settings)
    out = tmp_path / "race"
    argv = ["race", "--cars", "2", "--drivers", f"pursuit,policy:{report.model_path}",
            "--duration", "1", "--video-fps", "0", "--out", str(out), "--quiet"]  # fmt: skip
    assert main(argv) == 0
    with (out / "results.csv").open() as fh:
        drivers = {row["car"]: row["driver"] for row in csv.DictReader(fh)}
    assert drivers == {"car_0": "pursuit", "car_1": "policy:truth"}
    assert "policy:truth" in capsys.readouterr().out
