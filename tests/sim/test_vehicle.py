"""Tests of the car models (racecar_sim.car.models): the single-track car's analytic limits, its
integration error, and both models selectable everywhere a car is made."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import racecar_sim  # noqa: F401  (registers RacecarSim-v0)
from racecar_sim.car.models.manoeuvres import drive, skidpad
from racecar_sim.car.physics import RacecarPhysics
from racecar_sim.env import RacecarEnv
from racecar_sim.maps import OccupancyMap
from racecar_sim.settings.config import CarParams, EnvConfig, load_config
from racecar_sim.vector_env import RacecarVectorEnv
from tests.gym_checks import check_env_as_designed

G = 9.81
CAR = CarParams()
OPEN_FIELD = OccupancyMap(occupied=np.pad(np.zeros((396, 396), bool), 2, constant_values=True),
                          resolution=0.05)  # fmt: skip


def understeer_gradient(car: CarParams) -> float:
    """rad per m/s² of lateral acceleration, from the parameters alone: the linear single-track
    car's ``(m / L) (lr / C_af - lf / C_ar)`` with CommonRoad's axle stiffness ``C_a = mu C_S Fz``
    and static loads, which is ``(1 / C_Sf - 1 / C_Sr) / (mu g)``."""
    return (1.0 / car.cornering_front - 1.0 / car.cornering_rear) / (car.friction * G)


@pytest.mark.parametrize("steer", [0.1, 0.2, 0.35, -0.3])
def test_low_speed_circle_is_the_kinematic_one(steer: float) -> None:
    # At 1 m/s the single-track car is fully dynamic, but its tires barely slip.
    circle = skidpad(CAR, "single_track", steer, 1.0)
    assert circle.steady
    kinematic = CAR.wheelbase / math.tan(abs(steer))
    assert abs(circle.rear_radius) == pytest.approx(kinematic, rel=0.03)
    assert math.copysign(1.0, circle.yaw_rate) == math.copysign(1.0, steer)


@settings(max_examples=30)
@given(steer=st.floats(0.05, CAR.max_steer), speed=st.floats(1.0, 15.0))
def test_steady_lateral_acceleration_stays_within_the_friction(steer: float, speed: float) -> None:
    car = CarParams(max_speed=15.0)
    circle = skidpad(car, "single_track", steer, speed, duration=6.0)
    assert abs(circle.lateral_accel) <= 1.01 * car.friction * G
    # the kinematic car on the same command would corner far harder than the friction allows
    kinematic = speed**2 * math.tan(steer) / car.wheelbase
    if kinematic > 2 * car.friction * G:
        assert abs(circle.lateral_accel) < 0.5 * kinematic


@pytest.mark.parametrize(("front", "rear"), [(4.718, 5.4562), (5.4562, 4.718), (3.0, 6.0)])
def test_understeer_follows_the_parameters(front: float, rear: float) -> None:
    # Small steer, small lateral acceleration (under 0.1 mu g): the linear range of the tires.
    car = CarParams(cornering_front=front, cornering_rear=rear)
    expected = understeer_gradient(car)
    steer = 0.04
    low, high = skidpad(car, "single_track", steer, 1.0), skidpad(car, "single_track", steer, 3.0)
    assert low.steady and high.steady
    # steer = atan(L / R_rear) + K a_y: K from two circles, the geometry cancelling out
    k = (math.atan(car.wheelbase / low.rear_radius) - math.atan(car.wheelbase / high.rear_radius))
    k /= high.lateral_accel - low.lateral_accel
    assert k == pytest.approx(expected, rel=0.1)
    assert math.copysign(1.0, k) == math.copysign(1.0, expected)


def test_braking_in_a_turn_shares_the_friction_circle() -> None:
    # A steady circle near the limit, then full braking: the acceleration of the centre of
    # gravity stays inside the friction circle (combined slip): less is left for cornering.
    car = CarParams()
    dt = 0.01
    commands = np.array([[0.25, 4.0]] * 600 + [[0.25, 0.0]] * 40)
    rows = drive(car, "single_track", commands, dt)
    v, beta = rows[:, 7], rows[:, 5]  # speed and slip angle of the centre of gravity
    heading = rows[:, 2] + beta  # direction of the velocity of the centre of gravity
    along = np.gradient(v, dt)
    across = v * np.gradient(np.unwrap(heading), dt)
    braking = slice(603, 625)  # full braking, above the kinematic car's speeds
    assert along[braking].max() < -0.8 * car.max_decel
    total = np.hypot(along[braking], across[braking])
    assert total.max() <= 1.02 * car.friction * G
    assert abs(across[braking]).mean() < 0.6 * abs(across[550:600]).mean()


MANOEUVRES = {
    "sine 5 m/s": lambda t: np.c_[0.3 * np.sin(math.pi * t), np.full_like(t, 5.0)],
    "sine 7 m/s": lambda t: np.c_[0.4 * np.sin(1.4 * math.pi * t), np.full_like(t, 7.0)],
    "steps": lambda t: np.c_[np.where(t % 2 < 1, 0.15, -0.1), np.where(t < 2.5, 3.0, 6.0)],
}


@pytest.mark.parametrize("name", list(MANOEUVRES))
def test_step_size_error_is_small(name: str) -> None:
    # The same 5 s manoeuvre with the default 5 ms substeps and with 1.25 ms ones.
    dt = 0.02
    commands = MANOEUVRES[name](np.arange(250) * dt)
    coarse = drive(CAR, "single_track", commands, dt, substep=0.005)
    fine = drive(CAR, "single_track", commands, dt, substep=0.00125)
    diff = coarse - fine
    assert np.hypot(diff[:, 0], diff[:, 1]).max() < 0.015  # metres
    assert abs(diff[:, 2]).max() < 0.003  # rad, heading
    assert abs(diff[:, 5]).max() < 0.002  # rad, slip angle


def test_wheel_speed_and_steer_of_both_models() -> None:
    slips = {}
    for model in ("kinematic", "single_track"):
        phys = RacecarPhysics(OPEN_FIELD, car_model=model)
        phys.reset(np.array([10.0, 10.0, 0.0]))
        for _ in range(40):
            assert not phys.step((0.3, 4.0), 0.025)
        assert phys.steer == pytest.approx(0.3)
        assert phys.wheel_speed == phys.speed == pytest.approx(4.0, abs=0.05)
        slips[model] = phys.slip_angle
        with pytest.raises(AttributeError):
            phys.wheel_speed = 1.0  # type: ignore[misc]
    geometric = math.atan(CAR.cg_to_rear * math.tan(0.3) / CAR.wheelbase)
    assert slips["kinematic"] == pytest.approx(geometric)
    assert slips["single_track"] < geometric - 0.05  # at 4 m/s the rear tires slip outwards


def test_car_model_is_a_setting_everywhere(tmp_path) -> None:
    path = tmp_path / "env.yaml"
    path.write_text("car_model: single_track\nmap: corridor\n")
    env = gym.make("RacecarSim-v0", config=load_config(path))
    assert env.unwrapped.physics.car_model == "single_track"
    check_env_as_designed(env.unwrapped, skip_render_check=True)
    assert RacecarEnv("corridor").physics.car_model == "kinematic"
    vec = RacecarVectorEnv(3, map="corridor", car_model="single_track")
    assert {e.physics.car_model for e in vec.envs} == {"single_track"}
    with pytest.raises(ValueError, match="car_model must be one of"):
        EnvConfig(car_model="dynamic")


def test_single_track_vector_env_equals_single_envs() -> None:
    settings_ = {"map": "corridor", "dt": 0.03, "terminate_on_collision": False,
                 "car_model": "single_track"}  # fmt: skip
    n = 3
    vec = RacecarVectorEnv(n, **settings_)
    singles = [RacecarEnv(**settings_) for _ in range(n)]
    obs, _ = vec.reset(seed=4)
    for i, env in enumerate(singles):
        o, _ = env.reset(seed=4 + i)
        np.testing.assert_array_equal(o["scan"], obs["scan"][i])
    rng = np.random.default_rng(1)
    for _ in range(120):
        actions = np.column_stack([rng.uniform(-0.4, 0.4, n), rng.uniform(0.0, 7.0, n)])
        got = vec.step(actions)
        for i, env in enumerate(singles):
            o, r, *_ = env.step(actions[i])
            np.testing.assert_array_equal(o["odom"], got[0]["odom"][i])
            np.testing.assert_array_equal(o["scan"], got[0]["scan"][i])
            assert r == got[1][i]


def test_single_track_car_stays_out_of_walls() -> None:
    env = RacecarEnv("corridor", car_model="single_track", terminate_on_collision=False)
    env.reset(seed=3)
    hits = 0
    for _ in range(300):
        _, _, _, _, info = env.step(np.array([0.4, 7.0], dtype=np.float32))
        hits += info["collision"]
        assert env.physics.pose_is_free(env.physics.pose) or info["collision"]
    assert hits > 0


def test_car_params_validate_the_new_fields() -> None:
    with pytest.raises(ValueError, match="cg_to_rear"):
        CarParams(cg_to_rear=0.5)
    with pytest.raises(ValueError, match="dynamic_above"):
        CarParams(kinematic_below=1.0, dynamic_above=0.5)
    with pytest.raises(ValueError, match="friction"):
        CarParams(friction=0.0)
    assert CarParams().cg_to_rear == pytest.approx(0.33 * 0.17145 / 0.3302)
    f1 = CarParams.f1tenth()
    assert (f1.wheelbase - f1.cg_to_rear, f1.cg_to_rear) == pytest.approx((0.15875, 0.17145))
