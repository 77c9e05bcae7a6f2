"""Scenes: the room's geometry (openings in the walls, furniture against them, people) as a
setting, through gym.make, YAML and --env; what it does to the lidar and the car."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import racecar_sim  # noqa: F401
from racecar_sim.settings.config import EnvConfig, merge_settings
from racecar_sim.world.scenes import SCENES
from racecar_sim.world.wall_features import opening_ranges


def _env(**kw):
    return gym.make("RacecarSim-v0", map="basement_loop", **kw).unwrapped


def test_profile_alone_is_the_sensor_and_the_scenes_add_the_room():
    # the profile is the sensor only; the room is asked for
    assert _env(noise_profile="mit_racecar").obstacles is None
    clean = _env(noise_profile="mit_racecar", scene="clean")
    clean.reset(seed=0)
    assert len(clean.obstacles.openings) > 0
    assert len(clean.obstacles.people) == 0
    busy = _env(noise_profile="mit_racecar", scene="cluttered")
    busy.reset(seed=0)
    assert len(busy.obstacles.openings) > 0
    assert len(busy.obstacles.boxes) > 3 * len(clean.obstacles.boxes) and len(busy.obstacles.people) > 0
    assert _env().obstacles is None
    assert _env(noise_profile="mit_racecar", scene="none").obstacles is None


def test_scene_from_yaml_and_from_the_command_line(tmp_path):
    path = tmp_path / "env.yaml"
    path.write_text("scene: cluttered\nnoise_profile: mit_racecar\n")
    assert merge_settings(str(path), {}).obstacles.furniture == SCENES["cluttered"]["furniture"]
    from mcl.cli.common import Parser, check_env

    assert dict(check_env(Parser("t", "", ""), ["scene=cluttered"]))["scene"] == "cluttered"
    with pytest.raises(SystemExit) as err:
        check_env(Parser("t", "", ""), ["scene=busy"])
    assert err.value.code == 2


def test_unknown_scene_is_a_one_line_error_naming_the_choices():
    with pytest.raises(ValueError, match="cluttered") as err:
        EnvConfig(scene="busy")
    assert "\n" not in str(err.value)


def test_explicit_obstacles_go_over_the_scene():
    cfg = merge_settings(None, {"scene": "cluttered", "obstacles": {"furniture": 0.0, "boxes": 3}})
    assert cfg.obstacles.furniture == 0.0 and cfg.obstacles.boxes == 3
    assert cfg.obstacles.openings == SCENES["cluttered"]["openings"]


def test_same_seed_same_scene():
    a, b = _env(scene="cluttered"), _env(scene="cluttered")
    a.reset(seed=3)
    b.reset(seed=3)
    assert np.array_equal(a.obstacles.boxes, b.obstacles.boxes)
    assert np.array_equal(a.obstacles.openings, b.obstacles.openings)
    a.reset(seed=4)
    assert not np.array_equal(a.obstacles.openings, b.obstacles.openings)


def test_furniture_stands_against_a_wall_in_free_space_off_the_car():
    env = _env(scene="cluttered")
    m = env.map
    for seed in range(5):
        env.reset(seed=seed)
        boxes = env.obstacles.boxes
        assert len(boxes) > 0
        centre = boxes.mean(axis=1)
        assert (m.distance_at(centre) > 0).all()  # in free space
        # the back edge (the side nearest the wall) lies within a few cm of the wall's face
        mid = 0.5 * (boxes + np.roll(boxes, -1, axis=1))  # edge midpoints (K, 4, 2)
        back = m.distance_at(mid.reshape(-1, 2)).reshape(-1, 4).min(axis=1)
        assert (back <= 0.02 + 1.5 * m.resolution).all(), back.max()
        assert env.physics.pose_is_free(env.pose)


def test_openings_lengthen_the_beams_on_them_only():
    env = _env(scene="clean", obstacles={"furniture": 0.0}, max_range=30.0)
    env.reset(seed=1)
    pose = env.pose
    mount = env.lidar.mount_pose(pose)
    angles = env.lidar.angles
    true = env.lidar.true_ranges(pose).astype(np.float64)
    # one opening, 0.4 m wide, across the end point of the middle beam
    i = angles.size // 2
    a = mount[2] + angles[i]
    end = mount[:2] + true[i] * np.array([math.cos(a), math.sin(a)])
    side = 0.2 * np.array([-math.sin(a), math.cos(a)])
    env.obstacles.openings = np.array([[*(end - side), *(end + side), 0.7]])
    seen = env.obstacles.clip_ranges(mount, angles, true, 30.0)
    assert seen[i] == pytest.approx(min(true[i] + 0.7, 30.0))
    longer = seen > true + 1e-9
    assert (seen >= true - 1e-9).all()  # openings never shorten a beam
    assert np.allclose(seen[longer], np.minimum(true[longer] + 0.7, 30.0))
    # only the beams whose mapped end point meets the opening (0.2 m either side + 8 cm face)
    aa = mount[2] + angles[longer]
    ends = mount[:2] + true[longer, None] * np.stack([np.cos(aa), np.sin(aa)], axis=1)
    assert (np.hypot(*(ends - end).T) <= math.hypot(0.2, 0.08) + 1e-6).all()
    idx = np.flatnonzero(longer)
    assert idx.max() - idx.min() + 1 == idx.size  # one run of beams around the middle one


@settings(max_examples=60)
@given(
    r=st.floats(0.5, 8.0),
    along=st.floats(-1.5, 1.5),
    depth=st.floats(0.2, 3.0),
)
def test_opening_kernel_against_geometry(r, along, depth):
    """A wall across the beam at x = r, an opening on it from y = -0.5 to 0.5: the beam towards
    (r, along) passes through it exactly when |along| <= 0.5 (+ the face tolerance). At the
    opening's very edge the beam's end point is rounded to either side (|along| = 0.5 itself fails
    in about 6 % of cases), so the edge is given a nanometre either way."""
    angle = math.atan2(along, r)
    true = math.hypot(r, along)
    openings = np.array([[r, -0.5, r, 0.5, depth]])
    ranges = np.array([true])
    opening_ranges(0.0, 0.0, 0.0, np.array([angle]), openings, 30.0, ranges)
    if abs(along) <= 0.5 - 1e-9:
        assert ranges[0] == pytest.approx(min(true + depth, 30.0))
    elif abs(along) > 0.5 + 0.08 + 1e-9:
        assert ranges[0] == true


def test_scene_in_the_vector_env_is_refused():
    from racecar_sim.vector_env import RacecarVectorEnv

    with pytest.raises(ValueError, match="scene"):
        RacecarVectorEnv(2, map="basement_loop", scene="clean")


def test_openings_take_their_cover_of_the_beams_beside_a_wall_and_far_from_it():
    """Openings cover a share of the wall's face points drawn uniformly, so the share of beams
    whose mapped end point is an opening is that cover from anywhere: beside a wall (which takes
    half the scan at steep angles) and in the middle of the floor alike."""
    cover = 0.3
    env = _env(obstacles={"openings": cover}, max_range=30.0)
    m = env.map
    dist = m.distance
    near_rc = np.argwhere((dist > 0.3) & (dist < 0.4))
    far_rc = np.argwhere(dist >= 0.9 * dist.max())
    rng = np.random.default_rng(0)
    shares = {"near": [], "far": []}
    for seed in range(40):
        env.reset(seed=seed)
        for name, cells in (("near", near_rc), ("far", far_rc)):
            xy = m.grid_to_world(cells[rng.integers(len(cells))])
            pose = np.array([*xy, rng.uniform(-math.pi, math.pi)])
            mount = env.lidar.mount_pose(pose)
            true = env.lidar.true_ranges(pose).astype(np.float64)
            seen = env.obstacles.clip_ranges(mount, env.lidar.angles, true, 30.0)
            mapped = true < 30.0
            shares[name].append(float((seen[mapped] > true[mapped] + 1e-9).mean()))
    for name, got in shares.items():
        assert abs(np.mean(got) - cover) < 0.05, (name, np.mean(got))
