"""A trained lap policy as a driver of any car: ``driver(obs, pose) -> [steer rad, speed m/s]``.

``racecar-sim train-agent`` writes ``model.zip`` (the PPO policy) beside ``config.json`` (its
lap task, ``LapTaskConfig``).
[`load_policy_driver`][mcl.agents.policy_driver.load_policy_driver] reads both and gives a driver
with the protocol of the project's drivers (``racecar_sim.drivers``), so that a
race can put the policy in any car: each call builds the task's observation (the car's scan, its
odometry and the pose it drives on, against the race's track) with
``LapTask.observe``, asks the policy, and turns its action into
[steer, speed] with ``LapTask.command``. The pose is the one the
caller gives: the true pose, or the car's MCL estimate in a localized race. A policy trained on
``pose_source="none"`` gets no pose, as in training.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Mapping
from dataclasses import fields, replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from mcl.agents.lap_env import LapTask, LapTaskConfig
from racecar_sim.world.track import Track

__all__ = ["PolicyDriver", "load_policy_driver", "task_of_model"]

Policy = Callable[[np.ndarray], np.ndarray]


class PolicyDriver:
    """A lap policy driving one car (see the module doc).

    Args:
        policy: ``policy(task observation) -> task action`` in ``[-1, 1]^2``.
        task: the lap task on the car's own env (``RaceEnv.cars[i]``), on the race's track.
        speed: m/s, the most the car is asked for (the policy's own speed range is the task's).
    """

    def __init__(self, policy: Policy, task: LapTask, speed: float = math.inf) -> None:
        self.policy = policy
        self.task = task
        self.speed = float(speed)
        self._begun = False

    def reset(self) -> None:
        """Start again (the previous action in the observation is zero at the next call)."""
        self._begun = False

    def __call__(self, obs: Mapping[str, Any], pose: np.ndarray | None = None) -> np.ndarray:
        """Action float32 [steer rad, speed m/s] for the car's observation and world ``pose``
        (rear axle; default ``obs["pose_estimate"]``).

        Raises:
            ValueError: no pose given or in ``obs``, when the policy's task needs one.
        """
        if pose is None:
            pose = obs.get("pose_estimate") if isinstance(obs, Mapping) else None
        if pose is None and self.task.config.pose_source != "none":
            raise ValueError("PolicyDriver needs the car's pose: pass pose=[x, y, theta]")
        info = {"pose": np.asarray(pose if pose is not None else (0.0, 0.0, 0.0), dtype=float)}
        if not self._begun:
            self.task.begin(info)
            self._begun = True
        action = self.task.command(self.policy(self.task.observe(dict(obs), info)))
        return np.array([action[0], min(action[1], self.speed)], dtype=np.float32)


def task_of_model(model_path: str | os.PathLike[str]) -> LapTaskConfig:
    """The lap task a model was trained on: ``config.json`` beside ``model.zip`` (the first task
    when it trained on several).

    Raises:
        FileNotFoundError: no config.json beside the model.
        ValueError: a config.json that does not hold a lap task.
    """
    path = Path(model_path).parent / "config.json"
    if not path.is_file():
        raise FileNotFoundError(
            f"{path} is missing: a policy is the model.zip that racecar-sim train-agent wrote, "
            "beside its config.json"
        )
    try:
        task = json.loads(path.read_text(encoding="utf-8"))["task"]
        if isinstance(task, list):
            task = task[0]
        names = {f.name for f in fields(LapTaskConfig)}
        return LapTaskConfig(**{k: v for k, v in task.items() if k in names})
    except (ValueError, KeyError, TypeError, AttributeError, IndexError) as exc:
        raise ValueError(f"{path} does not hold a lap task: {exc}") from None


def load_policy_driver(
    model_path: str | os.PathLike[str],
    car_env: gym.Env,
    track: Track,
    speed: float = math.inf,
) -> PolicyDriver:
    """The policy in ``model_path`` (a ``model.zip`` of ``racecar-sim train-agent``) driving the
    car of ``car_env`` (its single env, e.g. ``RaceEnv.cars[i]``) on ``track``.

    Raises:
        ImportError: stable-baselines3 is not installed (extra ``[rl]``).
        FileNotFoundError, ValueError: the model or its config.json is missing or unreadable, or
            the model expects another observation than its task gives.
    """
    from mcl.agents.ppo import require_sb3

    path = Path(model_path)
    if not path.is_file():
        raise FileNotFoundError(f"{path} does not exist")
    config = task_of_model(path)
    require_sb3()
    from stable_baselines3 import PPO

    try:
        model = PPO.load(str(path), device="cpu")
    except Exception as exc:  # a zip that is no PPO model: sb3 raises what its loader raised
        raise ValueError(f"{path} is not a stable-baselines3 PPO model: {exc}") from None
    # the pose comes with each call, so the task builds its observation from the given pose
    source = "none" if config.pose_source == "none" else "truth"
    task = LapTask(
        car_env, replace(config, pose_source=source, localize=False, opponents=0), track=track
    )
    expected = getattr(model.observation_space, "shape", None)
    if expected != task.observation_space.shape:
        raise ValueError(
            f"{path} expects observations of shape {expected}, its task in config.json gives "
            f"{task.observation_space.shape}"
        )

    def policy(obs: np.ndarray) -> np.ndarray:
        action, _ = model.predict(obs, deterministic=True)
        return np.asarray(action)

    return PolicyDriver(policy, task, speed)
