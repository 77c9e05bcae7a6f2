"""Tests of racecar_sim.env.RacecarEnv: Gymnasium API, determinism, sensors timing, walls, config."""

from __future__ import annotations

import importlib
import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import racecar_sim
from racecar_sim.env import EnvConfig, RacecarEnv
from racecar_sim.maps import MapError, OccupancyMap, bundled_names
from racecar_sim.render import CAR_COLOUR, MapRenderer

FEW_BEAMS = 60
QUIET = {  # no sensor noise at all
    "range_sigma": 0.0,
    "p_short": 0.0,
    "p_max": 0.0,
    "p_rand": 0.0,
    "odom_proportional": (0.0, 0.0, 0.0),
    "odom_additive": (0.0, 0.0, 0.0),
}
pytestmark = pytest.mark.filterwarnings(
    "ignore:.*(symmetric and normalized|infinity. This is probably).*:UserWarning"
)


def room_map() -> OccupancyMap:
    """A 6 m x 6 m room (walls 3 cells thick), centre at the world origin."""
    occ = np.zeros((120, 120), dtype=bool)
    occ[:3] = occ[-3:] = True
    occ[:, :3] = occ[:, -3:] = True
    return OccupancyMap(occupied=occ, resolution=0.05, origin=(-3.0, -3.0, 0.0), name="room")


@pytest.fixture(scope="module")
def map_spec() -> str | OccupancyMap:
    """The bundled default map when it is there, else a small room."""
    return "basement_loop" if "basement_loop" in bundled_names() else room_map()


def make(map_spec, **kwargs) -> RacecarEnv:
    kwargs.setdefault("n_beams", FEW_BEAMS)
    return RacecarEnv(map_spec, **kwargs)


# ---------------------------------------------------------------------- Gymnasium API
def test_check_env_passes(map_spec) -> None:
    env = gym.make("RacecarSim-v0", map=map_spec, n_beams=FEW_BEAMS, render_mode="rgb_array")
    check_env(env.unwrapped, skip_render_check=False)
    env.close()


def test_make_with_defaults_works() -> None:
    env = gym.make("RacecarSim-v0")
    obs, info = env.reset(seed=0)
    assert obs["scan"].shape == (1080,) and obs["scan"].dtype == np.float32
    assert obs["odom"].shape == (3,) and obs["odom"].dtype == np.float32
    obs, reward, _, truncated, info = env.step(env.action_space.sample())
    assert env.observation_space.contains(obs)
    assert isinstance(reward, float) and truncated is False
    assert {"pose", "twist", "collision", "time", "new_scan", "rewards"} <= set(info)
    env.close()


def test_registration_survives_reimport() -> None:
    importlib.reload(racecar_sim)
    importlib.reload(racecar_sim)
    assert gym.spec("RacecarSim-v0").entry_point == "racecar_sim.env:RacecarEnv"


def test_spaces_follow_the_settings(map_spec) -> None:
    env = make(map_spec, max_range=12.0, car={"max_speed": 3.0, "max_steer": 0.3})
    assert env.observation_space["scan"].shape == (FEW_BEAMS,)
    assert env.observation_space["scan"].high.max() == pytest.approx(12.0)
    assert env.action_space.high == pytest.approx([0.3, 3.0])
    assert env.action_space.low == pytest.approx([-0.3, -env.car_params.max_reverse_speed])


def test_same_seed_same_observations_different_seed_differs(map_spec) -> None:
    def rollout(seed: int) -> list[dict[str, np.ndarray]]:
        env = make(map_spec, terminate_on_collision=False)
        actions = np.random.default_rng(99).uniform(
            env.action_space.low, env.action_space.high, size=(200, 2)
        )
        obs, _ = env.reset(seed=seed)
        out = [obs]
        for action in actions:
            obs, *_ = env.step(action)
            out.append(obs)
        return out

    a, b, c = rollout(5), rollout(5), rollout(6)
    for oa, ob in zip(a, b, strict=True):
        assert np.array_equal(oa["scan"], ob["scan"]) and np.array_equal(oa["odom"], ob["odom"])
    assert not np.array_equal(a[0]["scan"], c[0]["scan"])


def test_vector_envs_step() -> None:
    def factory():
        return gym.make("racecar_sim:RacecarSim-v0", n_beams=30, terminate_on_collision=False)

    # "spawn": numba's GNU OpenMP thread pool, once used in this process, forbids fork().
    for envs in (
        gym.vector.SyncVectorEnv([factory, factory]),
        gym.vector.AsyncVectorEnv([factory, factory], context="spawn"),
    ):
        obs, _ = envs.reset(seed=[1, 2])
        assert obs["scan"].shape == (2, 30)
        for _ in range(3):
            obs, rewards, *_ = envs.step(envs.action_space.sample())
        assert obs["odom"].shape == (2, 3) and rewards.shape == (2,)
        assert not np.array_equal(obs["scan"][0], obs["scan"][1])
        envs.close()


# ---------------------------------------------------------------------- reset
def test_random_starts_are_free_with_clearance(map_spec) -> None:
    env = make(map_spec)
    grid = env.map
    for seed in range(15):
        _, info = env.reset(seed=seed)
        pose = info["pose"]
        assert env.physics.pose_is_free(pose)
        # The footprint grown by start_clearance on every side still lies in free cells.
        fp = env.physics.footprint(pose)
        grow = env.config.start_clearance
        along = (fp[1] - fp[0]) / np.linalg.norm(fp[1] - fp[0])
        across = (fp[3] - fp[0]) / np.linalg.norm(fp[3] - fp[0])
        s, t = np.meshgrid(np.linspace(0, 1, 25), np.linspace(0, 1, 25))
        length = np.linalg.norm(fp[1] - fp[0]) + 2 * grow
        width = np.linalg.norm(fp[3] - fp[0]) + 2 * grow
        start = fp[0] - grow * (along + across)
        pts = start + (s.reshape(-1, 1) * length) * along + (t.reshape(-1, 1) * width) * across
        assert grid.is_free(pts).all()
    thetas = [env.reset(seed=s)[1]["pose"][2] for s in range(15)]
    assert np.ptp(thetas) > 1.0  # headings are random too


def test_reset_to_a_given_pose_and_bad_poses(map_spec) -> None:
    env = make(map_spec)
    _, info = env.reset(seed=0)
    pose = info["pose"].copy()
    _, info = env.reset(seed=1, options={"pose": pose.tolist()})
    assert info["pose"] == pytest.approx(pose)
    occupied_rc = np.argwhere(env.map.occupied)[len(np.argwhere(env.map.occupied)) // 2]
    inside_wall = [*env.map.grid_to_world(occupied_rc), 0.0]
    with pytest.raises(ValueError, match=r"pose"):
        env.reset(options={"pose": inside_wall})
    with pytest.raises(ValueError, match=r"pose"):
        env.reset(options={"pose": [1e4, 1e4, 0.0]})
    with pytest.raises(ValueError, match=r"pose"):
        env.reset(options={"pose": [0.0, math.nan, 0.0]})
    with pytest.raises(ValueError, match="speed"):
        env.reset(options={"speed": 1.0})


def test_unknown_map_lists_the_bundled_ones() -> None:
    if not bundled_names():
        pytest.skip("no bundled maps yet")
    with pytest.raises(MapError, match=bundled_names()[0]):
        RacecarEnv("no_such_map")


# ---------------------------------------------------------------------- actions
def test_non_finite_or_malformed_actions_raise(map_spec) -> None:
    env = make(map_spec)
    env.reset(seed=0)
    for bad in ([math.nan, 1.0], [0.0, math.inf], np.array([0.1, np.nan], np.float32)):
        with pytest.raises(ValueError, match="action"):
            env.step(bad)
    with pytest.raises(ValueError, match="action"):
        env.step([0.1, 0.2, 0.3])


def test_a_masked_action_is_refused_not_driven_by_its_hidden_value(map_spec) -> None:
    env = make(map_spec)
    env.reset(seed=0)
    before = env.pose.copy()
    with pytest.raises(ValueError, match="masked"):
        env.step(np.ma.array([0.0, 5.0], mask=[False, True]))
    np.testing.assert_array_equal(env.pose, before)  # nothing was driven


def test_reset_options_of_the_wrong_kind_are_one_message_naming_them(map_spec) -> None:
    env = make(map_spec)
    with pytest.raises(ValueError, match=r"RacecarEnv.reset: options must be a dict.*list"):
        env.reset(options=[1, 2])
    for pose, kind in (({"x": 1.0}, "dict"), ("abc", "str")):
        with pytest.raises(ValueError, match=rf"options\['pose'\].*{kind}"):
            env.reset(options={"pose": pose})


def test_a_negative_seed_is_refused_in_words_not_by_gymnasium(map_spec) -> None:
    env = make(map_spec)
    with pytest.raises(ValueError, match=r"RacecarEnv.reset: seed must be a non-negative int"):
        env.reset(seed=-1)


def test_actions_outside_the_box_are_clipped(map_spec) -> None:
    a, b = make(map_spec), make(map_spec)
    a.reset(seed=3)
    b.reset(seed=3)
    high = b.action_space.high
    for _ in range(10):
        oa, ra, _, _, ia = a.step(np.array([10.0, 100.0]))
        ob, rb, _, _, ib = b.step(high)
        assert np.array_equal(oa["scan"], ob["scan"]) and np.array_equal(oa["odom"], ob["odom"])
        assert ra == rb and np.array_equal(ia["pose"], ib["pose"])


# ---------------------------------------------------------------------- sensors and rewards
def test_scans_come_at_the_lidar_rate_and_repeat_between(map_spec) -> None:
    dt, rate = 0.01, 40.0
    env = make(map_spec, dt=dt, lidar_rate=rate, terminate_on_collision=False, **QUIET)
    obs, info = env.reset(seed=0)
    assert info["new_scan"]
    # The first scan after a reset is fresh: it is the exact scan of the start pose.
    assert np.array_equal(obs["scan"], env.lidar.true_ranges(info["pose"]).astype(np.float32))
    last = obs["scan"]
    fresh_steps = []
    for k in range(1, 101):
        obs, _, _, _, info = env.step(np.array([0.2, 1.0]))
        assert info["time"] == pytest.approx(k * dt)
        if info["new_scan"]:
            fresh_steps.append(k)
            expected = env.lidar.true_ranges(info["pose"]).astype(np.float32)
            assert np.array_equal(obs["scan"], expected)
        else:
            assert np.array_equal(obs["scan"], last)
        last = obs["scan"]
    # A new scan on the first step whose end reaches each multiple of the lidar period.
    period = 1.0 / rate
    expected_steps = [
        k
        for k in range(1, 101)
        if math.floor(k * dt / period + 1e-9) > math.floor((k - 1) * dt / period + 1e-9)
    ]
    assert fresh_steps == expected_steps
    assert len(fresh_steps) == pytest.approx(rate * 100 * dt, abs=1)


def test_noisy_scan_is_redrawn_each_scan_only(map_spec) -> None:
    env = make(map_spec, dt=0.01)
    obs, _ = env.reset(seed=0, options={"pose": env.reset(seed=0)[1]["pose"]})
    scans = [obs["scan"]]
    news = []
    for _ in range(6):
        obs, _, _, _, info = env.step(np.array([0.0, 0.0]))  # standing still
        scans.append(obs["scan"])
        news.append(info["new_scan"])
    for k, new in enumerate(news, start=1):
        assert np.array_equal(scans[k], scans[k - 1]) != new  # fresh noise only on a new scan


def test_twist_explains_the_motion_and_odometry_is_the_vesc_reading(map_spec) -> None:
    env = make(map_spec, terminate_on_collision=False, **QUIET)
    _, info = env.reset(seed=4)
    dt = env.dt
    wheelbase = env.car_params.wheelbase
    for k in range(80):
        before = info["pose"]
        obs, reward, _, _, info = env.step(np.array([0.3 * math.sin(k / 10), 2.0]))
        vx, vy, om = info["twist"]
        # The odometry is what the VESC reads: wheel speed and the steering angle's yaw rate.
        speed, steer = env.physics.wheel_speed, env.physics.steer
        expected = [speed, 0.0, speed * math.tan(steer) / wheelbase]
        assert np.array_equal(obs["odom"], np.array(expected, dtype=np.float32))
        # Integrate the constant twist over dt as an arc (SE(2) exponential).
        dth = om * dt
        a = math.sin(dth) / dth if dth else 1.0
        b = (1 - math.cos(dth)) / dth if dth else 0.0
        lx, ly = (a * vx - b * vy) * dt, (b * vx + a * vy) * dt
        c, s = math.cos(before[2]), math.sin(before[2])
        predicted = [before[0] + c * lx - s * ly, before[1] + s * lx + c * ly]
        assert info["pose"][:2] == pytest.approx(predicted, abs=1e-9)
        if not info["collision"]:
            assert reward == pytest.approx(info["rewards"]["progress"])
            assert info["rewards"]["progress"] == pytest.approx(vx * dt)


def test_odometry_noise_is_applied(map_spec) -> None:
    env = make(map_spec, odom_proportional=(0.0, 0.0, 0.0), odom_additive=(0.05, 0.05, 0.05))
    env.reset(seed=0)
    diffs = []
    for _ in range(40):
        obs, _, _, _, info = env.step(np.array([0.0, 0.0]))
        diffs.append(obs["odom"] - info["twist"])
    sd = np.std(diffs, axis=0)
    assert (sd > 0.025).all() and (sd < 0.1).all()


# ---------------------------------------------------------------------- walls
def test_driving_into_a_wall_terminates_with_a_penalty() -> None:
    env = RacecarEnv(room_map(), n_beams=FEW_BEAMS, collision_penalty=2.0)
    env.reset(seed=0, options={"pose": [0.0, 0.0, 0.0]})
    for _ in range(200):
        _, reward, terminated, _, info = env.step(np.array([0.0, 7.0]))
        if terminated:
            break
    assert terminated and info["collision"]
    assert info["rewards"]["collision"] == -2.0
    assert reward == pytest.approx(info["rewards"]["progress"] - 2.0)
    assert info["pose"][0] < 3.0 - 0.15 - 0.44 + 0.04  # rear axle: the front bumper is at the wall


def test_without_termination_the_car_stays_outside_the_wall() -> None:
    grid = room_map()
    env = RacecarEnv(grid, n_beams=FEW_BEAMS, terminate_on_collision=False)
    env.reset(seed=0, options={"pose": [0.0, 0.0, 0.7]})
    car = env.car_params
    tolerance = car.max_speed * env.config.substep + 0.002  # a substep of travel plus slop
    collisions = []
    for _ in range(120):
        _, _, terminated, _, info = env.step(np.array([0.0, car.max_speed]))
        assert not terminated
        collisions.append(info["collision"])
        fp = env.physics.footprint()
        # Every point of the footprint shrunk by the tolerance lies in a free cell.
        centre = fp.mean(axis=0)
        shrunk = centre + (fp - centre) * (1 - 2 * tolerance / car.width)
        s, t = np.meshgrid(np.linspace(0, 1, 20), np.linspace(0, 1, 20))
        pts = shrunk[0] + s.reshape(-1, 1) * (shrunk[1] - shrunk[0])
        pts = pts + t.reshape(-1, 1) * (shrunk[3] - shrunk[0])
        assert grid.is_free(pts).all()
    assert any(collisions) and collisions[-1]


def test_teleport_moves_the_car_silently() -> None:
    env = gym.make("RacecarSim-v0", map=room_map(), n_beams=FEW_BEAMS, dt=0.01, **QUIET)
    env.reset(seed=0, options={"pose": [-1.0, -1.0, 0.0]})
    for _ in range(5):
        env.step(np.array([0.0, 2.0]))
    target = np.array([1.5, 1.0, 2.0])
    env.unwrapped.teleport(target)
    obs, _, _, _, info = env.step(np.array([0.0, 0.0]))
    assert info["pose"] == pytest.approx(target, abs=1e-9)  # at rest, no old motion
    assert info["time"] == pytest.approx(0.06)  # the clock went on
    for _ in range(3):
        obs, _, _, _, info = env.step(np.array([0.0, 0.0]))
        if info["new_scan"]:
            break
    assert np.array_equal(obs["scan"], env.unwrapped.lidar.true_ranges(target).astype(np.float32))
    with pytest.raises(ValueError, match="pose"):
        env.unwrapped.teleport([2.99, 0.0, 0.0])


# ---------------------------------------------------------------------- config
def test_yaml_config_and_keyword_overrides(tmp_path, map_spec) -> None:
    path = tmp_path / "env.yaml"
    path.write_text(
        "n_beams: 50\ndt: 0.01\nmax_range: 15.0\nterminate_on_collision: false\n"
        "odom_additive: [0.01, 0.0, 0.02]\ncar:\n  max_speed: 3.0\n"
    )
    env = RacecarEnv(map_spec, config=path, max_range=20.0)
    assert env.lidar_params.n_beams == 50
    assert env.dt == 0.01
    assert env.lidar_params.max_range == 20.0  # the keyword wins over the file
    assert env.config.terminate_on_collision is False
    assert env.odometry_noise.additive == (0.01, 0.0, 0.02)
    assert env.car_params.max_speed == 3.0
    made = gym.make("RacecarSim-v0", map=map_spec, config=str(path))
    assert made.observation_space["scan"].shape == (50,)
    made.close()


def test_config_errors_name_the_setting(tmp_path, map_spec) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("n_beams: 50\nwheel_radius: 0.05\n")
    with pytest.raises(ValueError, match="wheel_radius"):
        RacecarEnv(map_spec, config=path)
    with pytest.raises(ValueError, match="beams_per_scan"):
        RacecarEnv(map_spec, beams_per_scan=10)
    with pytest.raises(ValueError, match=r"range_sigma|sigma"):
        RacecarEnv(map_spec, range_sigma=-1.0)
    with pytest.raises(ValueError, match="dt"):
        RacecarEnv(map_spec, dt=0.0)
    with pytest.raises(ValueError, match="not found"):
        RacecarEnv(map_spec, config=tmp_path / "missing.yaml")
    with pytest.raises(ValueError, match="CarParams"):
        RacecarEnv(map_spec, car={"max_sped": 3.0})


def test_env_config_defaults_match_the_parameter_classes() -> None:
    from racecar_sim.settings.config import LidarParams, OdometryNoise

    cfg = EnvConfig()
    assert cfg.lidar_params() == LidarParams()
    assert cfg.odometry_noise() == OdometryNoise()


# ---------------------------------------------------------------------- rendering
def test_render_shows_the_car_and_calls_hooks() -> None:
    env = gym.make("RacecarSim-v0", map=room_map(), n_beams=FEW_BEAMS, render_mode="rgb_array")
    env.reset(seed=0, options={"pose": [0.0, 0.0, 0.5]})
    calls = []
    marker = (1, 2, 3)

    def hook(img: np.ndarray, renderer: MapRenderer) -> None:
        calls.append(renderer)
        x, y = renderer.world_to_pixel(np.array([-2.0, -2.0]))
        img[y - 2 : y + 3, x - 2 : x + 3] = marker

    env.unwrapped.add_render_hook(hook)
    frame = env.render()
    renderer = env.unwrapped.renderer
    assert frame.dtype == np.uint8 and frame.shape == (renderer.size[1], renderer.size[0], 3)
    car = (frame == np.array(CAR_COLOUR, np.uint8)).all(axis=-1)
    x, y = renderer.world_to_pixel(env.unwrapped.physics.footprint().mean(axis=0))
    assert car[y, x] and car.sum() > 20
    assert len(calls) == 1 and isinstance(calls[0], MapRenderer)
    assert (frame == np.array(marker, np.uint8)).all(axis=-1).sum() == 25
    env.unwrapped.remove_render_hook(hook)
    env.render()
    assert len(calls) == 1


def test_render_without_render_mode_returns_none(map_spec) -> None:
    env = make(map_spec)
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="render_mode"):
        assert env.render() is None
    with pytest.raises(ValueError, match="render_mode"):
        make(map_spec, render_mode="human")


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_a_copied_env_steps_on_exactly_as_the_original(how: str) -> None:
    """An env copied whole mid-episode (its core, clock and generator with it) gives the same
    observations and times as the original from there on."""
    import copy
    import pickle

    env = RacecarEnv("corridor", n_beams=FEW_BEAMS, odom_lead=0.05)
    env.reset(seed=4)
    for _ in range(5):
        env.step(np.array([0.1, 1.0]))
    twin = copy.deepcopy(env) if how == "deepcopy" else pickle.loads(pickle.dumps(env))
    assert twin.fleet is not env.fleet and twin.fleet.cars == [twin]
    for k in range(40):
        action = np.array([0.3 * math.sin(0.3 * k), 1.5])
        (a, _, _, _, ia), (b, _, _, _, ib) = env.step(action), twin.step(action)
        for key in a:
            np.testing.assert_array_equal(a[key], b[key])
        assert ia["time"] == ib["time"] and ia["new_scan"] == ib["new_scan"]
