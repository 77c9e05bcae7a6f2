"""racecar_sim: a fast headless 2D racecar simulator on ROS occupancy grid maps."""

from gymnasium.envs.registration import register, registry

from racecar_sim.maps import DEFAULT_MAP, MapError, OccupancyMap, bundled, load_map
from racecar_sim.old_paths import RACECAR_SIM_MOVED, install

install(RACECAR_SIM_MOVED)  # ``racecar_sim.config`` and the other 0.2 paths still import, with a warning

__all__ = [
    "DEFAULT_MAP",
    "ENV_ID",
    "RACE_ENV_ID",
    "MapError",
    "OccupancyMap",
    "PurePursuit",
    "RaceEnv",
    "RacecarEnv",
    "RacecarVectorEnv",
    "WallFollower",
    "bundled",
    "load_map",
]
__version__ = "0.3.0"

ENV_ID = "RacecarSim-v0"
"""Gymnasium id of [`racecar_sim.env.RacecarEnv`][racecar_sim.env.RacecarEnv]: ``gymnasium.make(ENV_ID, map=...)``; many
cars in one process: ``gymnasium.make_vec(ENV_ID, num_envs=N, vectorization_mode="vector_entry_point")``
([`racecar_sim.vector_env.RacecarVectorEnv`][racecar_sim.vector_env.RacecarVectorEnv])."""

RACE_ENV_ID = "RacecarRace-v0"
"""Gymnasium id of [`racecar_sim.race.single.RacecarRaceEnv`][racecar_sim.race.single.RacecarRaceEnv]: one agent (car 0) against
``opponents`` scripted cars; the multi-agent race is [`racecar_sim.RaceEnv`][racecar_sim.RaceEnv] (PettingZoo)."""

if RACE_ENV_ID not in registry:
    register(id=RACE_ENV_ID, entry_point="racecar_sim.race.single:RacecarRaceEnv")

if ENV_ID not in registry:  # importing the package twice (or reloading it) must not fail
    register(
        id=ENV_ID,
        entry_point="racecar_sim.env:RacecarEnv",
        vector_entry_point="racecar_sim.vector_env:RacecarVectorEnv",
    )


def __getattr__(name: str):
    """The envs and drivers are imported on first use (``racecar_sim.RaceEnv`` needs the ``race``
    extra)."""
    if name == "RaceEnv":
        from racecar_sim.race.env import RaceEnv

        return RaceEnv
    if name == "RacecarEnv":
        from racecar_sim.env import RacecarEnv

        return RacecarEnv
    if name in ("WallFollower", "PurePursuit"):
        from racecar_sim import drivers

        return getattr(drivers, name)
    if name == "RacecarVectorEnv":
        from racecar_sim.vector_env import RacecarVectorEnv

        return RacecarVectorEnv
    raise AttributeError(f"module 'racecar_sim' has no attribute {name!r}")
