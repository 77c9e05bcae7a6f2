"""The lap task on the simulator's batched env, as a stable-baselines3 ``VecEnv`` (extra ``[rl]``).

`BatchedLapVecEnv` steps N cars with one [`racecar_sim.vector_env.RacecarVectorEnv`][racecar_sim.vector_env.RacecarVectorEnv]
(all lidar scans of a step in one cast) and runs one [`LapTask`][mcl.agents.lap_env.LapTask] per car
for the start poses, observations, rewards and laps, so car ``i`` sees what a ``LapTask`` over a
single env sees for the same seed. It has no MCL: pose sources ``truth`` and ``none`` only (the
filters of the estimate would each step on their own anyway). Episodes end as stable-baselines3
expects: the car is reset in the same step and the last observation goes to
``info["terminal_observation"]``; ``info["TimeLimit.truncated"]`` marks the time limit.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import VecEnv

from mcl.agents.lap_env import LapTask, LapTaskConfig
from racecar_sim.vector_env import RacecarVectorEnv

__all__ = ["BatchedLapVecEnv"]

_INFO_KEYS = ("pose", "twist", "collision", "time", "new_scan")


class BatchedLapVecEnv(VecEnv):
    """``n_envs`` lap-task cars in one batched simulator (see the module docstring).

    Raises:
        ValueError: the task needs MCL (pose source ``estimate``), or ``n_envs`` < 1.
    """

    def __init__(self, config: LapTaskConfig, n_envs: int) -> None:
        if config.localized:
            raise ValueError(
                "the batched env runs no localization: use pose_source 'truth' or 'none' "
                "(or the sync vector env for 'estimate')"
            )
        settings = {"terminate_on_collision": config.terminate_on_collision, **dict(config.env)}
        self.sim = RacecarVectorEnv(n_envs, config.map, **settings)
        self.tasks = [LapTask(env, config) for env in self.sim.envs]
        self.max_steps = max(1, round(config.episode_seconds / self.sim.dt))
        self._steps = np.zeros(n_envs, dtype=np.int64)
        self._actions = np.zeros((n_envs, 2))
        first = self.tasks[0]
        super().__init__(n_envs, first.observation_space, first.action_space)

    # ------------------------------------------------------------------ VecEnv API
    def reset(self) -> np.ndarray:
        """Reset every car (seeds from `seed()`, then fresh draws)."""
        seeds = list(self._seeds) if self._seeds else [None] * self.num_envs
        obs = np.stack([self._reset_car(i, seeds[i]) for i in range(self.num_envs)])
        self._reset_seeds()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
        commands = np.stack([t.command(a) for t, a in zip(self.tasks, self._actions, strict=True)])
        obs, _, terminated, _, info = self.sim.step(commands)
        n = self.num_envs
        out = np.empty((n, *self.observation_space.shape), dtype=np.float32)
        rewards = np.zeros(n, dtype=np.float32)
        dones = np.zeros(n, dtype=bool)
        infos: list[dict[str, Any]] = []
        self._steps += 1
        for i, task in enumerate(self.tasks):
            car_info = {k: info[k][i] for k in _INFO_KEYS}
            rewards[i] = task.track_step(car_info)
            out[i] = task.observe({"scan": obs["scan"][i], "odom": obs["odom"][i]}, car_info)
            timeout = bool(self._steps[i] >= self.max_steps)
            car = task.add_lap_info(car_info)
            if terminated[i] or timeout:
                dones[i] = True
                car["TimeLimit.truncated"] = timeout and not terminated[i]
                car["terminal_observation"] = out[i].copy()
                out[i] = self._reset_car(i, None)
            infos.append(car)
        return out, rewards, dones, infos

    def close(self) -> None:
        self.sim.close()

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        return [getattr(self.tasks[i], attr_name) for i in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        for i in self._get_indices(indices):
            setattr(self.tasks[i], attr_name, value)

    def env_method(
        self, method_name: str, *method_args: Any, indices: Any = None, **method_kwargs: Any
    ) -> list[Any]:
        return [
            getattr(self.tasks[i], method_name)(*method_args, **method_kwargs)
            for i in self._get_indices(indices)
        ]

    def env_is_wrapped(self, wrapper_class: type, indices: Any = None) -> list[bool]:
        return [isinstance(self.tasks[i], wrapper_class) for i in self._get_indices(indices)]

    # ------------------------------------------------------------------ internals
    def _reset_car(self, i: int, seed: int | None) -> np.ndarray:
        """Reset car ``i`` alone at its task's next start pose; its first observation."""
        task = self.tasks[i]
        pose = task.start_pose(seed)
        mask = np.zeros(self.num_envs, dtype=bool)
        mask[i] = True
        seeds: list[int | None] = [None] * self.num_envs
        seeds[i] = seed
        obs, info = self.sim.reset(seed=seeds, options={"pose": pose, "reset_mask": mask})
        car_info = {k: info[k][i] for k in _INFO_KEYS}
        task.begin(car_info)
        self._steps[i] = 0
        return task.observe({"scan": obs["scan"][i], "odom": obs["odom"][i]}, car_info)
