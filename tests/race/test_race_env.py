"""RaceEnv: PettingZoo's own API test, cars seeing and hitting each other, the one-car case, seeds."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from gymnasium.error import ResetNeeded
from hypothesis import given
from hypothesis import strategies as st
from pettingzoo.test import parallel_api_test
from race_helpers import QUIET, hall_map, penetration

import racecar_sim
from racecar_sim.env import RacecarEnv
from racecar_sim.race.env import RaceEnv

HALL = hall_map()
CAR = racecar_sim.env.CarParams()
MOUNT = 0.275  # the default lidar mount, metres ahead of the rear axle


def quiet_race(n: int = 2, **kw) -> RaceEnv:
    return RaceEnv(HALL, n_cars=n, n_beams=kw.pop("n_beams", 1081), max_range=30.0, **QUIET, **kw)


def test_pettingzoo_parallel_api_test_passes():
    env = RaceEnv(HALL, n_cars=3, n_beams=61, max_episode_steps=150)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # PettingZoo's probe option {"options": 1} warns nothing
        parallel_api_test(env, num_cycles=200)


def test_render_without_a_render_mode_warns_in_plain_text():
    for env in (RaceEnv(HALL, n_cars=1, n_beams=61), RacecarEnv(HALL, n_beams=61)):
        env.reset(seed=0)
        with pytest.warns(UserWarning, match="without a render_mode") as caught:
            assert env.render() is None
        assert "\x1b" not in str(caught[0].message)  # no terminal colour codes in logs


def test_options_it_does_not_know_are_ignored_but_a_misspelt_poses_is_refused():
    env = RaceEnv(HALL, n_cars=2, n_beams=61)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env.reset(seed=0, options={"options": 1, "init": "global"})  # e.g. a wrapper's, PettingZoo's
    for typo in ("pose", "Poses", "posses"):
        with pytest.raises(ValueError, match=r"unknown option .*did you mean 'poses'"):
            env.reset(seed=0, options={typo: env.poses})


def test_parallel_api_test_on_a_track_with_crashes():
    # The bundled loop with its derived centerline: the grid start, random actions crash cars.
    env = RaceEnv("basement_loop", n_cars=4, n_beams=61, max_episode_steps=300)
    parallel_api_test(env, num_cycles=300)


def test_a_car_ahead_shows_in_the_scan_at_its_range():
    env = quiet_race()
    # car_1 4 m ahead facing car_0: its front bumper is length - rear overhang ahead of its axle.
    poses = np.array([[10.0, 5.0, 0.0], [14.0, 5.0, math.pi]])
    obs, _ = env.reset(seed=0, options={"poses": poses})
    front = CAR.length - CAR.rear_overhang
    expect = (14.0 - front) - (10.0 + MOUNT)
    mid = 540  # beam 540 of 1081 points straight ahead
    assert obs["car_0"]["scan"][mid] == pytest.approx(expect, abs=1e-5)
    assert obs["car_1"]["scan"][mid] == pytest.approx(expect, abs=1e-5)
    # Beams just past the box's edges see the far wall (the hall is 30 m long).
    half_angle = math.atan2(CAR.width / 2, expect)
    step = env.lidar_params.fov / 1080
    outside = int(math.ceil(half_angle / step)) + 2
    assert obs["car_0"]["scan"][mid + outside] > 10.0
    assert obs["car_0"]["scan"][mid - outside] > 10.0


def test_a_car_behind_the_lidar_field_of_view_is_not_seen():
    env = quiet_race()
    poses = np.array([[10.0, 5.0, 0.0], [7.0, 5.0, 0.0]])  # car_1 right behind car_0's blind spot
    alone = quiet_race(1)
    o2, _ = env.reset(seed=0, options={"poses": poses})
    o1, _ = alone.reset(seed=0, options={"poses": poses[:1]})
    np.testing.assert_array_equal(o2["car_0"]["scan"], o1["car_0"]["scan"])
    assert o2["car_1"]["scan"][540] < 3.0  # but car_1 sees car_0's rear


def _on_box_boundary(point: np.ndarray, box: np.ndarray) -> float:
    """Distance (m) from a point to the nearest edge of a box (4, 2)."""
    best = np.inf
    for k in range(4):
        a, b = box[k], box[(k + 1) % 4]
        t = np.clip((point - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
        best = min(best, float(np.hypot(*(point - a - t * (b - a)))))
    return best


def _inside(points: np.ndarray, box: np.ndarray) -> np.ndarray:
    """bool (...,): whether points (..., 2) lie strictly inside a convex box (4, 2)."""
    signs = []
    for k in range(4):
        e = box[(k + 1) % 4] - box[k]
        r = points - box[k]
        signs.append(e[0] * r[..., 1] - e[1] * r[..., 0])
    signs = np.stack(signs)
    return (signs > 0).all(axis=0) | (signs < 0).all(axis=0)


_PAIR = (quiet_race(n_beams=271), quiet_race(1, n_beams=271))


@given(
    x=st.floats(11.0, 20.0), y=st.floats(2.0, 8.0), th=st.floats(-math.pi, math.pi),
)  # fmt: skip
def test_every_beam_that_hits_another_car_ends_on_its_box(x, y, th):
    env, alone = _PAIR
    poses = np.array([[10.0, 5.0, 0.3], [x, y, th]])
    obs, _ = env.reset(seed=0, options={"poses": poses})
    walls, _ = alone.reset(seed=0, options={"poses": poses[:1]})
    scan = obs["car_0"]["scan"].astype(np.float64)
    wall_scan = walls["car_0"]["scan"].astype(np.float64)
    box = env.world.boxes()[1]
    lidar = np.array([10.0 + MOUNT * math.cos(0.3), 5.0 + MOUNT * math.sin(0.3)])
    angles = 0.3 + env.cars[0].lidar.angles
    assert (scan <= wall_scan + 1e-6).all()
    for i in np.flatnonzero(scan < wall_scan - 1e-4):
        d = np.array([math.cos(angles[i]), math.sin(angles[i])])
        hit = lidar + scan[i] * d
        assert _on_box_boundary(hit, box) < 1e-4
        assert not _inside(lidar + (scan[i] - 0.01) * d, box)
    # Every beam whose ray passes through the box's inside is cut (sampled every 1 cm).
    ts = np.arange(0.05, 30.0, 0.01)
    d = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    samples = lidar + ts[None, :, None] * d[:, None, :]  # (beams, T, 2)
    crossed = (_inside(samples, box) & (ts[None, :] < wall_scan[:, None] - 0.05)).any(axis=1)
    assert (scan[crossed] < wall_scan[crossed]).all()


def test_two_cars_driven_into_each_other_separate_without_overlapping():
    env = quiet_race(n_beams=61, terminate_on_collision=False)
    poses = np.array([[10.0, 5.0, 0.0], [14.0, 5.1, math.pi]])
    env.reset(seed=0, options={"poses": poses})
    hits: dict[str, set[str]] = {"car_0": set(), "car_1": set()}
    depth = []
    for _ in range(120):  # 3 s at 3 m/s head on
        _, _, _, _, info = env.step({"car_0": [0.0, 3.0], "car_1": [0.0, 3.0]})
        for a in hits:
            hits[a].update(info[a]["contacts"])
        boxes = env.world.boxes()
        depth.append(penetration(boxes[0], boxes[1]))
        assert info["car_0"]["pose"][0] < info["car_1"]["pose"][0]  # never through each other
    assert hits == {"car_0": {"car_1"}, "car_1": {"car_0"}}
    # pymunk resolves a contact after the substep that made it, as against a wall: the boxes
    # overlap by at most one substep of closing (2 x 3 m/s x 5 ms), and are apart the step after.
    depth = np.array(depth)
    assert depth.max() <= 2 * 3.0 * env.config.substep + 1e-9
    touching = np.flatnonzero(depth > 0)
    assert len(touching) >= 1
    assert (depth[touching + 1] < 0).all()
    # Backing off, they come apart.
    for _ in range(40):
        _, _, _, _, info = env.step({"car_0": [0.0, -1.0], "car_1": [0.0, -1.0]})
    boxes = env.world.boxes()
    assert penetration(boxes[0], boxes[1]) < -0.5
    assert info["car_0"]["collision"] == ""


def test_contact_with_a_car_ends_the_episode_and_names_it():
    env = quiet_race(n_beams=61)
    poses = np.array([[10.0, 5.0, 0.0], [11.0, 5.0, 0.0]])  # car_0 rear-ends a parked car_1
    env.reset(seed=0, options={"poses": poses})
    for _ in range(40):
        _, rew, term, _, info = env.step(
            {a: [0.0, 2.0 if a == "car_0" else 0.0] for a in env.agents}
        )
        if term["car_0"]:
            break
    assert term["car_0"] and info["car_0"]["collision"] == "car_1"
    assert info["car_1"]["collision"] == "car_0"  # the hit car touched it too
    assert rew["car_0"] < 0
    assert env.agents == []


def test_overlapping_start_poses_are_refused_naming_the_cars():
    env = quiet_race(n_beams=61)
    with pytest.raises(ValueError, match="car_1 onto car_0"):
        env.reset(options={"poses": [[10.0, 5.0, 0.0], [10.3, 5.1, 0.5]]})
    with pytest.raises(ValueError, match=r"poses must be a finite \(2, 3\)"):
        env.reset(options={"poses": [[10.0, 5.0, 0.0]]})


def test_a_one_car_race_is_the_single_env():
    race = RaceEnv(HALL, n_cars=1, n_beams=181)
    single = RacecarEnv(HALL, n_beams=181)
    pose = np.array([5.0, 5.0, 0.2])
    ro, _ = race.reset(seed=7, options={"poses": pose[None]})
    so, _ = single.reset(seed=7, options={"pose": pose})
    rng = np.random.default_rng(0)
    for _ in range(60):
        a = rng.uniform([-0.4, -1.0], [0.4, 5.0])
        ro, rr, _, _, ri = race.step({"car_0": a})
        so, sr, _, _, si = single.step(a)
        np.testing.assert_array_equal(ro["car_0"]["scan"], so["scan"])
        np.testing.assert_array_equal(ro["car_0"]["odom"], so["odom"])
        np.testing.assert_array_equal(ri["car_0"]["pose"], si["pose"])
        assert rr["car_0"] == sr


def test_a_one_car_race_keeps_the_single_env_clock_into_a_wall():
    # A scan every 2-3 steps (15 Hz lidar, dt 0.025 s), then straight into the hall's end wall
    # (pymunk steps): the same scans, odometry, poses, times and new_scan flags.
    settings = {"n_beams": 91, "lidar_rate": 15.0, "terminate_on_collision": False}
    race = RaceEnv(HALL, n_cars=1, **settings)
    single = RacecarEnv(HALL, **settings)
    pose = np.array([26.0, 5.0, 0.0])
    race.reset(seed=4, options={"poses": pose[None]})
    single.reset(seed=4, options={"pose": pose})
    fresh = hits = 0
    for k in range(100):
        a = np.array([0.05 * math.sin(0.1 * k), 3.0])
        ro, _, _, _, ri = race.step({"car_0": a})
        so, _, _, _, si = single.step(a)
        np.testing.assert_array_equal(ro["car_0"]["scan"], so["scan"])
        np.testing.assert_array_equal(ro["car_0"]["odom"], so["odom"])
        np.testing.assert_array_equal(ri["car_0"]["pose"], si["pose"])
        assert ri["car_0"]["time"] == si["time"]
        assert ri["car_0"]["new_scan"] == si["new_scan"]
        fresh += si["new_scan"]
        hits += bool(si["collision"])
    assert 30 < fresh < 50  # 2.5 s at 15 Hz
    assert hits > 10  # it drove into the wall


def _race(seed: int) -> list[np.ndarray]:
    env = RaceEnv(HALL, n_cars=4, n_beams=121, terminate_on_collision=False)
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(3)
    out = []
    for _ in range(80):
        obs, _, _, _, info = env.step({a: rng.uniform([-0.4, 0.0], [0.4, 4.0]) for a in env.agents})
        out += [obs[a]["scan"] for a in env.agents] + [info[a]["pose"] for a in env.agents]
    return out


def test_the_same_seed_gives_the_same_race():
    a, b, c = _race(5), _race(5), _race(6)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    assert any(not np.array_equal(x, y) for x, y in zip(a, c, strict=True))


def test_render_draws_every_car_in_its_own_colour():
    from racecar_sim.race.drawing import CAR_COLOURS

    env = RaceEnv(HALL, n_cars=3, n_beams=61, render_mode="rgb_array")
    env.reset(seed=0, options={"poses": [[5.0, 5.0, 0.0], [10.0, 5.0, 0.0], [15.0, 5.0, 0.0]]})
    img = env.render()
    for i in range(3):
        assert (img == np.array(CAR_COLOURS[i], dtype=np.uint8)).all(axis=-1).sum() > 10


def test_bad_actions_name_the_agent():
    env = quiet_race(n_beams=61)
    env.reset(seed=0, options={"poses": [[5.0, 5.0, 0.0], [10.0, 5.0, 0.0]]})
    with pytest.raises(ValueError, match="car_1 must be finite"):
        env.step({"car_0": [0.0, 1.0], "car_1": [float("nan"), 1.0]})
    with pytest.raises(ValueError, match="no action for live agent 'car_1'"):
        env.step({"car_0": [0.0, 1.0]})
    with pytest.raises(ValueError, match="not alive"):
        env.step({"car_0": [0.0, 1.0], "car_1": [0.0, 1.0], "car_9": [0.0, 0.0]})


def test_a_grid_longer_than_the_track_is_refused_naming_n_cars_and_the_track_length():
    # Each grid car takes its length plus the 0.3 m gap of centerline: the most that fit once
    # round the bundled loop start; one more is refused at reset, before any car is placed,
    # instead of a message about an option never given.
    probe = RaceEnv("basement_loop", n_cars=1, n_beams=11)
    most = int(probe.track.length // (CAR.length + 0.3))
    full = RaceEnv("basement_loop", n_cars=most, n_beams=11)
    full.reset(seed=0)
    boxes = full.world.boxes()
    assert not any(penetration(boxes[i], boxes[i - 1]) > 0 for i in range(1, most))
    over = RaceEnv("basement_loop", n_cars=most + 1, n_beams=11)
    with pytest.raises(ValueError, match=rf"n_cars = {most + 1}.*{probe.track.length:.1f} m long") as err:
        over.reset(seed=0)
    assert "options['poses']:" not in str(err.value)


def test_step_before_reset_or_after_every_agent_is_done_needs_a_reset():
    env = quiet_race(n_beams=61, max_episode_steps=1)
    actions = {"car_0": [0.0, 0.0], "car_1": [0.0, 0.0]}
    with pytest.raises(ResetNeeded, match=r"RaceEnv.step: call reset"):
        env.step(actions)
    env.reset(seed=0, options={"poses": [[5.0, 5.0, 0.0], [10.0, 5.0, 0.0]]})
    env.step(actions)  # truncated: every agent is done
    assert env.agents == []
    for late in ({}, actions):
        with pytest.raises(ResetNeeded, match="every agent is done"):
            env.step(late)


@pytest.mark.parametrize("actions", [None, [[0.0, 1.0], [0.0, 1.0]], np.zeros((2, 2)), "car_0"])
def test_actions_that_are_not_a_dict_are_refused_in_words(actions):
    env = quiet_race(n_beams=61)
    env.reset(seed=0, options={"poses": [[5.0, 5.0, 0.0], [10.0, 5.0, 0.0]]})
    with pytest.raises(ValueError, match=r"^RaceEnv.step: actions must be a dict \{agent"):
        env.step(actions)


def test_agent_names_of_any_kind_that_are_not_alive_are_named():
    env = quiet_race(n_beams=61)
    env.reset(seed=0, options={"poses": [[5.0, 5.0, 0.0], [10.0, 5.0, 0.0]]})
    with pytest.raises(ValueError, match=r"not alive: \['car_9', 0\]"):
        env.step({"car_0": [0.0, 1.0], "car_1": [0.0, 1.0], 0: [0.0, 0.0], "car_9": [0.0, 0.0]})


def test_a_masked_action_is_refused_naming_the_agent_and_nothing_moves():
    env = quiet_race(n_beams=61)
    env.reset(seed=0, options={"poses": [[5.0, 5.0, 0.0], [10.0, 5.0, 0.0]]})
    before = env.poses
    masked = np.ma.array([0.0, 5.0], mask=[False, True])
    with pytest.raises(ValueError, match=r"action of car_1 .*masked"):
        env.step({"car_0": np.array([0.0, 1.0]), "car_1": masked})
    np.testing.assert_array_equal(env.poses, before)


def test_reset_options_of_the_wrong_kind_name_the_option_and_need_a_new_reset():
    env = quiet_race(n_beams=61)
    with pytest.raises(ValueError, match=r"^RaceEnv.reset: options must be a dict.*list \[1, 2\]"):
        env.reset(options=[1, 2])
    env.reset(seed=0, options={"poses": [[5.0, 5.0, 0.0], [10.0, 5.0, 0.0]]})
    for poses, kind in (({"car_0": [5.0, 5.0, 0.0]}, "dict"), ("grid", "str")):
        with pytest.raises(ValueError, match=rf"^RaceEnv.reset options\['poses'\]: .*{kind}"):
            env.reset(options={"poses": poses})
    with pytest.raises(ResetNeeded):  # the refused reset left no race to step
        env.step({"car_0": [0.0, 1.0], "car_1": [0.0, 1.0]})
    env.reset(seed=0, options={"poses": [[5.0, 5.0, 0.0], [10.0, 5.0, 0.0]]})
    with pytest.raises(ValueError, match="seed must be a non-negative int"):
        env.reset(seed=-1)  # refused before anything changed, but a reset was asked for
    with pytest.raises(ResetNeeded):
        env.step({"car_0": [0.0, 1.0], "car_1": [0.0, 1.0]})


def test_single_track_cars_race_and_pass_the_api_test():
    env = RaceEnv(HALL, n_cars=3, n_beams=61, max_episode_steps=150, car_model="single_track")
    assert {car.physics.car_model for car in env.world.cars} == {"single_track"}
    parallel_api_test(env, num_cycles=200)


def test_single_track_cars_driven_into_each_other_do_not_overlap():
    env = quiet_race(n_beams=61, terminate_on_collision=False, car_model="single_track")
    env.reset(seed=0, options={"poses": np.array([[10.0, 5.0, 0.0], [14.0, 5.1, math.pi]])})
    touched = False
    for _ in range(120):  # 3 s at 3 m/s head on
        _, _, _, _, info = env.step({"car_0": [0.0, 3.0], "car_1": [0.0, 3.0]})
        touched = touched or "car_1" in info["car_0"]["contacts"]
        boxes = env.world.boxes()
        assert penetration(boxes[0], boxes[1]) <= 2 * 3.0 * env.config.substep + 1e-9
        assert info["car_0"]["pose"][0] < info["car_1"]["pose"][0]
    assert touched


def test_scans_cast_on_two_threads_are_the_same_race():
    poses = np.array([[3.0 + 1.5 * (i % 8), 3.5 + 3.0 * (i // 8), 0.1 * i] for i in range(16)])
    races = [RaceEnv(HALL, n_cars=16, n_beams=1080, workers=w) for w in (1, 2)]
    assert races[1].world._threaded  # 16 x 1080 rays: above the threading threshold
    outs = [r.reset(seed=3, options={"poses": poses})[0] for r in races]
    for _ in range(10):
        outs = [r.step({a: (0.1, 1.0) for a in r.agents})[0] for r in races]
    for a in races[0].agents:
        np.testing.assert_array_equal(outs[0][a]["scan"], outs[1][a]["scan"])


@pytest.mark.parametrize("imu", [True, None], ids=["imu", "no_imu"])
def test_a_one_car_race_with_an_imu_and_odometry_lead_is_the_single_env(imu):
    # without an IMU the race measures the odometry on the core's N-car path, the commands still
    # on their way car by car; with one, through each car's observation
    settings = {"n_beams": 61, "imu": imu, "odom_lead": 0.05}
    race = RaceEnv(HALL, n_cars=1, **settings)
    single = RacecarEnv(HALL, **settings)
    pose = np.array([5.0, 5.0, 0.0])
    ro, _ = race.reset(seed=2, options={"poses": pose[None]})
    so, _ = single.reset(seed=2, options={"pose": pose})
    for k in range(30):
        a = np.array([0.3 * math.sin(0.2 * k), 2.0])
        ro, _, _, _, ri = race.step({"car_0": a})
        so, _, _, _, si = single.step(a)
        assert ro["car_0"].keys() == so.keys()
        for key in so:
            np.testing.assert_array_equal(ro["car_0"][key], so[key])
        np.testing.assert_array_equal(ri["car_0"]["pose"], si["pose"])
