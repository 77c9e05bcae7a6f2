"""Tests of racecar_sim.car.physics: walls on the grid's cell edges, bicycle kinematics, limits, contact."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from racecar_sim.car.physics import RacecarPhysics, wall_segments
from racecar_sim.maps import OccupancyMap
from racecar_sim.settings.config import CarParams

RES = 0.05


def box_room(size_cells: int = 120, wall: int = 3, origin=(-3.0, -3.0, 0.0)) -> OccupancyMap:
    """A square room: free inside, ``wall`` cells of wall on every side."""
    occ = np.zeros((size_cells, size_cells), dtype=bool)
    occ[:wall] = occ[-wall:] = True
    occ[:, :wall] = occ[:, -wall:] = True
    return OccupancyMap(occupied=occ, resolution=RES, origin=origin, name="room")


@pytest.fixture(scope="module")
def room() -> OccupancyMap:
    return box_room()


@pytest.fixture()
def physics(room: OccupancyMap) -> RacecarPhysics:
    return RacecarPhysics(room)


def footprint_overlaps_grid(grid: OccupancyMap, corners: np.ndarray, shrink: float = 0.0) -> bool:
    """Brute force: whether the footprint (shrunk by ``shrink`` metres on every side) overlaps an
    occupied cell or leaves the map, by the separating-axis test against every cell square of the
    grid padded with one ring of occupied cells."""
    centre = corners.mean(axis=0)
    if shrink:
        along = corners[1] - corners[0]
        across = corners[3] - corners[0]
        along_u = along / np.linalg.norm(along)
        across_u = across / np.linalg.norm(across)
        sign = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]])
        corners = corners - shrink * (sign[:, :1] * along_u + sign[:, 1:] * across_u)
    uv = grid.world_to_map(corners) / grid.resolution  # map frame, cells
    occ = np.pad(grid.occupied, 1, constant_values=True)
    rows, cols = np.nonzero(occ)
    # Cell (row, col) of the padded grid covers u in [col - 1, col), v in [H - row, H - row + 1).
    u0 = cols - 1.0
    v0 = grid.height - rows.astype(float)
    corner_offsets = [(0, 0), (1, 0), (1, 1), (0, 1)]
    sq = np.stack([np.stack([u0 + du, v0 + dv], -1) for du, dv in corner_offsets], axis=1)
    axes = [np.array([1.0, 0.0]), np.array([0.0, 1.0])]
    edge = uv[1] - uv[0]
    axes += [edge / np.linalg.norm(edge), np.array([-edge[1], edge[0]]) / np.linalg.norm(edge)]
    separated = np.zeros(len(rows), dtype=bool)
    for axis in axes:
        p_car = uv @ axis
        p_sq = sq @ axis
        separated |= (p_sq.min(axis=1) >= p_car.max()) | (p_sq.max(axis=1) <= p_car.min())
    overlaps = bool((~separated).any())
    return overlaps or not bool(grid.is_free(centre))


# ---------------------------------------------------------------------- walls
@st.composite
def random_maps(draw) -> OccupancyMap:
    h = draw(st.integers(3, 14))
    w = draw(st.integers(3, 14))
    seed = draw(st.integers(0, 2**32 - 1))
    density = draw(st.floats(0.1, 0.6))
    occ = np.random.default_rng(seed).random((h, w)) < density
    occ[0, 0] = False  # at least one free cell
    yaw = draw(st.floats(-math.pi, math.pi))
    res = draw(st.sampled_from([0.05, 0.1, 0.0504]))
    return OccupancyMap(occupied=occ, resolution=res, origin=(1.5, -2.0, yaw))


@settings(max_examples=60, deadline=None)
@given(random_maps())
def test_wall_segments_are_exactly_the_free_occupied_cell_edges(grid: OccupancyMap) -> None:
    segs = grid.world_to_map(wall_segments(grid)) / grid.resolution  # map frame, cells
    assert np.allclose(segs, np.round(segs), atol=1e-6), "segment ends lie on cell corners"
    segs = np.round(segs).astype(int)
    horizontal = segs[:, 0, 1] == segs[:, 1, 1]
    vertical = segs[:, 0, 0] == segs[:, 1, 0]
    assert (horizontal ^ vertical).all(), "every segment is axis-aligned and not a point"
    # Split every segment into unit edges and compare with the boundary edges of the grid.
    found = set()
    for (a, b), is_h in zip(segs.tolist(), horizontal, strict=True):
        k = 0 if is_h else 1
        lo, hi = sorted((a[k], b[k]))
        for t in range(lo, hi):
            unit = ("h", t, a[1]) if is_h else ("v", a[0], t)
            assert unit not in found, f"unit edge {unit} covered twice"
            found.add(unit)
    occ = np.pad(grid.occupied, 1, constant_values=True)  # padded rows/cols: index + 1
    h = grid.height
    expected = set()
    # Horizontal unit edge at v (cells) between the cells below (row h - v) and above.
    for v in range(h + 1):
        for u in range(grid.width):
            below, above = occ[h - v + 1, u + 1], occ[h - v, u + 1]
            if below != above:
                expected.add(("h", u, v))
    for u in range(grid.width + 1):
        for v in range(h):
            left, right = occ[h - v, u], occ[h - v, u + 1]
            if left != right:
                expected.add(("v", u, v))
    assert found == expected


def test_physics_builds_walls_from_the_map(room: OccupancyMap) -> None:
    phys = RacecarPhysics(room)
    # The room's inside is one square: four wall segments, nothing else.
    assert phys.n_segments == 4
    phys.reset(np.array([0.0, 0.0, 0.0]))
    phys.step((0.0, 1.0), 0.025)  # the first step after a placement uses pymunk: walls near
    assert len(phys.space.shapes) == 4 + 1


# ---------------------------------------------------------------------- free poses
@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(random_maps(), st.data())
def test_pose_is_free_agrees_with_the_grid(grid: OccupancyMap, data) -> None:
    car = CarParams(length=0.12, width=0.07, rear_overhang=0.03, wheelbase=0.08)
    phys = RacecarPhysics(grid, car)
    w, h = grid.extent
    for _ in range(8):
        u = data.draw(st.floats(-0.2 * w, 1.2 * w))
        v = data.draw(st.floats(-0.2 * h, 1.2 * h))
        theta = data.draw(st.floats(-math.pi, math.pi))
        x, y = grid.map_to_world(np.array([u, v]))
        pose = np.array([x, y, theta])
        assert phys.pose_is_free(pose) == (not footprint_overlaps_grid(grid, phys.footprint(pose)))


def test_pose_is_free_on_the_real_map(stata_map: OccupancyMap) -> None:
    phys = RacecarPhysics(stata_map)
    rng = np.random.default_rng(3)
    poses = stata_map.sample_free_poses(rng, 40, clearance=0.1)  # near walls: both answers occur
    answers = []
    for pose in poses:
        free = phys.pose_is_free(pose)
        answers.append(free)
        # Check against the grid on a crop around the pose (the brute force is O(cells)).
        rc = stata_map.world_to_grid(pose[:2])
        r0, c0 = max(rc[0] - 20, 0), max(rc[1] - 20, 0)
        crop_occ = stata_map.occupied[r0 : rc[0] + 20, c0 : rc[1] + 20]
        # The crop's lower-left corner, map frame: column c0, bottom of its last row.
        bottom = stata_map.height - r0 - crop_occ.shape[0]
        origin_xy = stata_map.map_to_world(np.array([c0, bottom]) * stata_map.resolution)
        yaw = stata_map.yaw
        crop = OccupancyMap(
            occupied=crop_occ, resolution=stata_map.resolution, origin=(*origin_xy, yaw)
        )
        assert free == (not footprint_overlaps_grid(crop, phys.footprint(pose)))
    assert any(answers) and not all(answers)


def test_reset_rejects_bad_poses(physics: RacecarPhysics) -> None:
    with pytest.raises(ValueError, match="pose"):
        physics.reset(np.array([-2.95, 0.0, 0.0]))  # inside the left wall
    with pytest.raises(ValueError, match="pose"):
        physics.reset(np.array([50.0, 0.0, 0.0]))  # off the map
    with pytest.raises(ValueError, match="pose"):
        physics.reset(np.array([0.0, np.nan, 0.0]))
    with pytest.raises(ValueError, match="pose"):
        physics.reset(np.array([0.0, 0.0]))


# ---------------------------------------------------------------------- kinematics
@pytest.mark.parametrize("steer", [0.1, 0.3, -0.25])
def test_constant_steer_drives_the_bicycle_circle(physics: RacecarPhysics, steer: float) -> None:
    speed = 0.5
    physics.reset(np.array([0.0, -0.5, 0.0]), speed=speed, steer=steer)
    poses = []
    for _ in range(200):
        physics.step((steer, speed), 0.02)
        poses.append(physics.pose)
    xy = np.array(poses)[:, :2]
    # Least-squares circle through the rear-axle track.
    a = np.column_stack([2 * xy, np.ones(len(xy))])
    cx, cy, c = np.linalg.lstsq(a, (xy**2).sum(axis=1), rcond=None)[0]
    radius = math.sqrt(c + cx**2 + cy**2)
    expected = physics.car.wheelbase / math.tan(abs(steer))
    assert radius == pytest.approx(expected, rel=1e-3)
    assert np.hypot(xy[:, 0] - cx, xy[:, 1] - cy) == pytest.approx(radius, rel=1e-3)
    # The centre is on the side the wheels point to (left of the start heading for steer > 0).
    assert math.copysign(1.0, cy - (-0.5)) == math.copysign(1.0, steer)
    omega = speed * math.tan(steer) / physics.car.wheelbase
    assert physics.twist == pytest.approx([speed, 0.0, omega], abs=1e-6)


def test_pose_heading_stays_wrapped(physics: RacecarPhysics) -> None:
    physics.reset(np.array([0.0, -0.5, 3.0]), speed=1.0, steer=0.4)
    for _ in range(300):
        physics.step((0.4, 1.0), 0.025)
        theta = physics.pose[2]
        assert -math.pi <= theta < math.pi


def test_straight_drive_covers_speed_times_time(physics: RacecarPhysics) -> None:
    physics.reset(np.array([-1.5, 0.0, 0.3]), speed=2.0)
    start = physics.pose
    for _ in range(20):
        physics.step((0.0, 2.0), 0.025)
    end = physics.pose
    assert np.hypot(*(end[:2] - start[:2])) == pytest.approx(2.0 * 20 * 0.025, rel=1e-9)
    assert end[2] == pytest.approx(0.3, abs=1e-12)
    assert physics.twist == pytest.approx([2.0, 0.0, 0.0], abs=1e-9)


def test_steering_rate_and_acceleration_limits(physics: RacecarPhysics) -> None:
    car = physics.car
    dt = 0.01
    physics.reset(np.array([-2.0, 0.0, 0.0]))
    steers, speeds = [physics.steer], [physics.speed]
    for _ in range(60):
        physics.step((10.0, 100.0), dt)  # far beyond both limits
        steers.append(physics.steer)
        speeds.append(physics.speed)
    steers, speeds = np.array(steers), np.array(speeds)
    assert np.diff(steers).max() <= car.max_steer_rate * dt + 1e-12
    assert np.diff(speeds).max() <= car.max_accel * dt + 1e-12
    assert steers.max() == pytest.approx(car.max_steer)  # reached and held at the angle limit
    assert speeds[-1] == pytest.approx(car.max_accel * 60 * dt)  # still accelerating, exactly
    # Braking, then reversing: deceleration limit down to zero, then acceleration limit.
    for _ in range(30):
        physics.step((-10.0, -100.0), dt)
        steers = np.append(steers, physics.steer)
        speeds = np.append(speeds, physics.speed)
    d = np.diff(speeds[-31:])
    assert d.min() >= -car.max_decel * dt - 1e-12
    assert physics.steer == pytest.approx(-car.max_steer)
    assert np.diff(steers[-31:]).min() >= -car.max_steer_rate * dt - 1e-12
    for _ in range(200):
        physics.step((0.0, -100.0), dt)
    assert physics.speed == pytest.approx(-car.max_reverse_speed)


def test_teleport_forgets_the_old_motion(room: OccupancyMap) -> None:
    moved = RacecarPhysics(room)
    moved.reset(np.array([0.0, 0.0, 0.0]), speed=3.0, steer=0.2)
    for _ in range(10):
        moved.step((0.3, 3.0), 0.025)
    target = np.array([1.0, -1.0, 2.0])
    moved.teleport(target)
    assert moved.pose == pytest.approx(target)
    assert moved.speed == 0.0 and moved.steer == 0.0
    assert moved.twist == pytest.approx([0.0, 0.0, 0.0])
    fresh = RacecarPhysics(room)
    fresh.reset(target)
    for _ in range(30):
        a = moved.step((0.2, 1.5), 0.025)
        b = fresh.step((0.2, 1.5), 0.025)
        assert a == b
        assert np.array_equal(moved.pose, fresh.pose)


def test_footprint_corners(physics: RacecarPhysics) -> None:
    car = physics.car
    physics.reset(np.array([0.5, 0.5, math.pi / 2]))
    fp = physics.footprint()
    # Heading +y: the rear bumper is rear_overhang below the axle, the front length above it.
    assert fp[:, 1].min() == pytest.approx(0.5 - car.rear_overhang)
    assert fp[:, 1].max() == pytest.approx(0.5 - car.rear_overhang + car.length)
    assert fp[:, 0].max() - fp[:, 0].min() == pytest.approx(car.width)


# ---------------------------------------------------------------------- walls and contact
@pytest.mark.parametrize("heading", [0.0, 0.6, 1.3, -2.5])
def test_car_driven_at_a_wall_stops_outside_it(room: OccupancyMap, heading: float) -> None:
    phys = RacecarPhysics(room)
    car = phys.car
    phys.reset(np.array([0.0, 0.0, heading]), speed=car.max_speed)
    # Without a solver the car would go 4 m per 0.025 s step x 25 steps = far through the wall.
    tolerance = car.max_speed * phys.substep + 0.002  # one substep of travel plus pymunk's slop
    contacts = []
    for _ in range(150):
        contacts.append(phys.step((0.0, car.max_speed), 0.025))
        assert not footprint_overlaps_grid(room, phys.footprint(), shrink=tolerance)
    assert any(contacts), "the contact is reported"
    assert all(contacts[-20:]), "the car keeps pushing against the wall and keeps reporting it"
    assert not phys.pose_is_free(phys.pose)  # touching the wall
    if heading == 0.0:  # head-on: the wheels stop with the car (no wheel spin)
        assert abs(phys.speed) <= 2 * car.max_accel * phys.substep
    # Backing away ends the contact.
    phys.step((0.0, -car.max_reverse_speed), 0.5)
    for _ in range(10):
        last = phys.step((0.0, -car.max_reverse_speed), 0.025)
    assert not last
    assert phys.pose_is_free(phys.pose)


def test_thin_wall_is_not_crossed() -> None:
    occ = box_room(160).occupied.copy()
    occ[:, 80] = True  # a one-cell (5 cm) wall across the room
    grid = OccupancyMap(occupied=occ, resolution=RES, origin=(0.0, 0.0, 0.0))
    phys = RacecarPhysics(grid)
    phys.reset(np.array([2.5, 4.0, 0.0]), speed=phys.car.max_speed)
    for _ in range(100):
        phys.step((0.05, phys.car.max_speed), 0.025)
        assert phys.footprint()[:, 0].max() < 80 * RES + phys.car.max_speed * phys.substep
    assert phys.pose[0] < 80 * RES


def test_bad_arguments_raise(room: OccupancyMap) -> None:
    with pytest.raises(ValueError, match="substep"):
        RacecarPhysics(room, substep=0.0)
    with pytest.raises(TypeError, match="car"):
        RacecarPhysics(room, car={"wheelbase": 0.3})  # type: ignore[arg-type]
    phys = RacecarPhysics(room)
    phys.reset(np.array([0.0, 0.0, 0.0]))
    with pytest.raises(ValueError, match="command"):
        phys.step((math.nan, 1.0), 0.025)
    with pytest.raises(ValueError, match="command"):
        phys.step((0.0, 1.0, 2.0), 0.025)
    with pytest.raises(ValueError, match="dt"):
        phys.step((0.0, 1.0), 0.0)
    assert phys.pose == pytest.approx([0.0, 0.0, 0.0])  # nothing moved


# ---------------------------------------------------------------------- free steps
def _drive_fast_and_slow(seed: int, dt: float, max_speed: float, car_model: str = "kinematic") -> int:
    """Drive a car with free steps and one without them on the same random commands (with a
    placement every 100 steps); assert they agree bit for bit; return the steps taken free."""
    occ = box_room(100).occupied.copy()
    occ[40:60, 45:55] = True  # a pillar to drive into
    grid = OccupancyMap(occupied=occ, resolution=RES, origin=(-1.0, 0.5, 0.7))
    fast = RacecarPhysics(grid, car_model=car_model)
    slow = RacecarPhysics(grid, car_model=car_model)
    slow.free_steps = False
    rng = np.random.default_rng(seed)
    start = np.array([*grid.map_to_world(np.array([1.0, 1.0])), 0.3])
    for phys in (fast, slow):
        phys.reset(start)
    free = 0
    for k in range(300):
        if k % 100 == 99:  # a placement mid-run, as after a collision and a reset
            pose = np.array([*grid.map_to_world(rng.uniform(0.6, 4.2, 2)), rng.uniform(-3, 3)])
            if fast.pose_is_free(pose):
                fast.teleport(pose)
                slow.teleport(pose)
        command = (rng.uniform(-0.5, 0.5), rng.uniform(-2.0, max_speed))
        was_free = fast._quiet >= fast._quiet_needed
        hit = fast.step(command, dt)
        assert hit == slow.step(command, dt)
        free += was_free and fast._free_valid
        assert np.array_equal(fast.pose, slow.pose), f"step {k}"
        assert np.array_equal(fast.twist, slow.twist)
        assert (fast.speed, fast.steer) == (slow.speed, slow.steer)
    return free


@settings(max_examples=25, deadline=None)
@example(seed=0, dt=0.025, max_speed=7.0)  # drives into the walls: contacts, then free again
@example(seed=291, dt=0.025, max_speed=7.0)  # mostly against walls: few free steps
@given(
    seed=st.integers(0, 2**32 - 1),
    dt=st.sampled_from([0.005, 0.01, 0.025, 0.03]),
    max_speed=st.floats(0.5, 7.0),
)
def test_free_steps_equal_pymunk_bit_for_bit(seed: int, dt: float, max_speed: float) -> None:
    _drive_fast_and_slow(seed, dt, max_speed)


@settings(max_examples=25, deadline=None)
@example(seed=0, dt=0.025, max_speed=7.0)
@given(
    seed=st.integers(0, 2**32 - 1),
    dt=st.sampled_from([0.005, 0.01, 0.025, 0.03]),
    max_speed=st.floats(0.5, 7.0),
)
def test_single_track_free_steps_equal_pymunk_bit_for_bit(
    seed: int, dt: float, max_speed: float
) -> None:
    _drive_fast_and_slow(seed, dt, max_speed, car_model="single_track")


def test_most_steps_far_from_walls_skip_pymunk() -> None:
    # How many steps are free depends on how often the random drive meets a wall (a fast drive
    # may spend most of its time against one), so the count is asserted on a calm drive only.
    assert _drive_fast_and_slow(seed=0, dt=0.01, max_speed=1.5) > 50
    assert _drive_fast_and_slow(seed=0, dt=0.01, max_speed=1.5, car_model="single_track") > 50
