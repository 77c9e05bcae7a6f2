"""Tests of the VESC's view of the car (racecar_sim.sensors.vesc): wheel odometry, its lead, the IMU."""

from __future__ import annotations

import math

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from hypothesis import example, given, settings
from hypothesis import strategies as st

from racecar_sim.env import RacecarEnv
from racecar_sim.maps import OccupancyMap
from racecar_sim.sensors.vesc import ImuParams, actuate, lead_steps, wheel_twist
from racecar_sim.settings.config import CarParams, EnvConfig, merge_settings
from racecar_sim.vector_env import RacecarVectorEnv

QUIET = {
    "range_sigma": 0.0, "p_short": 0.0, "p_max": 0.0, "p_rand": 0.0,
    "odom_proportional": (0.0, 0.0, 0.0), "odom_additive": (0.0, 0.0, 0.0),
}  # fmt: skip
pytestmark = pytest.mark.filterwarnings(
    "ignore:.*(symmetric and normalized|infinity. This is probably).*:UserWarning"
)


def open_map(size_m: float = 30.0) -> OccupancyMap:
    """An empty square hall (walls 3 cells thick), centre at the world origin."""
    n = int(size_m / 0.05)
    occ = np.zeros((n, n), dtype=bool)
    occ[:3] = occ[-3:] = True
    occ[:, :3] = occ[:, -3:] = True
    half = size_m / 2
    return OccupancyMap(occupied=occ, resolution=0.05, origin=(-half, -half, 0.0), name="hall")


HALL = open_map()


def make(**kwargs) -> RacecarEnv:
    kwargs.setdefault("n_beams", 20)
    return RacecarEnv(HALL, **{**QUIET, **kwargs})


def test_wheel_twist_is_the_bicycle_formula() -> None:
    vx, vy, om = wheel_twist(3.0, 0.2, 0.33)
    assert (vx, vy) == (3.0, 0.0)
    assert om == pytest.approx(3.0 * math.tan(0.2) / 0.33, rel=1e-15)
    assert wheel_twist(-1.0, 0.3, 0.33)[2] < 0  # reversing with the wheels left turns right


@settings(max_examples=15)
@given(speed=st.floats(0.5, 7.0), steer=st.floats(-0.42, 0.42))
def test_kinematic_odometry_equals_the_true_twist_on_a_steady_command(speed, steer) -> None:
    """On the kinematic car the VESC reading is the body's twist once the command is reached, to
    float32 rounding and the substep's chord: the body moves ``v h`` along the chord of each
    substep's arc, so its arc-length speed is ``v`` times ``1 + (omega h)² / 24`` to leading order."""
    env = make()
    env.reset(seed=0, options={"pose": [0.0, 0.0, 0.0]})
    h = env.config.substep
    for k in range(60):  # 1.5 s: the speed (7.5 m/s²) and the steering (3.2 rad/s) settle
        obs, _, terminated, _, info = env.step(np.array([steer, speed]))
        assert not terminated
        if k >= 45:
            chord = (info["twist"][2] * h) ** 2 / 24
            assert obs["odom"][1] == 0.0 and abs(info["twist"][1]) < 1e-9
            for c in (0, 2):
                assert obs["odom"][c] == pytest.approx(info["twist"][c], rel=chord * 1.01 + 2e-7)


def test_while_accelerating_the_reading_leads_the_step_average_by_less_than_a_step() -> None:
    env = make()
    env.reset(seed=0, options={"pose": [0.0, 0.0, 0.0]})
    car = env.car_params
    leads = []
    for _ in range(50):  # 5 m/s reached after 0.67 s
        obs, _, _, _, info = env.step(np.array([0.1, 5.0]))
        gap = float(obs["odom"][0]) - float(info["twist"][0])
        assert -1e-4 <= gap <= car.max_accel * env.dt  # wheel speed at the end of the step
        leads.append(gap)
    assert max(leads) > 0.1  # the reading does differ while the speed changes
    assert abs(leads[-1]) < 1e-4  # and not once it has settled


@settings(max_examples=20)
@given(commands=st.lists(st.tuples(st.floats(-0.5, 0.5), st.floats(-3.0, 8.0)), min_size=1,
                         max_size=12))  # fmt: skip
@example(commands=[(0.5, 0.0), (-0.5, 8.0), (0.0, -3.0)])  # beyond the limits both ways
def test_actuate_is_the_physics_own_arithmetic(commands) -> None:
    env = make()
    env.reset(seed=0, options={"pose": [0.0, 0.0, 0.0]})
    car, p = env.car_params, env.physics
    low, high = env.action_space.low.tolist(), env.action_space.high.tolist()  # float32 bounds
    for steer_cmd, speed_cmd in commands:
        target = (min(max(steer_cmd, low[0]), high[0]), min(max(speed_cmd, low[1]), high[1]))
        expected = actuate(p.steer, p.wheel_speed, *target, car, env.dt, env.config.substep)
        env.step(np.array([steer_cmd, speed_cmd]))
        assert (p.steer, p.wheel_speed) == expected  # bit for bit


def _drive(env: RacecarEnv, n: int) -> tuple[np.ndarray, np.ndarray]:
    env.reset(seed=3, options={"pose": [0.0, 0.0, 0.0]})
    odom, poses = [], []
    for k in range(n):
        obs, _, _, _, info = env.step(np.array([0.35 * math.sin(k / 6), 2.0 + 2.0 * math.sin(k / 9)]))
        odom.append(obs["odom"])
        poses.append(info["pose"])
    return np.array(odom), np.array(poses)


def test_odometry_leads_the_motion_by_odom_lead() -> None:
    """With a lead the odometry reads the same as without, while the body follows n steps late."""
    n = lead_steps(0.13, 0.025)
    assert n == 5
    odom0, poses0 = _drive(make(), 80)
    odom_l, poses_l = _drive(make(odom_lead=0.13), 80)
    np.testing.assert_array_equal(odom_l, odom0)
    np.testing.assert_allclose(poses_l[n:], poses0[:-n], rtol=0, atol=1e-12)
    np.testing.assert_allclose(poses_l[:n - 1], np.zeros((n - 1, 3)), atol=1e-12)  # still waiting
    assert np.abs(poses_l[-1] - poses0[-1]).max() > 0.05  # the lead is not nothing


def test_profile_has_the_measured_lead_and_bias() -> None:
    cfg = merge_settings(None, {"noise_profile": "mit_racecar"})
    assert cfg.odom_lead == pytest.approx(0.13)
    assert cfg.odom_bias.scale[0] < -0.03 and cfg.odom_bias.scale[2] > 0.05


def test_imu_is_off_by_default_and_reports_the_true_yaw_rate_with_noise() -> None:
    plain = make()
    assert "imu" not in plain.observation_space.spaces
    assert "imu" not in plain.reset(seed=0)[0]
    env = make(imu={"sigma": 0.02, "bias": 0.05})
    check_env(env)
    env.reset(seed=1, options={"pose": [0.0, 0.0, 0.0]})
    errors = []
    for _ in range(400):
        obs, _, _, _, info = env.step(np.array([0.3, 2.0]))
        assert obs["imu"].shape == (1,) and obs["imu"].dtype == np.float32
        errors.append(float(obs["imu"][0]) - info["twist"][2])
    assert np.mean(errors) == pytest.approx(0.05, abs=0.005)
    assert np.std(errors) == pytest.approx(0.02, rel=0.15)
    assert make(imu=True).imu == ImuParams()


def test_imu_draws_after_the_odometry_so_the_rest_is_unchanged() -> None:
    noisy = {"odom_additive": (0.05, 0.05, 0.05)}
    a, b = make(**noisy), make(imu=True, **noisy)
    oa, _ = a.reset(seed=5)
    ob, _ = b.reset(seed=5)
    assert np.array_equal(oa["odom"], ob["odom"]) and np.array_equal(oa["scan"], ob["scan"])


@pytest.mark.parametrize(
    ("setting", "value", "message"),
    [("odom_lead", -0.1, "odom_lead"), ("imu", {"sigma": -1}, "ImuParams.sigma"),
     ("imu", {"gain": 1}, "imu must be")],
)  # fmt: skip
def test_bad_settings_name_the_setting(setting, value, message) -> None:
    with pytest.raises(ValueError, match=message):
        EnvConfig(**{setting: value})


@pytest.mark.parametrize(("setting", "value"), [("odom_lead", 0.1), ("imu", True)])
def test_vector_env_refuses_what_it_does_not_simulate(setting, value) -> None:
    with pytest.raises(ValueError, match=setting):
        RacecarVectorEnv(2, HALL, n_beams=10, **{setting: value})


def test_car_params_wheelbase_sets_the_yaw_rate() -> None:
    env = make(car=CarParams(wheelbase=0.5))
    env.reset(seed=0, options={"pose": [0.0, 0.0, 0.0]})
    for _ in range(40):
        obs, *_ = env.step(np.array([0.2, 2.0]))
    assert obs["odom"][2] == pytest.approx(2.0 * math.tan(0.2) / 0.5, rel=1e-6)


# ---------------------------------------------------------------------- odometry under slip
GRAVITY = 9.81


def _single_track_env(**kwargs) -> RacecarEnv:
    try:
        return make(car_model="single_track", **kwargs)
    except (TypeError, ValueError) as exc:  # a build without the single-track model
        if "car_model" in str(exc):
            pytest.skip(f"car_model='single_track' is not in this build: {exc}")
        raise


def _steady(env: RacecarEnv, steer: float, speed: float, seconds: float = 4.0):
    """Drive a constant command from rest; the last 20 steps' (odometry, twist, wheel speed,
    slip angle, steering angle) as arrays."""
    env.reset(seed=0, options={"pose": [0.0, 0.0, 0.0]})
    rows = []
    for _ in range(int(seconds / env.dt)):
        obs, _, terminated, _, info = env.step(np.array([steer, speed]))
        assert not terminated
        p = env.physics
        rows.append((*obs["odom"], *info["twist"], p.wheel_speed, p.slip_angle, p.steer))
    return np.array(rows[-20:])


def test_odometry_yaw_rate_differs_from_the_truth_as_the_slip_angles_say() -> None:
    """A steady circle of the single-track car with the tires in their linear range: the VESC's
    yaw rate (wheel speed and steering angle) exceeds the true one by the tires' slip angles,
    and those grow with the lateral acceleration as the cornering stiffnesses say (understeer
    gradient K = (1 / C_Sf - 1 / C_Sr) / (mu g) radians per m/s²)."""
    env = _single_track_env()
    car = env.car_params
    # 0.17 mu g: the brush tires' slip grows 2-3 % faster than linear here (at 0.4 mu g, 20 %)
    steer, speed = 0.05, 3.5
    rows = _steady(env, steer, speed)
    odo_om, tw_vx, tw_vy, tw_om = rows[:, 2], rows[:, 3], rows[:, 4], rows[:, 5]
    wheel, beta = rows[:, 6], rows[:, 7]
    assert np.ptp(tw_om) < 1e-3 * tw_om.mean()  # steady
    L = car.wheelbase
    # The reading is the VESC's formula of the wheels, not the twist.
    np.testing.assert_allclose(odo_om, wheel * math.tan(steer) / L, rtol=1e-6)
    # The slip angles from the motion: rear from the rear axle's velocity (the twist's origin),
    # front from the front axle's (L ahead); the odometry's error is what they leave out.
    alpha_r = -np.arctan2(tw_vy, tw_vx)
    alpha_f = steer - np.arctan2(tw_vy + L * tw_om, tw_vx)
    np.testing.assert_allclose(
        odo_om - tw_om,
        wheel / L * (math.tan(steer) - np.tan(steer - alpha_f) - np.tan(alpha_r)), atol=1e-4,
    )
    assert (odo_om - tw_om).mean() > 0.05 * tw_om.mean()  # understeer: the odometry over-turns
    # The model's own body slip angle (at the centre of gravity) moves the rear axle sideways.
    lr = car.cg_to_rear
    speed_cg = tw_vx / np.cos(beta)
    np.testing.assert_allclose(tw_vy, speed_cg * np.sin(beta) - lr * tw_om, atol=2e-3)
    # Linear tires: the slip angle difference is the understeer gradient times the lateral
    # acceleration.
    k_us = (1 / car.cornering_front - 1 / car.cornering_rear) / (car.friction * GRAVITY)
    lateral = tw_vx * tw_om
    assert lateral.mean() < 0.5 * car.friction * GRAVITY
    assert (alpha_f - alpha_r).mean() == pytest.approx(k_us * lateral.mean(), rel=0.15)


def test_beyond_the_friction_limit_the_odometry_turns_far_more_than_the_car() -> None:
    env = _single_track_env()
    car = env.car_params
    rows = _steady(env, 0.35, 7.0)
    odo_om, tw_vx, tw_om = rows[:, 2], rows[:, 3], rows[:, 5]
    lateral = np.hypot(tw_vx, rows[:, 4]) * np.abs(tw_om)
    assert lateral.mean() <= 1.05 * car.friction * GRAVITY  # the tires saturate
    assert odo_om.mean() > 2.0 * tw_om.mean()  # the VESC's kinematic yaw rate does not


@settings(max_examples=50)
@given(
    st.lists(st.tuples(st.floats(-0.5, 0.5), st.floats(-3.0, 9.0)), min_size=1, max_size=8),
    st.integers(0, 2**31),
)
def test_vesc_odometry_of_many_cars_is_each_cars_own_measurement(cars, seed):
    # The race's batched odometry against the single env's: wheel_twist, then Odometry.noisy
    # drawing its six normals from the same generator state: the same float32s.
    from racecar_sim.sensors.odometry import Odometry, OdometryNoise
    from racecar_sim.sensors.vesc import vesc_odometry

    odo = Odometry(OdometryNoise(proportional=(0.05, 0.02, 0.1), additive=(0.01, 0.003, 0.02)))
    wheelbase = CarParams().wheelbase
    steer, speed = np.array(cars).T.copy()
    z = np.random.default_rng(seed).standard_normal((len(cars), 6))
    out = np.empty((len(cars), 3), dtype=np.float32)
    vesc_odometry(steer, speed, wheelbase, z, odo._prop, odo._add, out)
    rng = np.random.default_rng(seed)
    for j, (s, v) in enumerate(cars):
        expect = odo.noisy(*wheel_twist(v, s, wheelbase), rng)
        np.testing.assert_array_equal(out[j], expect)
