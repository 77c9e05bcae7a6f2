"""LocalizedRaceEnv: a filter per car of a race, sharing one sensor model, seeded per car."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pettingzoo", reason="the race env needs the [race] extra (pettingzoo)")

from pettingzoo.test import parallel_api_test

from mcl.wrappers.race import LocalizedRaceEnv
from racecar_sim import RaceEnv

CONFIG = {"filter": {"n_particles": 300}}


def _race(n_cars: int = 3) -> LocalizedRaceEnv:
    return LocalizedRaceEnv(RaceEnv("basement_loop", n_cars=n_cars), CONFIG, clock=lambda: 0.0)


def _drive(env: LocalizedRaceEnv, steps: int, seed: int, options=None) -> list[dict]:
    _, infos = env.reset(seed=seed, options=options)
    out = [infos]
    for _ in range(steps):
        actions = {a: np.array([0.0, 1.0]) for a in env.agents}
        _, _, _, _, infos = env.step(actions)
        out.append(infos)
    return out


def test_parallel_api() -> None:
    parallel_api_test(_race(3), num_cycles=30)


def test_every_car_is_localized_with_one_shared_sensor_model() -> None:
    env = _race(3)
    infos = _drive(env, 40, seed=1)[-1]
    assert set(env.filters) == {"car_0", "car_1", "car_2"}
    assert all(pf.sensor_model is env.sensor_model for pf in env.filters.values())
    for agent, info in infos.items():
        loc = info["localization"]
        assert loc["position_error"] < 0.25, agent
        err = np.hypot(*(loc["estimate"][:2] - info["pose"][:2]))
        assert loc["position_error"] == pytest.approx(err)


def test_the_same_seed_gives_the_same_estimates() -> None:
    a = _drive(_race(2), 20, seed=4)
    b = _drive(_race(2), 20, seed=4)
    for ia, ib in zip(a, b, strict=True):
        for agent in ia:
            np.testing.assert_array_equal(
                ia[agent]["localization"]["estimate"], ib[agent]["localization"]["estimate"]
            )


def test_filter_seed_redraws_the_cars_filters_on_the_same_race() -> None:
    def estimates(run: list[dict]) -> list:
        return [[i[a]["localization"]["estimate"] for a in sorted(i)] for i in run]

    plain = _drive(_race(2), 12, seed=4)
    redrawn = _drive(_race(2), 12, seed=4, options={"filter_seed": 9})
    for ia, ib in zip(plain, redrawn, strict=True):  # the same race
        for agent in ia:
            np.testing.assert_array_equal(ia[agent]["pose"], ib[agent]["pose"])
    assert not np.array_equal(estimates(plain), estimates(redrawn))
    as_seed = _drive(_race(2), 12, seed=4, options={"filter_seed": 4})
    np.testing.assert_array_equal(estimates(plain), estimates(as_seed))
    with pytest.raises(ValueError, match=r"option filter_seed = 1.5 must be a non-negative"):
        _race(2).reset(seed=4, options={"filter_seed": 1.5})


def test_bad_init_pose_is_refused() -> None:
    env = _race(2)
    with pytest.raises(ValueError, match="init_pose"):
        env.reset(seed=0, options={"init_pose": np.zeros(3)})


# ---------------------------------------------------------------------- RacecarRace-v0, car 0
def test_localization_wrapper_localizes_car_0_of_racecar_race() -> None:
    import gymnasium as gym

    from mcl.wrappers.single import LocalizationWrapper
    from tests.gym_checks import check_env_as_designed

    env = LocalizationWrapper(
        gym.make("RacecarRace-v0", map="basement_loop", opponents=2), CONFIG, clock=lambda: 0.0
    )
    check_env_as_designed(env, skip_render_check=True)
    obs, info = env.reset(seed=3)
    assert "pose_estimate" in obs
    for _ in range(30):
        obs, _, terminated, truncated, info = env.step(np.array([0.0, 1.0]))
        if terminated or truncated:
            break
    loc = info["localization"]
    assert loc["position_error"] < 0.25
    np.testing.assert_allclose(loc["estimate"], obs["pose_estimate"])
    # the opponents are in car 0's scan, not in the filter's map
    assert info["opponent_poses"].shape == (2, 3)


# ---------------------------------------------------------------------- misuse
def test_no_localized_agent_still_steps_after_a_reset() -> None:
    from gymnasium.error import ResetNeeded

    env = LocalizedRaceEnv(RaceEnv("basement_loop", n_cars=2, n_beams=61), CONFIG, agents=[])
    with pytest.raises(ResetNeeded, match=r"LocalizedRaceEnv.step: call reset\(\)"):
        env.step({"car_0": [0.0, 1.0], "car_1": [0.0, 1.0]})
    env.reset(seed=0)
    obs, *_ = env.step({"car_0": [0.0, 1.0], "car_1": [0.0, 1.0]})
    assert env.filters == {} and set(obs) == {"car_0", "car_1"}
    assert all("pose_estimate" not in o for o in obs.values())  # passed through


@pytest.mark.parametrize("agents", [["car_9"], ["car_0", "car_0"], [0], "car_0"])
def test_agents_that_are_not_distinct_agent_names_are_refused(agents) -> None:
    with pytest.raises(ValueError, match="LocalizedRaceEnv agents"):
        LocalizedRaceEnv(RaceEnv("basement_loop", n_cars=2, n_beams=61), CONFIG, agents=agents)


def test_wrapping_anything_but_a_race_names_the_wrapper_that_takes_it() -> None:
    import gymnasium as gym

    from racecar_sim.env import RacecarEnv

    vec = gym.make_vec("RacecarSim-v0", num_envs=2, vectorization_mode="vector_entry_point",
                       map="corridor", n_beams=61)  # fmt: skip
    with pytest.raises(
        TypeError,
        match=r"needs a racecar_sim.RaceEnv; got RacecarVectorEnv, a vector env: use mcl.LocalizedVectorEnv",
    ):
        LocalizedRaceEnv(vec)
    with pytest.raises(
        TypeError, match=r"got RacecarEnv, a single env: use mcl.LocalizationWrapper"
    ):
        LocalizedRaceEnv(RacecarEnv("corridor", n_beams=61))


def test_reset_options_of_the_wrong_kind_or_place_name_the_option_and_the_car() -> None:
    env = LocalizedRaceEnv(RaceEnv("basement_loop", n_cars=2, n_beams=61), CONFIG)
    with pytest.raises(ValueError, match=r"^LocalizedRaceEnv.reset: options must be a dict"):
        env.reset(options=[1, 2])
    with pytest.raises(ValueError, match=r"option init_pose must be a finite \(2, 3\) array.*dict"):
        env.reset(options={"init_pose": {"car_0": [9.0, 2.5, 0.0]}})
    _, infos = env.reset(seed=0)
    good = infos["car_0"]["pose"]
    with pytest.raises(
        ValueError, match=r"option init_pose\[1\] = \[5000.0, 5000.0, 0.0\] is off the filter map"
    ):
        env.reset(options={"init_pose": [good, [5000.0, 5000.0, 0.0]]})
