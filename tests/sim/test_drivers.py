"""Tests of racecar_sim.drivers: the wall follower's geometry and laws, pure pursuit, and drives in
the env (a full lap of the default map, a minute on the real Stata basement, circles in a room)."""

from __future__ import annotations

import math

import cv2
import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import racecar_sim  # noqa: F401  (registers RacecarSim-v0)
from racecar_sim.drivers import (
    PurePursuit,
    WallFollower,
    despeckle,
    resample_polyline,
    waypoints_from_drive,
)
from racecar_sim.maps import OccupancyMap
from racecar_sim.sensors.lidar import Lidar
from racecar_sim.settings.config import LidarParams, from_mapping

RES = 0.05
NOISE_FREE = {"sigma": 0.0, "p_short": 0.0, "p_max": 0.0, "p_rand": 0.0}


def box_map(width: float, height: float, name: str = "box") -> OccupancyMap:
    """An empty width x height m room whose one-cell walls' inner faces are at x, y = RES and
    width - RES, height - RES (world origin at the lower-left corner of the image)."""
    occ = np.zeros((round(height / RES), round(width / RES)), dtype=bool)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = True
    return OccupancyMap(occupied=occ, resolution=RES, origin=(0.0, 0.0, 0.0), name=name)


@pytest.fixture(scope="module")
def corridor() -> OccupancyMap:
    """A 40 m x 4 m corridor: free for y in [0.05, 3.95] m."""
    return box_map(40.0, 4.0, "corridor")


def scan_at(grid: OccupancyMap, pose: list[float], **noise: float) -> np.ndarray:
    """A scan from the lidar at ``pose`` (mount offset 0), noise-free unless given."""
    params = LidarParams(mount_offset=0.0, **{**NOISE_FREE, **noise})
    return Lidar(grid, params).measure(np.asarray(pose, float), np.random.default_rng(0))


# ---------------------------------------------------------------------- wall fitting
@settings(max_examples=40, deadline=None)
@given(y=st.floats(0.4, 1.6), theta=st.floats(-0.4, 0.4))
def test_fit_wall_recovers_distance_and_angle_of_the_right_wall(
    corridor: OccupancyMap, y: float, theta: float
) -> None:
    scan = scan_at(corridor, [20.0, y, theta]).astype(np.float64)
    wall = WallFollower(side="right").fit_wall(scan)
    assert wall is not None
    d, phi = wall
    # The right wall's face is the line y = RES; seen from the car it runs at -theta.
    assert d == pytest.approx(y - RES, abs=0.02)
    assert phi == pytest.approx(-theta, abs=0.02)


@settings(max_examples=30, deadline=None)
@given(y=st.floats(2.4, 3.6), theta=st.floats(-0.4, 0.4))
def test_fit_wall_recovers_the_left_wall(corridor: OccupancyMap, y: float, theta: float) -> None:
    scan = scan_at(corridor, [20.0, y, theta]).astype(np.float64)
    d, phi = WallFollower(side="left").fit_wall(scan)
    assert d == pytest.approx(4.0 - RES - y, abs=0.02)
    assert phi == pytest.approx(-theta, abs=0.02)


def corridor_with_recesses(width: float, depth: float, at: list[float]) -> OccupancyMap:
    """A 30 m corridor, free for y in [1.0, 4.0] m, with recesses ``width`` x ``depth`` m in its
    right-hand (y = 1 m) wall starting at the x positions ``at``."""
    occ = np.zeros((round(5.0 / RES), round(30.0 / RES)), dtype=bool)
    occ[: round(1.0 / RES), :] = True  # y above 4 m (row 0 is the top of the image)
    occ[-round(1.0 / RES) :, :] = True  # y below 1 m
    for x0 in at:
        rows = slice(occ.shape[0] - round(1.0 / RES), occ.shape[0] - round((1.0 - depth) / RES))
        occ[rows, round(x0 / RES) : round((x0 + width) / RES)] = False
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = True
    return OccupancyMap(occupied=occ, resolution=RES, name="recesses")


@pytest.mark.parametrize("x", np.arange(13.0, 17.01, 0.25))
def test_fit_wall_bridges_a_doorway(x: float) -> None:
    """An 0.8 m doorway in the right wall, anywhere beside the car, leaves the fit on the wall."""
    grid = corridor_with_recesses(0.8, 0.95, [15.0])
    scan = scan_at(grid, [x, 1.8, 0.0]).astype(np.float64)
    d, phi = WallFollower(side="right").fit_wall(scan)
    assert d == pytest.approx(0.8, abs=0.1)
    assert abs(phi) < 0.25


def test_wall_follower_drives_past_alcoves_without_entering_them() -> None:
    grid = corridor_with_recesses(1.5, 0.95, [8.0, 14.0, 20.0])
    run = drive(make_env(grid), WallFollower(side="right"), [2.0, 2.0, 0.0], 14.0)
    path = run["path"]
    assert run["collisions"] == 0
    assert path[-1, 0] > 25.0  # got past all three
    assert path[:, 1].min() > 1.0  # the rear axle never went into an alcove


def test_fit_wall_is_robust_to_beam_noise(corridor: OccupancyMap) -> None:
    noisy = scan_at(corridor, [20.0, 0.9, 0.1], sigma=0.02, p_short=0.02, p_rand=0.02, p_max=0.02)
    d, phi = WallFollower().fit_wall(despeckle(noisy.astype(np.float64)))
    assert d == pytest.approx(0.9 - RES, abs=0.05)
    assert phi == pytest.approx(-0.1, abs=0.05)


def test_no_wall_within_fit_range_gives_none(corridor: OccupancyMap) -> None:
    scan = scan_at(corridor, [20.0, 2.0, 0.0]).astype(np.float64)  # walls 1.95 m away
    assert WallFollower(fit_range=1.5).fit_wall(scan) is None


# ---------------------------------------------------------------------- despeckle
@settings(max_examples=50, deadline=None)
@given(
    levels=st.lists(st.floats(0.1, 10.0), min_size=1, max_size=6),
    width=st.integers(3, 30),
    which=st.integers(0, 5),
    outlier=st.floats(0.0, 12.0),
    run=st.integers(1, 2),
)
def test_despeckle_removes_short_runs_and_keeps_steps(
    levels: list[float], width: int, which: int, outlier: float, run: int
) -> None:
    """Plateaus of three beams or more survive; a run of one or two outliers with at least three
    beams of its plateau on either side is replaced by the plateau's range."""
    clean = np.repeat(np.asarray(levels), width)
    np.testing.assert_array_equal(despeckle(clean), clean)
    if width >= run + 6:
        k = (which % len(levels)) * width + (width - run) // 2  # middle of one plateau
        noisy = clean.copy()
        noisy[k : k + run] = outlier
        np.testing.assert_array_equal(despeckle(noisy), clean)


# ---------------------------------------------------------------------- control laws
def test_steers_back_towards_the_wanted_distance(corridor: OccupancyMap) -> None:
    wf = WallFollower(side="right", distance=0.8)
    far = wf(scan_at(corridor, [20.0, 1.4, 0.0]))
    near = wf(scan_at(corridor, [20.0, 0.5, 0.0]))
    assert far.dtype == np.float32 and far.shape == (2,)
    assert far[0] < 0 < near[0]  # too far: right (towards the wall); too near: left
    assert 0 < far[1] <= wf.speed and 0 < near[1] <= wf.speed


def test_heading_into_the_wall_steers_away_first(corridor: OccupancyMap) -> None:
    # At the wanted distance but heading 0.3 rad towards the right wall: the D term turns left.
    steer, _ = WallFollower(side="right", distance=0.8)(scan_at(corridor, [20.0, 0.85, -0.3]))
    assert steer > 0


@settings(max_examples=25, deadline=None)
@given(y=st.floats(0.4, 3.6), theta=st.floats(-0.5, 0.5))
def test_left_follower_mirrors_the_right_one(
    corridor: OccupancyMap, y: float, theta: float
) -> None:
    """Mirroring the world left-right mirrors the scan (beam order reversed) and the action."""
    scan = scan_at(corridor, [20.0, y, theta])
    right = WallFollower(side="right")(scan)
    left = WallFollower(side="left")(scan[::-1].copy())
    assert left[0] == pytest.approx(-right[0], abs=1e-4)
    assert left[1] == pytest.approx(right[1], abs=1e-4)


def test_slows_down_and_turns_before_a_wall_ahead() -> None:
    room = box_map(6.0, 6.0)
    wf = WallFollower(side="right", speed=2.0)
    open_road = wf(scan_at(room, [1.0, 0.85, 0.0]))  # right wall at 0.8 m, 4.9 m clear ahead
    wf.reset()
    blocked = wf(scan_at(room, [4.9, 0.85, 0.0]))  # the end wall 1 m ahead
    assert blocked[1] < open_road[1]
    assert blocked[0] > 0.2  # turns left, away from the right wall, round the corner


def test_backs_out_of_a_dead_end_and_reset_forgets_it() -> None:
    pocket = box_map(1.2, 3.0)
    wf = WallFollower(side="right")
    facing_end = scan_at(pocket, [0.6, 2.5, math.pi / 2])  # nose 0.4 m from the end wall
    steer, speed = wf(facing_end)
    assert speed < 0  # reverses
    assert steer == pytest.approx(-wf.max_steer)  # full lock to the right: nose swings left
    wf.reset()
    assert wf._state == {}


def test_unchanged_scan_gives_the_same_action(corridor: OccupancyMap) -> None:
    wf = WallFollower()
    scan = scan_at(corridor, [20.0, 1.0, 0.1])
    first = wf({"scan": scan})
    again = wf({"scan": scan.copy()})
    np.testing.assert_array_equal(first, again)


def test_beam_count_and_fov_are_taken_from_the_scan_length(corridor: OccupancyMap) -> None:
    params = LidarParams(n_beams=181, fov=math.pi, mount_offset=0.0, **NOISE_FREE)
    scan = Lidar(corridor, params).measure(np.array([20.0, 1.0, 0.0]), np.random.default_rng(0))
    d, phi = WallFollower(lidar=params).fit_wall(scan.astype(np.float64))
    assert d == pytest.approx(1.0 - RES, abs=0.02)
    assert abs(phi) < 0.02


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"side": "middle"}, "side"),
        ({"distance": -1.0}, "distance"),
        ({"speed": math.nan}, "speed"),
        ({"window": (1.0, 0.5)}, "window"),
        ({"n_arcs": 1}, "n_arcs"),
    ],
)
def test_bad_parameters_are_named(kwargs: dict, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        WallFollower(**kwargs)


def test_parameters_load_from_a_mapping_and_scans_must_have_beams() -> None:
    wf = from_mapping(WallFollower, {"side": "left", "distance": 1.0})
    assert wf.side == "left" and wf.distance == 1.0
    with pytest.raises(ValueError, match="scan"):
        wf({"scan": np.ones(3, dtype=np.float32)})


# ---------------------------------------------------------------------- pure pursuit
def circle(centre: tuple[float, float], radius: float, n: int = 120) -> np.ndarray:
    t = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
    return np.column_stack([centre[0] + radius * np.cos(t), centre[1] + radius * np.sin(t)])


def test_pure_pursuit_needs_a_pose() -> None:
    pp = PurePursuit(circle((0, 0), 2.0))
    with pytest.raises(ValueError, match="pose"):
        pp({"scan": np.zeros(10)})
    with pytest.raises(ValueError, match="pose"):
        pp({}, pose=[0.0, np.nan, 0.0])


def test_pure_pursuit_reads_the_pose_estimate() -> None:
    pose = np.array([2.0, 0.1, 1.4])
    a = PurePursuit(circle((0, 0), 2.0))({"pose_estimate": pose})
    b = PurePursuit(circle((0, 0), 2.0))({}, pose=pose)
    np.testing.assert_array_equal(a, b)
    assert a.dtype == np.float32


def test_pure_pursuit_steers_towards_a_path_to_the_left() -> None:
    straight = np.column_stack([np.linspace(0, 20, 41), np.full(41, 1.0)])
    steer, speed = PurePursuit(straight, loop=False, speed=1.5)({}, pose=[0.0, 0.0, 0.0])
    assert steer > 0 and speed == pytest.approx(1.5)
    steer, speed = PurePursuit(straight, loop=False)({}, pose=[20.0, 1.0, 0.0])
    assert speed == 0.0  # at the end of an open path


def test_pure_pursuit_does_not_jump_to_a_nearby_part_of_the_path() -> None:
    """A hairpin: the return leg passes 0.6 m from the outbound leg."""
    out_leg = np.column_stack([np.linspace(0, 10, 41), np.zeros(41)])
    back_leg = np.column_stack([np.linspace(10, 0, 41), np.full(41, 0.6)])
    pp = PurePursuit(np.vstack([out_leg, back_leg]), lookahead=1.0, loop=False)
    pp({}, pose=[0.0, 0.05, 0.0])  # starts on the outbound leg
    for x in np.linspace(0.25, 6.0, 24):
        pp({}, pose=[x, 0.35, 0.0])  # now nearer the return leg than the outbound one
        assert pp.progress is not None and x - 0.5 < pp.progress < x + 0.5
    pp.reset()
    pp({}, pose=[3.0, 0.35, 0.0])  # without the history the nearest leg wins
    assert pp.progress == pytest.approx(20.0 - 3.0 + 0.6, abs=0.01)


def test_resample_polyline_spacing_and_loop_closure() -> None:
    square = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]])
    pts = resample_polyline(square, 0.5, loop=True)
    gaps = np.hypot(*np.diff(np.vstack([pts, pts[:1]]), axis=0).T)
    assert gaps.sum() == pytest.approx(16.0, rel=0.02)
    assert gaps.max() <= 0.5 + 1e-9
    with pytest.raises(ValueError, match="spacing"):
        resample_polyline(square, 0.0)


# ---------------------------------------------------------------------- drives in the env
def make_env(grid: OccupancyMap | str, **kw) -> gym.Env:
    return gym.make("RacecarSim-v0", map=grid, terminate_on_collision=False, **kw)


def drive(env: gym.Env, driver, pose, seconds: float, stop=None) -> dict:
    """Run ``driver`` for ``seconds``; the poses, collisions and distance covered."""
    options = {"pose": list(pose)} if pose is not None else None
    obs, info = env.reset(seed=0, options=options)
    poses = [info["pose"]]
    collisions = 0
    for _ in range(round(seconds / env.unwrapped.dt)):
        obs, _, _, _, info = env.step(driver(obs, info["pose"]))
        poses.append(info["pose"])
        collisions += bool(info["collision"])
        if stop is not None and stop(np.asarray(poses)):
            break
    path = np.asarray(poses)
    covered = float(np.hypot(*np.diff(path[:, :2], axis=0).T).sum())
    return {"path": path, "collisions": collisions, "covered": covered}


def winding(path: np.ndarray, centre: np.ndarray) -> float:
    """Turns of the path round ``centre`` (positive anticlockwise)."""
    ang = np.unwrap(np.arctan2(path[:, 1] - centre[1], path[:, 0] - centre[0]))
    return float((ang[-1] - ang[0]) / (2 * math.pi))


def inner_block(grid: OccupancyMap) -> tuple[np.ndarray, float]:
    """Centre (world) and convex-hull perimeter (metres) of the largest occupied region not
    touching the image border: the block a loop map's hallway runs round."""
    n, labels, stats, _ = cv2.connectedComponentsWithStats(grid.occupied.astype(np.uint8), 4)
    border = set(labels[0]) | set(labels[-1]) | set(labels[:, 0]) | set(labels[:, -1])
    inner = [k for k in range(1, n) if k not in border]
    k = max(inner, key=lambda i: stats[i, cv2.CC_STAT_AREA])
    rc = np.argwhere(labels == k)
    xy = grid.grid_to_world(rc).astype(np.float32)
    hull = cv2.convexHull(xy)
    return xy.mean(axis=0), float(cv2.arcLength(hull, True))


def bottom_hallway_start(grid: OccupancyMap) -> np.ndarray:
    """The most open cell of the middle column in the lower third of the map."""
    col = grid.width // 2
    rows = np.arange(grid.height * 2 // 3, grid.height)
    row = rows[np.argmax(grid.distance[rows, col])]
    return grid.grid_to_world(np.array([row, col]))


@pytest.mark.slow
@pytest.mark.parametrize(
    ("side", "heading"), [("right", 0.0), ("left", math.pi)], ids=["anticlockwise", "clockwise"]
)
def test_wall_follower_laps_the_default_map_without_collision(
    default_map: OccupancyMap, side: str, heading: float
) -> None:
    """Following the outer wall of the hallway loop (with its alcoves) all the way round."""
    centre, hull_length = inner_block(default_map)
    start = bottom_hallway_start(default_map)

    def lapped(path: np.ndarray) -> bool:
        return abs(winding(path, centre)) > 0.9 and np.hypot(*(path[-1, :2] - path[0, :2])) < 1.0

    env = make_env(default_map)
    run = drive(env, WallFollower(side=side), [*start, heading], 120.0, stop=lapped)
    assert run["collisions"] == 0
    assert lapped(run["path"]), f"no lap: winding {winding(run['path'], centre):.2f}"
    # Any closed path round the block is at least as long as the block's convex hull.
    assert hull_length < run["covered"] < 1.6 * hull_length
    clearance = default_map.distance_at(run["path"][:, :2])
    assert clearance.min() > 0.3  # the rear axle never came near a wall


@pytest.mark.slow
def test_wall_follower_drives_a_minute_on_the_stata_basement(stata_map: OccupancyMap) -> None:
    env = make_env(stata_map)
    wf = WallFollower(side="right")
    run = drive(env, wf, None, 60.0)  # random start pose from the env's seeded rng
    assert run["collisions"] == 0
    assert run["covered"] > 0.5 * wf.speed * 60.0  # it kept going


def test_pure_pursuit_follows_a_circle_in_an_empty_room() -> None:
    room = box_map(12.0, 12.0)
    centre, radius = np.array([6.0, 6.0]), 3.0
    pp = PurePursuit(circle(centre, radius), lookahead=1.0, speed=2.0)
    run = drive(make_env(room), pp, [centre[0] + radius, centre[1], math.pi / 2], 12.0)
    assert run["collisions"] == 0
    assert winding(run["path"], centre) > 1.0  # more than a lap, anticlockwise
    err = np.abs(np.hypot(*(run["path"][:, :2] - centre).T) - radius)
    settled = err[len(err) // 5 :]
    # On a circle pure pursuit is exact (the arc through the car and the target is the circle
    # itself); what is left comes from the chords of the 120-gon and the steering lag.
    assert settled.max() < 0.1


def test_pure_pursuit_follows_an_ellipse_with_tight_ends() -> None:
    room = box_map(14.0, 10.0)
    t = np.linspace(0.0, 2 * math.pi, 200, endpoint=False)
    path = np.column_stack([7.0 + 5.0 * np.cos(t), 5.0 + 2.5 * np.sin(t)])
    pp = PurePursuit(path, lookahead=0.8, speed=1.5)
    run = drive(make_env(room), pp, [12.0, 5.0, math.pi / 2], 25.0)
    assert run["collisions"] == 0
    assert winding(run["path"], np.array([7.0, 5.0])) > 1.0
    # Distance from each pose to the waypoint polyline (dense, so nearest waypoint suffices).
    gap = np.hypot(*(run["path"][:, None, :2] - path[None]).transpose(2, 0, 1)).min(axis=1)
    assert gap.max() < 0.25


def test_waypoints_from_drive_records_a_closed_loop() -> None:
    room = box_map(12.0, 12.0)
    centre, radius = np.array([6.0, 6.0]), 3.0
    driver = PurePursuit(circle(centre, radius), lookahead=1.0, speed=2.0)
    loop = waypoints_from_drive(
        make_env(room), driver, seed=0, start_pose=[9.0, 6.0, math.pi / 2], spacing=0.25
    )
    length = np.hypot(*np.diff(np.vstack([loop, loop[:1]]), axis=0).T).sum()
    assert length == pytest.approx(2 * math.pi * radius, rel=0.05)
    assert np.abs(np.hypot(*(loop - centre).T) - radius).max() < 0.1
    # ... and pure pursuit on the recorded loop drives round it again.
    run = drive(make_env(room), PurePursuit(loop), [9.0, 6.0, math.pi / 2], 11.0)
    assert run["collisions"] == 0 and winding(run["path"], centre) > 1.0


class ScriptedEnv:
    """An env stand-in whose car follows a fixed list of poses, one per step."""

    def __init__(self, poses: np.ndarray) -> None:
        self.poses = poses
        self.i = 0

    def reset(self, seed=None, options=None):
        self.i = 0
        return {}, {"pose": self.poses[0]}

    def step(self, action):
        self.i += 1
        return {}, 0.0, False, False, {"pose": self.poses[self.i], "collision": False}


def test_waypoints_from_drive_does_not_close_an_out_and_back_path() -> None:
    # Out 8 m east, U-turn, back west past the start (heading pi), U-turn again, then east past the
    # start once more (heading 0): only the last pass closes the loop.
    out = np.column_stack([np.linspace(0, 8, 81), np.zeros(81), np.zeros(81)])
    back = np.column_stack([np.linspace(8, -3, 111), np.full(111, 0.3), np.full(111, math.pi)])
    again = np.column_stack([np.linspace(-3, 2, 51), np.zeros(51), np.zeros(51)])
    poses = np.vstack([out, back, again])
    loop = waypoints_from_drive(
        ScriptedEnv(poses), lambda obs, pose=None: np.zeros(2), min_length=5.0, spacing=0.1
    )
    # Closing on the way back would have stopped before x = -3; the closed loop reaches it.
    assert loop[:, 0].min() < -2.5


def test_waypoints_from_drive_orients_the_loop_along_the_start_heading() -> None:
    # The car starts heading west, then settles into an anticlockwise circle that runs east through
    # its start: the returned loop must run west there so pure pursuit needs no U-turn.
    west = np.column_stack([np.linspace(1, -1, 21), np.zeros(21), np.full(21, math.pi)])
    a = np.linspace(-math.pi / 2, 3.5 * math.pi, 800)
    circle_poses = np.column_stack([5 * np.cos(a), 5 + 5 * np.sin(a), a + math.pi / 2])
    loop = waypoints_from_drive(
        ScriptedEnv(np.vstack([west, circle_poses])),
        lambda obs, pose=None: np.zeros(2),
        spacing=0.1,
    )
    assert np.abs(np.hypot(loop[:, 0], loop[:, 1] - 5) - 5).max() < 0.05
    i = int(np.argmin(np.hypot(loop[:, 0], loop[:, 1])))
    assert (loop[(i + 1) % len(loop)] - loop[i - 1])[0] < 0


@pytest.mark.parametrize("reading", [0.02, 0.06, 0.12])
def test_the_cars_own_body_in_the_scan_is_not_an_obstacle(corridor: OccupancyMap, reading: float) -> None:
    """The real racecar's lidar sees its own rear wheel: the scan's right-rear end reads ~6 cm
    (the mit_racecar profile's body block). Readings inside the car's outline are the car
    itself, so the follower drives on as without them (it used to back out, boxed in)."""
    scan = scan_at(corridor, [20.0, 1.2, 0.0]).astype(np.float64)
    body = scan.copy()
    body[: round(0.0213 * scan.size)] = reading  # the first 23 of 1081 beams: right-rear
    wf = WallFollower(side="right")
    free = wf(scan)
    seen = WallFollower(side="right")(body)
    assert free[1] > 0 and np.array_equal(free, seen)
    # a reading just outside the outline on the same beams is an obstacle and is kept
    a = np.linspace(-wf.fov / 2, wf.fov / 2, scan.size)[0]
    out = (wf.car.width / 2 + 0.02) / abs(math.sin(a))
    kept = wf.without_body(np.where(np.arange(scan.size) < 23, out, scan))
    assert (kept[:23] == out).all()
