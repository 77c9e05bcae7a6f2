"""Unmapped obstacles: reproducible placement, never on the car, block the lidar and the car."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import racecar_sim  # noqa: F401
from racecar_sim.world.obstacle_params import ObstacleParams
from racecar_sim.world.obstacles import obstacle_ranges

SETTINGS = {"boxes": 8, "people": 4}


def _env(**kw):
    return gym.make("RacecarSim-v0", map="basement_loop", obstacles=SETTINGS, **kw).unwrapped


def test_same_seed_same_obstacles_other_seed_others():
    a, b = _env(), _env()
    a.reset(seed=5)
    b.reset(seed=5)
    assert np.array_equal(a.obstacles.boxes, b.obstacles.boxes)
    assert np.array_equal(a.obstacles.people, b.obstacles.people)
    for _ in range(20):
        a.step([0.0, 1.0])
        b.step([0.0, 1.0])
    assert np.array_equal(a.obstacles.people, b.obstacles.people)
    a.reset(seed=6)
    assert not np.array_equal(a.obstacles.boxes, b.obstacles.boxes)
    assert a.obstacles.boxes.shape == (8, 4, 2) and a.obstacles.people.shape == (4, 2)


def test_obstacles_never_spawn_on_the_car():
    env = _env()
    keep = ObstacleParams().keep_out
    for seed in range(15):
        env.reset(seed=seed)
        car = env.pose[:2]
        obs = env.obstacles
        assert (np.hypot(*(obs.people - car).T) >= keep).all()
        centres = obs.boxes.mean(axis=1)
        assert (np.hypot(*(centres - car).T) >= keep).all()
        assert env.physics.pose_is_free(env.pose)  # nothing overlaps the car's footprint


def test_a_box_ahead_blocks_the_lidar_and_the_car():
    env = gym.make(
        "RacecarSim-v0", map="basement_loop", obstacles={"boxes": 1}, terminate_on_collision=False
    ).unwrapped
    env.reset(seed=0)
    pose = env.pose
    x, y, th = pose
    # move the box 1.5 m straight ahead of the lidar, across the heading
    c = np.array([x + 1.8 * math.cos(th), y + 1.8 * math.sin(th)])
    box = env.obstacles.boxes[0]
    env.obstacles.move_box(0, box - box.mean(axis=0) + c)
    mount = env.lidar.mount_pose(pose)
    clear = env.lidar.true_ranges(pose)
    cut = env.obstacles.clip_ranges(mount, env.lidar.angles, clear, env.lidar_params.max_range)
    ahead = np.abs(env.lidar.angles) < 0.05
    assert (cut <= clear + 1e-12).all()
    assert cut[ahead].max() < min(1.9, clear[ahead].min())
    hit = False
    for _ in range(80):
        *_, info = env.step([0.0, 1.0])
        hit |= info["collision"]
    assert hit  # the car ran into the box
    assert np.hypot(*(env.pose[:2] - c)) > 0.3


def test_people_block_the_car():
    """Drive straight at a person standing ahead: pymunk reports the contact."""
    env = gym.make(
        "RacecarSim-v0", map="basement_loop", obstacles={"people": 1, "stop_distance": 0.0,
        "person_speed": 0.0}, terminate_on_collision=False,
    ).unwrapped  # fmt: skip
    for seed in range(30):  # a start with 2.5 m of open floor straight ahead
        env.reset(seed=seed)
        x, y, th = env.pose
        line = np.array([[x + d * math.cos(th), y + d * math.sin(th)] for d in np.arange(0, 2.6, 0.1)])
        if (env.map.distance_at(line) > 0.45).all():
            break
    ahead = np.array([x + 1.5 * math.cos(th), y + 1.5 * math.sin(th)])
    env.obstacles.move_person(0, ahead)
    hit = False
    for _ in range(80):
        *_, info = env.step([0.0, 1.0])
        hit |= info["collision"]
    assert hit
    assert np.hypot(*(env.pose[:2] - ahead)) > 0.25  # it did not drive through


def test_obstacle_ranges_against_geometry():
    """A circle of radius r at distance d straight ahead is hit at d - r; a segment across at d."""
    angles = np.array([-0.5, 0.0, 0.5])
    out = np.full(3, 30.0)
    circles = np.array([[5.0, 0.0, 0.5]])
    obstacle_ranges(0.0, 0.0, 0.0, angles, circles, np.zeros((0, 4)), 30.0, out)
    assert out[1] == pytest.approx(4.5)
    assert out[0] == 30.0 and out[2] == 30.0
    out = np.full(3, 30.0)
    seg = np.array([[3.0, -10.0, 3.0, 10.0]])
    obstacle_ranges(0.0, 0.0, 0.0, angles, np.zeros((0, 3)), seg, 30.0, out)
    assert out == pytest.approx(3.0 / np.cos(angles))


def test_bad_obstacle_settings():
    with pytest.raises(ValueError, match="unknown obstacles setting"):
        gym.make("RacecarSim-v0", obstacles={"boxs": 3})
    with pytest.raises(ValueError, match="box_size"):
        ObstacleParams(box_size=(1.0, 0.5))
