"""PPO on the lap task with stable-baselines3 (the optional extra ``[rl]``).

`train()` writes into its output folder::

    config.json      the task and the PPO settings
    learning.csv     one row per finished training episode: timesteps, wall_s, return (m of
                     progress minus penalties), length (steps), progress (m), collisions
                     (steps in contact), laps, opponents, overtakes (rank gains)
    model.zip        the policy (saved every ``save_every`` timesteps and at the end)
    train.json       timesteps done, wall seconds, steps per second

Without MCL (pose sources ``truth`` and ``none``) and without opponents the cars are stepped by
the simulator's batched env ([`mcl.agents.batched`][mcl.agents.batched]); with MCL or opponents by
stable-baselines3's ``DummyVecEnv`` (a sync vector env of single lap envs, one filter or one race
each). A list of tasks gives env ``i`` the task ``i % len(tasks)``, e.g. races against 1, 2 and 3
opponents side by side. Torch and numba use one thread each.
"""

from __future__ import annotations

import csv
import functools
import json
import os
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mcl.agents.lap_env import LapTaskConfig
from mcl.agents.task_env import make_task_env
from racecar_sim.file_guard import claim_folder, writable
from racecar_sim.settings.validation import check_number

__all__ = ["PPOSettings", "TrainReport", "load_policy", "require_sb3", "train"]


def require_sb3() -> None:
    """Raise ``ImportError`` with the install hint when stable-baselines3 is missing."""
    try:
        import stable_baselines3  # noqa: F401
    except ImportError as exc:
        raise ImportError(
            "the agent needs stable-baselines3 and torch: pip install torch==2.13.0 "
            "-e '.[rl]' (a CPU torch is enough)"
        ) from exc


@dataclass(frozen=True)
class PPOSettings:
    """PPO hyper-parameters (stable-baselines3 names; steps per env per update, etc.)."""

    n_envs: int = 8
    n_steps: int = 256
    batch_size: int = 256
    n_epochs: int = 10
    learning_rate: float = 3e-4
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip_range: float = 0.2
    ent_coef: float = 0.0
    net_arch: tuple[int, ...] = (128, 128)

    def __post_init__(self) -> None:
        for name in ("n_envs", "n_steps", "batch_size", "n_epochs"):
            check_number("PPOSettings", name, getattr(self, name), low=1, integer=True)
        for name in ("learning_rate", "gamma", "gae_lambda", "clip_range"):
            check_number("PPOSettings", name, getattr(self, name), low=0, low_open=True)
        check_number("PPOSettings", "ent_coef", self.ent_coef, low=0)


@dataclass(frozen=True)
class TrainReport:
    """What `train()` did: timesteps, wall seconds and the files written."""

    timesteps: int
    wall_s: float
    model_path: Path
    learning_path: Path


def _one_thread() -> None:
    import numba
    import torch

    torch.set_num_threads(1)
    numba.set_num_threads(1)


def train(
    task: LapTaskConfig | Sequence[LapTaskConfig],
    timesteps: int,
    out_dir: str | os.PathLike[str],
    *,
    settings: PPOSettings | None = None,
    seed: int = 0,
    save_every: int = 50_000,
    progress: bool = False,
    batched: bool | None = None,
    max_minutes: float | None = None,
) -> TrainReport:
    """Train PPO on ``task`` for ``timesteps`` env steps (all envs together) into ``out_dir``.

    ``task``: one task, or a list: env ``i`` runs ``task[i % len(task)]`` (all must share the
    observation: any mix of opponents and car models, one pose source).
    ``batched``: step the cars in the simulator's batched env
    ([`BatchedLapVecEnv`][mcl.agents.batched.BatchedLapVecEnv]; None: whenever there is one task and it runs
    no MCL and no race), else in stable-baselines3's sync ``DummyVecEnv`` of single lap envs (the
    same observations).
    ``max_minutes``: stop after this many wall-clock minutes even before ``timesteps`` (a time
    box on a shared machine; ``train.json`` says whether it stopped the run).
    """
    require_sb3()
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor

    if isinstance(timesteps, bool) or not isinstance(timesteps, int) or timesteps < 1:
        raise ValueError(f"timesteps = {timesteps!r} must be a positive integer")
    settings = settings if settings is not None else PPOSettings()
    if max_minutes is not None:
        check_number("train", "max_minutes", max_minutes, low=0, low_open=True)
    tasks = [task] if isinstance(task, LapTaskConfig) else list(task)
    if not tasks:
        raise ValueError("train: no task given")
    if batched is None:
        batched = len(tasks) == 1 and not tasks[0].localized and not tasks[0].opponents
    out = Path(out_dir)
    claim_folder(out)
    _one_thread()
    writable(out / "config.json").write_text(
        json.dumps(
            {
                "task": asdict(tasks[0]) if len(tasks) == 1 else [asdict(t) for t in tasks],
                "ppo": asdict(settings),
                "seed": seed,
                "timesteps": timesteps,
                "batched": batched,
            },
            indent=1,
            default=str,
        )
        + "\n",
        encoding="utf-8",
    )
    if batched:
        if len(tasks) > 1:
            raise ValueError("train: the batched env runs one task; give one or batched=False")
        from mcl.agents.batched import BatchedLapVecEnv

        inner: Any = BatchedLapVecEnv(tasks[0], settings.n_envs)
    else:
        inner = DummyVecEnv(
            [
                functools.partial(make_task_env, tasks[i % len(tasks)])
                for i in range(settings.n_envs)
            ]
        )
    venv = VecMonitor(inner)
    model = PPO(
        "MlpPolicy",
        venv,
        n_steps=settings.n_steps,
        batch_size=settings.batch_size,
        n_epochs=settings.n_epochs,
        learning_rate=settings.learning_rate,
        gamma=settings.gamma,
        gae_lambda=settings.gae_lambda,
        clip_range=settings.clip_range,
        ent_coef=settings.ent_coef,
        policy_kwargs={"net_arch": list(settings.net_arch)},
        seed=seed,
        device="cpu",
        verbose=0,
    )
    learning_path, model_path = out / "learning.csv", out / "model.zip"
    t0 = time.perf_counter()

    class Record(BaseCallback):
        """Write every finished episode to learning.csv; save the model now and then."""

        def __init__(self) -> None:
            super().__init__()
            self.file = writable(learning_path).open("w", newline="", encoding="utf-8")
            self.writer = csv.writer(self.file)
            self.writer.writerow(
                [
                    *("timesteps", "wall_s", "return", "length", "progress", "collisions"),
                    *("laps", "opponents", "overtakes"),
                ]
            )
            self.next_save = save_every

        def _on_step(self) -> bool:
            for info in self.locals["infos"]:
                episode = info.get("episode")
                if episode is None:
                    continue
                lap, race = info.get("lap", {}), info.get("race", {})
                self.writer.writerow(
                    [
                        self.num_timesteps,
                        round(time.perf_counter() - t0, 2),
                        round(float(episode["r"]), 3),
                        int(episode["l"]),
                        round(float(lap.get("progress", np.nan)), 3),
                        int(lap.get("collisions", -1)),
                        int(lap.get("laps", -1)),
                        int(race.get("opponents", 0)),
                        int(race.get("overtakes", 0)),
                    ]
                )
                self.file.flush()
            if self.num_timesteps >= self.next_save:
                self.model.save(writable(model_path))
                self.next_save += save_every
            return max_minutes is None or time.perf_counter() - t0 < 60.0 * max_minutes

        def _on_training_end(self) -> None:
            self.file.close()

    model.learn(total_timesteps=timesteps, callback=Record(), progress_bar=progress)
    wall = time.perf_counter() - t0
    model.save(writable(model_path))
    done = int(model.num_timesteps)
    writable(out / "train.json").write_text(
        json.dumps(
            {
                "timesteps": done,
                "wall_s": round(wall, 1),
                "steps_per_s": round(done / wall, 1),
                "stopped_by_max_minutes": done < timesteps,
            },
            indent=1,
        )
        + "\n",
        encoding="utf-8",
    )
    venv.close()
    return TrainReport(done, wall, model_path, learning_path)


def load_policy(model_path: str | os.PathLike[str]) -> Any:
    """``policy(obs) -> action`` (deterministic) of a saved PPO model."""
    require_sb3()
    from stable_baselines3 import PPO

    _one_thread()
    model = PPO.load(str(model_path), device="cpu")

    def policy(obs: np.ndarray) -> np.ndarray:
        action, _ = model.predict(obs, deterministic=True)
        return np.asarray(action)

    return policy
