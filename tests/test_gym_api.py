"""Every registered env id, alone and under the localization wrapper, passes Gymnasium's
``check_env`` and gives the same run for the same seed; the vector env and the race (PettingZoo)
with their wrappers give the same run for the same seed too.

A run is a reset and ``STEPS`` steps of actions drawn from the action space seeded alike; the same
seed must give equal observations, rewards, flags and infos (exactly: every number of our envs
comes from seeded generators; the wrappers' clock, the only wall time, is fixed)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import racecar_sim  # noqa: F401  (registers the ids)
from tests.gym_checks import check_env_as_designed

STEPS = 25
SMALL = {"map": "basement_loop", "n_beams": 61}  # fast and still a real map
FILTER = {"filter": {"n_particles": 200}}


def our_ids() -> list[str]:
    return sorted(
        env_id for env_id, spec in gym.registry.items()
        if str(spec.entry_point).startswith(("racecar_sim", "mcl"))
    )  # fmt: skip


def plain(env_id: str) -> gym.Env:
    return gym.make(env_id, **SMALL)


def localized(env_id: str) -> gym.Env:
    from mcl import LocalizationWrapper

    return LocalizationWrapper(gym.make(env_id, **SMALL), FILTER, clock=lambda: 0.0)


def assert_same(a: Any, b: Any, where: str = "") -> None:
    """Nested dicts / sequences / arrays / numbers equal exactly (NaN equal to NaN)."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and sorted(a) == sorted(b), where
        for key in a:
            assert_same(a[key], b[key], f"{where}[{key!r}]")
    elif isinstance(a, list | tuple):
        assert isinstance(b, list | tuple) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_same(x, y, f"{where}[{i}]")
    elif isinstance(a, np.ndarray | np.generic | float | int | bool):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b), err_msg=where)
    else:
        assert a == b, where


def gym_run(env: gym.Env, seed: int) -> list[Any]:
    env.action_space.seed(seed)
    out: list[Any] = [env.reset(seed=seed)]
    for _ in range(STEPS):
        step = env.step(env.action_space.sample())
        out.append(step)
        if step[2] or step[3]:
            out.append(env.reset())
    return out


def test_the_registry_holds_our_envs() -> None:
    assert {"RacecarSim-v0", "RacecarRace-v0"} <= set(our_ids())


@pytest.mark.parametrize("wrap", [plain, localized], ids=["plain", "localized"])
@pytest.mark.parametrize("env_id", our_ids())
def test_check_env_and_same_seed_same_run(env_id: str, wrap: Callable[[str], gym.Env]) -> None:
    env = wrap(env_id)
    check_env_as_designed(env if wrap is localized else env.unwrapped, skip_render_check=True)
    first = gym_run(env, 7)
    again = gym_run(wrap(env_id), 7)
    assert_same(first, again)
    other = gym_run(wrap(env_id), 8)
    assert not np.array_equal(other[0][0]["scan"], first[0][0]["scan"])  # the seed matters


@pytest.mark.parametrize("localize", [False, True], ids=["plain", "localized"])
def test_the_vector_env_gives_the_same_run_for_the_same_seed(localize: bool) -> None:
    def make() -> gym.vector.VectorEnv:
        env = gym.make_vec("RacecarSim-v0", num_envs=3, vectorization_mode="vector_entry_point",
                           max_episode_steps=10, **SMALL)  # fmt: skip
        if localize:
            from mcl import LocalizedVectorEnv

            env = LocalizedVectorEnv(env, FILTER, clock=lambda: 0.0)
        return env

    def run(env: gym.vector.VectorEnv) -> list[Any]:
        env.action_space.seed(5)
        return [env.reset(seed=5)] + [env.step(env.action_space.sample()) for _ in range(STEPS)]

    assert_same(run(make()), run(make()))


@pytest.mark.parametrize("localize", [False, True], ids=["plain", "localized"])
def test_the_race_passes_parallel_api_test_and_repeats_itself(localize: bool) -> None:
    pytest.importorskip("pettingzoo")
    from pettingzoo.test import parallel_api_test

    from racecar_sim import RaceEnv

    def make():
        env = RaceEnv("basement_loop", n_cars=3, n_beams=61)
        if localize:
            from mcl.wrappers.race import LocalizedRaceEnv

            env = LocalizedRaceEnv(env, FILTER, clock=lambda: 0.0)
        return env

    parallel_api_test(make(), num_cycles=STEPS)

    def run(env) -> list[Any]:
        out: list[Any] = [env.reset(seed=4)]
        for agent in env.possible_agents:
            env.action_space(agent).seed(4)
        for _ in range(STEPS):
            if not env.agents:
                break
            out.append(env.step({a: env.action_space(a).sample() for a in env.agents}))
        return out

    assert_same(run(make()), run(make()))
