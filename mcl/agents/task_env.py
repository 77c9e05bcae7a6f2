"""One factory for every lap task: alone on ``RacecarSim-v0`` or in a race on ``RacecarRace-v0``.

`make_task_env()` is what training and tests build their envs with: the config's
``opponents`` pick [`mcl.agents.race_task.make_race_lap_env()`][mcl.agents.race_task.make_race_lap_env] (one or more) or
[`mcl.agents.lap_env.make_lap_env()`][mcl.agents.lap_env.make_lap_env] (none).
"""

from __future__ import annotations

import gymnasium as gym

from mcl.agents.lap_env import LapTaskConfig, make_lap_env
from mcl.agents.race_task import make_race_lap_env

__all__ = ["make_task_env"]


def make_task_env(config: LapTaskConfig, *, render_mode: str | None = None) -> gym.Env:
    """The lap task of ``config``, alone or against its opponents (see the module doc)."""
    if config.opponents:
        return make_race_lap_env(config, render_mode=render_mode)
    return make_lap_env(config, render_mode=render_mode)
