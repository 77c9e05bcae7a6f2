"""Tests of mcl.wrappers.vector: one filter per car of the vector env equals N single wrappers."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.error import ResetNeeded

import racecar_sim  # noqa: F401  (registers RacecarSim-v0)
from mcl.wrappers.localization import LocalizationConfig
from mcl.wrappers.single import LocalizationWrapper
from mcl.wrappers.vector import LocalizedVectorEnv

SETTINGS = {"map": "corridor", "dt": 0.03, "terminate_on_collision": True, "max_range": 12.0}
CONFIG = LocalizationConfig().with_particles(300)
KEYS = ("estimate", "position_error", "heading_error", "n_eff", "corrected", "n_particles")


def _sync(n: int, steps: int) -> gym.vector.SyncVectorEnv:
    def make() -> gym.Env:
        env = gym.make("RacecarSim-v0", max_episode_steps=steps, **SETTINGS)
        return LocalizationWrapper(env, CONFIG, clock=lambda: 0.0)

    return gym.vector.SyncVectorEnv([make] * n)


def test_each_car_localizes_as_a_single_wrapper_with_its_seed() -> None:
    """Same seeds, same actions: estimates, errors and n_eff equal SyncVectorEnv over single
    LocalizationWrappers, through collisions and next-step autoresets."""
    n = 3
    fast = LocalizedVectorEnv(
        gym.make_vec(
            "RacecarSim-v0", num_envs=n, vectorization_mode="vector_entry_point",
            max_episode_steps=25, **SETTINGS,
        ),
        CONFIG,
    )  # fmt: skip
    sync = _sync(n, 25)
    assert fast.single_observation_space == sync.single_observation_space
    got, want = fast.reset(seed=4), sync.reset(seed=4)
    np.testing.assert_array_equal(got[0]["pose_estimate"], want[0]["pose_estimate"])
    rng = np.random.default_rng(1)
    ends = 0
    for t in range(60):
        actions = np.column_stack([rng.uniform(-0.5, 0.5, n), rng.uniform(0.0, 5.0, n)])
        (o1, r1, te1, tr1, i1), (o2, r2, te2, tr2, i2) = fast.step(actions), sync.step(actions)
        np.testing.assert_array_equal(r1, r2)
        np.testing.assert_array_equal(te1 | tr1, te2 | tr2)
        np.testing.assert_array_equal(o1["pose_estimate"], o2["pose_estimate"], f"step {t}")
        for key in KEYS:
            np.testing.assert_array_equal(
                i1["localization"][key], i2["localization"][key], f"step {t} {key}"
            )
        ends += int((te1 | tr1).sum())
    assert ends >= 3, "the run covered autoresets"
    errors = i1["localization"]["position_error"]
    assert np.all(errors < 0.5), errors  # and the filters track
    fast.close()
    sync.close()


def test_reset_mask_restarts_only_those_filters_and_global_start() -> None:
    env = LocalizedVectorEnv(
        gym.make_vec(
            "RacecarSim-v0", num_envs=2, vectorization_mode="vector_entry_point", **SETTINGS
        ),
        CONFIG,
        uncertainty=True,
    )
    env.reset(seed=0)
    env.step(np.array([[0.0, 1.0], [0.0, 1.0]]))
    kept = env.filters[1].particles.copy()
    obs, info = env.reset(options={"reset_mask": np.array([True, False]), "init": "global"})
    loc = info["localization"]
    assert list(loc["_estimate"]) == [True, False]
    np.testing.assert_array_equal(env.filters[1].particles, kept)
    # Car 0 starts spread over the corridor's floor: one scan does not pin it down.
    assert loc["position_sd"][0] > 0.5 and bool(loc["ambiguous"][0])
    obs, info = env.reset(seed=0)
    assert info["localization"]["position_sd"].max() < 0.5  # both around their start pose
    assert np.all(np.isfinite(obs["pose_estimate"]))


def _vector_drive(options=None, steps: int = 8) -> tuple[list, list]:
    """Two cars reset with seed 4 (and ``options``) driven ``steps`` steps: (truths, estimates)."""
    env = LocalizedVectorEnv(
        gym.make_vec(
            "RacecarSim-v0", num_envs=2, vectorization_mode="vector_entry_point", **SETTINGS
        ),
        CONFIG,
    )
    obs, info = env.reset(seed=4, options=options)
    truths, estimates = [info["pose"].copy()], [obs["pose_estimate"].copy()]
    for _ in range(steps):
        obs, _, _, _, info = env.step(np.array([[0.1, 1.0], [-0.1, 1.0]]))
        truths.append(info["pose"].copy())
        estimates.append(obs["pose_estimate"].copy())
    env.close()
    return truths, estimates


def test_filter_seed_redraws_every_cars_filter_on_the_same_drive() -> None:
    truths, plain = _vector_drive()
    truths_b, redrawn = _vector_drive({"filter_seed": 1004})
    np.testing.assert_array_equal(truths, truths_b)  # the same drives
    for car in (0, 1):
        assert not np.array_equal([e[car] for e in plain], [e[car] for e in redrawn]), car
    np.testing.assert_array_equal(redrawn, _vector_drive({"filter_seed": 1004})[1])
    # the reset's own seed as filter_seed: each car's filter as without the option
    np.testing.assert_array_equal(plain, _vector_drive({"filter_seed": 4})[1])
    with pytest.raises(ValueError, match=r"option filter_seed = -4 must be a non-negative"):
        _vector_drive({"filter_seed": -4})


def test_wrong_env_and_config() -> None:
    with pytest.raises(TypeError, match="vector env"):
        LocalizedVectorEnv(
            gym.vector.SyncVectorEnv([lambda: gym.make("RacecarSim-v0", **SETTINGS)])
        )
    vec = gym.make_vec(
        "RacecarSim-v0", num_envs=1, vectorization_mode="vector_entry_point", **SETTINGS
    )
    with pytest.raises(ValueError, match="init"):
        LocalizedVectorEnv(vec, {"init": "nowhere"})
    env = LocalizedVectorEnv(vec, CONFIG)
    with pytest.raises(ResetNeeded, match="reset"):
        env.step(np.zeros((1, 2)))
    with pytest.raises(ValueError, match="init_pose"):
        env.reset(seed=0, options={"init_pose": [1.0, 2.0]})
    obs, _ = env.reset(seed=0, options={"init_pose": [[1.0, 2.0, 0.0]], "init_spread": 0.01})
    assert np.hypot(*(obs["pose_estimate"][0, :2] - [1.0, 2.0])) < 0.2  # started where told


def test_init_option_holds_for_that_reset_only() -> None:
    """A global start asked for at reset: the autoresets after it start as the config says, as
    with single wrappers (same seeds, same estimates)."""
    n = 2
    fast = LocalizedVectorEnv(
        gym.make_vec(
            "RacecarSim-v0", num_envs=n, vectorization_mode="vector_entry_point",
            max_episode_steps=4, **SETTINGS,
        ),
        CONFIG,
    )  # fmt: skip
    sync = _sync(n, 4)
    got, want = (
        fast.reset(seed=7, options={"init": "global"}),
        sync.reset(seed=7, options={"init": "global"}),
    )
    np.testing.assert_array_equal(got[0]["pose_estimate"], want[0]["pose_estimate"])
    actions = np.tile([0.0, 1.0], (n, 1))
    for t in range(7):  # an autoreset at step 5
        o1, *_, i1 = fast.step(actions)
        o2, *_, i2 = sync.step(actions)
        np.testing.assert_array_equal(o1["pose_estimate"], o2["pose_estimate"], f"step {t}")
        np.testing.assert_array_equal(
            i1["localization"]["position_error"], i2["localization"]["position_error"]
        )
    assert np.all(i1["localization"]["position_error"] < 0.5)  # the autoreset started at the pose


# ---------------------------------------------------------------------- misuse
def _vec(n: int = 2) -> LocalizedVectorEnv:
    vec = gym.make_vec("RacecarSim-v0", num_envs=n, vectorization_mode="vector_entry_point",
                       n_beams=61, **SETTINGS)  # fmt: skip
    return LocalizedVectorEnv(vec, CONFIG)


def test_a_car_left_out_of_the_first_reset_is_named_not_called_never_reset() -> None:
    env = _vec()
    env.reset(seed=0, options={"reset_mask": [True, False]})
    with pytest.raises(
        ResetNeeded, match=r"car\(s\) \[1\] were never reset \(reset_mask left them out\)"
    ):
        env.step(np.zeros((2, 2)))
    env.reset(seed=1, options={"reset_mask": [False, True]})
    env.step(np.zeros((2, 2)))  # now every car has a filter


def test_reset_options_of_the_wrong_kind_or_place_are_named() -> None:
    env = _vec()
    with pytest.raises(ValueError, match=r"^LocalizedVectorEnv.reset: options must be a dict"):
        env.reset(options=[1, 2])
    with pytest.raises(ValueError, match=r"init_pose must be a finite \(2, 3\) array.*dict"):
        env.reset(options={"init_pose": {"x": 1.0}})
    with pytest.raises(
        ValueError, match=r"init_pose = \[5000.0, 5000.0, 0.0\] is off the filter map"
    ):
        env.reset(options={"init_pose": [5000.0, 5000.0, 0.0]})  # one pose for every car


def test_wrapping_a_single_env_or_a_race_names_the_wrapper_that_takes_it() -> None:
    from racecar_sim.env import RacecarEnv
    from racecar_sim.race.env import RaceEnv

    with pytest.raises(
        TypeError, match=r"got RacecarEnv, a single env: use mcl.LocalizationWrapper"
    ):
        LocalizedVectorEnv(RacecarEnv("corridor", n_beams=61))
    with pytest.raises(
        TypeError, match=r"got RaceEnv, a PettingZoo race .*use mcl.LocalizedRaceEnv"
    ):
        LocalizedVectorEnv(RaceEnv("corridor", n_cars=2, n_beams=61))
