"""Ray casting: exact method against an independent slab-method reference, hand-checked geometry,
no-ray-through-walls properties, approximate methods within their documented error bounds, the
in-process cache, and input validation."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from racecar_sim.maps import OccupancyMap
from racecar_sim.raycast import METHODS, LutParams, MarchParams, RayCaster, clear_cache, table_cache
from racecar_sim.raycast.lut_table import FLAG, FLAG_ABOVE, RANGE_MASK
from racecar_sim.settings.config import from_mapping

# Documented in the racecar_sim.raycast module docstring (metres, default parameters).
ERROR_BOUNDS = {"lut": (0.02, 0.10), "march": (0.03, 0.10)}


# ---------------------------------------------------------------------- reference (slow)
def _slab(px, py, dx, dy, x0, x1, y0, y1):
    """Entry and exit parameters of the ray p + t d through the boxes [x0, x1] x [y0, y1]
    (arrays), by the slab method; entry > exit where the line misses a box."""
    with np.errstate(divide="ignore", invalid="ignore"):
        if dx != 0.0:
            tx0, tx1 = (x0 - px) / dx, (x1 - px) / dx
            tx_lo, tx_hi = np.minimum(tx0, tx1), np.maximum(tx0, tx1)
        else:
            inside = (x0 <= px) & (px < x1)
            tx_lo = np.where(inside, -np.inf, np.inf)
            tx_hi = np.where(inside, np.inf, -np.inf)
        if dy != 0.0:
            ty0, ty1 = (y0 - py) / dy, (y1 - py) / dy
            ty_lo, ty_hi = np.minimum(ty0, ty1), np.maximum(ty0, ty1)
        else:
            inside = (y0 <= py) & (py < y1)
            ty_lo = np.where(inside, -np.inf, np.inf)
            ty_hi = np.where(inside, np.inf, -np.inf)
    return np.maximum(tx_lo, ty_lo), np.minimum(tx_hi, ty_hi)


def reference_ranges(
    occupied: np.ndarray,
    res: float,
    origin: tuple[float, float, float],
    poses: np.ndarray,
    angles: np.ndarray,
    max_range: float,
) -> np.ndarray:
    """Ranges by brute force: for each ray, the nearest slab-method entry into any occupied cell's
    square, or the exit from the map's rectangle, clipped; 0 from an occupied cell or off the map.

    Independent of the code under test: its own world -> image-axes transform (ROS map_server:
    world = origin + R(yaw) (u, v), v up from the image's bottom edge) and no grid traversal.
    """
    h, w = occupied.shape
    ox, oy, yaw = origin
    rows, cols = np.nonzero(occupied)
    bx0 = cols * res
    bx1 = bx0 + res
    by0 = (h - 1 - rows) * res
    by1 = by0 + res
    c, s = math.cos(yaw), math.sin(yaw)
    out = np.zeros((len(poses), len(angles)))
    for i, (x, y, theta) in enumerate(poses):
        u = c * (x - ox) + s * (y - oy)
        v = -s * (x - ox) + c * (y - oy)
        col, rv = math.floor(u / res), math.floor(v / res)
        if not (0 <= col < w and 0 <= rv < h) or occupied[h - 1 - rv, col]:
            continue
        for j, a in enumerate(angles):
            dx, dy = math.cos(theta + a - yaw), math.sin(theta + a - yaw)
            t_in, t_out = _slab(u, v, dx, dy, bx0, bx1, by0, by1)
            hit = (t_in <= t_out) & (t_out > 0.0)
            _, t_exit = _slab(
                u,
                v,
                dx,
                dy,
                np.array([0.0]),
                np.array([w * res]),
                np.array([0.0]),
                np.array([h * res]),
            )
            best = min(float(t_exit[0]), float(np.min(t_in[hit], initial=np.inf)))
            out[i, j] = min(max(best, 0.0), max_range)
    return out


# ---------------------------------------------------------------------- maps built here
def corridor_map(length: int = 40, res: float = 0.1) -> OccupancyMap:
    """Rows 0 and 4 are walls, rows 1-3 free: a 3-cell (0.3 m) corridor open at both ends."""
    occ = np.zeros((5, length), dtype=bool)
    occ[0, :] = occ[4, :] = True
    return OccupancyMap(occupied=occ, resolution=res, name="corridor")


def rooms_map(res: float = 0.05) -> OccupancyMap:
    """A 15 x 10 m floor with rooms, doors, pillars and an oblique wall (the approximate methods'
    test map)."""
    h, w = 200, 300
    img = np.zeros((h, w), np.uint8)  # 1 = occupied
    img[:3, :] = img[-3:, :] = img[:, :3] = img[:, -3:] = 1
    img[:, 100:103] = 1
    img[80:100, 100:103] = 0  # door
    img[120:123, 100:] = 1
    img[120:123, 180:200] = 0  # door
    img[:120, 200:202] = 1
    img[30:45, 200:202] = 0
    for r, c in ((40, 40), (60, 150), (160, 60), (150, 250), (90, 260)):
        cv2.circle(img, (c, r), 4, 1, -1)
    cv2.line(img, (20, 180), (90, 130), 1, 2)  # oblique wall
    cv2.line(img, (220, 190), (290, 140), 1, 1)  # thin oblique wall
    return OccupancyMap(occupied=img.astype(bool), resolution=res, origin=(-3.0, 2.0, 0.7))


def stata_crop(stata: OccupancyMap) -> OccupancyMap:
    """The densest 500 x 500-cell window of the Stata basement (keeps the table build short)."""
    free = ~stata.occupied
    win = 500
    sums = cv2.boxFilter(free.astype(np.float32), -1, (win, win), normalize=False)
    r, c = np.unravel_index(np.argmax(sums), sums.shape)
    r0 = int(np.clip(r - win // 2, 0, stata.height - win))
    c0 = int(np.clip(c - win // 2, 0, stata.width - win))
    crop = stata.occupied[r0 : r0 + win, c0 : c0 + win]
    return OccupancyMap(occupied=crop, resolution=stata.resolution, origin=stata.origin)


def free_poses(grid: OccupancyMap, n: int, seed: int = 0) -> np.ndarray:
    return grid.sample_free_poses(np.random.default_rng(seed), n)


FULL_TURN = np.linspace(-math.pi, math.pi, 100, endpoint=False)


# ---------------------------------------------------------------------- exact vs reference
@st.composite
def small_maps(draw):
    h = draw(st.integers(2, 12))
    w = draw(st.integers(2, 12))
    occ = draw(hnp.arrays(np.bool_, (h, w), elements=st.booleans()))
    assume(not occ.all())
    res = draw(st.sampled_from([0.05, 0.1, 0.37, 1.0]))
    origin = (
        draw(st.floats(-5, 5)),
        draw(st.floats(-5, 5)),
        draw(st.floats(-math.pi, math.pi)),
    )
    return OccupancyMap(occupied=occ, resolution=res, origin=origin)


def _poses_in_extent(grid: OccupancyMap, rng: np.random.Generator, n: int) -> np.ndarray:
    """Poses anywhere over the image (free, occupied) and a little beyond it."""
    w, h = grid.extent
    uv = rng.uniform(-0.1, 1.1, size=(n, 2)) * (w, h)
    xy = grid.map_to_world(uv)
    return np.column_stack([xy, rng.uniform(-math.pi, math.pi, n)])


@settings(max_examples=60, deadline=None)
@given(grid=small_maps(), seed=st.integers(0, 2**32 - 1), max_range=st.floats(0.05, 20.0))
def test_exact_matches_slab_reference(grid, seed, max_range):
    rng = np.random.default_rng(seed)
    poses = _poses_in_extent(grid, rng, 6)
    angles = rng.uniform(-math.pi, math.pi, 9)
    got = RayCaster(grid, max_range, "exact").cast(poses, angles)
    want = reference_ranges(grid.occupied, grid.resolution, grid.origin, poses, angles, max_range)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-6)


@settings(max_examples=10, deadline=None)
@given(grid=small_maps(), seed=st.integers(0, 2**32 - 1))
def test_serial_and_parallel_paths_agree(grid, seed):
    rng = np.random.default_rng(seed)
    poses = _poses_in_extent(grid, rng, 5)
    for method in METHODS:
        ser = RayCaster(grid, 5.0, method, parallel=False).cast(poses, FULL_TURN)
        par = RayCaster(grid, 5.0, method, parallel=True).cast(poses, FULL_TURN)
        np.testing.assert_array_equal(ser, par)


# ---------------------------------------------------------------------- hand-checked geometry
def test_corridor_along_and_across():
    grid = corridor_map()  # 40 x 0.1 m long, free rows 1-3 (v from 0.1 to 0.4 m)
    pose = np.array([1.25, 0.25, 0.0])  # in the middle row, facing +x along the corridor
    caster = RayCaster(grid, 10.0)
    ahead, left, behind, right = caster.cast(pose, [0.0, math.pi / 2, math.pi, -math.pi / 2])[0]
    assert ahead == pytest.approx(4.0 - 1.25, abs=1e-9)  # leaves the map at its edge x = 4 m
    assert behind == pytest.approx(1.25, abs=1e-9)
    assert left == pytest.approx(0.4 - 0.25, abs=1e-9)  # top wall's lower face at v = 0.4 m
    assert right == pytest.approx(0.25 - 0.1, abs=1e-9)
    assert left + right == pytest.approx(0.3, abs=1e-9)  # the corridor's width


@pytest.mark.parametrize("method", METHODS)
def test_pose_in_a_wall_or_off_the_map_gives_zero(method):
    grid = corridor_map()
    poses = np.array(
        [
            [1.0, 0.05, 0.3],  # in the bottom wall
            [1.0, 0.45, 0.3],  # in the top wall
            [-0.5, 0.25, 0.0],  # left of the map, looking in
            [4.5, 0.25, math.pi],  # right of the map, looking in
            [1.0, 3.0, -math.pi / 2],  # far above
        ]
    )
    ranges = RayCaster(grid, 10.0, method).cast(poses, FULL_TURN)
    assert ranges.shape == (5, 100)
    assert (ranges == 0.0).all()


@pytest.mark.parametrize("method", METHODS)
def test_max_range_clips_exactly(method):
    grid = corridor_map()
    ranges = RayCaster(grid, 1.5, method).cast([0.5, 0.25, 0.0], [0.0, -0.01, 0.01])
    np.testing.assert_array_equal(ranges, 1.5)


@pytest.mark.parametrize("method", METHODS)
def test_map_edge_is_a_hit(method):
    occ = np.zeros((20, 30), dtype=bool)
    occ[0, 0] = True
    grid = OccupancyMap(occupied=occ, resolution=0.1)  # 3 x 2 m, free but one corner cell
    pose = np.array([1.0, 0.8, 0.0])
    ranges = RayCaster(grid, 10.0, method).cast(pose, [0.0, math.pi / 2, math.pi, -math.pi / 2])
    np.testing.assert_allclose(ranges[0], [2.0, 1.2, 1.0, 0.8], atol=0.01)


def test_origin_yaw_rotates_the_world_with_the_map():
    """The same image with origin yaw 3.14 instead of 0 is the world rotated by 3.14 rad about the
    origin: the correspondingly rotated poses see the same ranges."""
    occ = rooms_map().occupied
    a = OccupancyMap(occupied=occ, resolution=0.05, origin=(0.0, 0.0, 0.0))
    b = OccupancyMap(occupied=occ, resolution=0.05, origin=(0.0, 0.0, 3.14))
    poses_a = free_poses(a, 50, seed=3)
    c, s = math.cos(3.14), math.sin(3.14)
    poses_b = np.column_stack(
        [
            c * poses_a[:, 0] - s * poses_a[:, 1],
            s * poses_a[:, 0] + c * poses_a[:, 1],
            poses_a[:, 2] + 3.14,
        ]
    )
    ra = RayCaster(a, 10.0).cast(poses_a, FULL_TURN)
    rb = RayCaster(b, 10.0).cast(poses_b, FULL_TURN)
    np.testing.assert_allclose(ra, rb, atol=1e-6)
    assert (ra > 0).all()


def test_image_turned_half_round_with_origin_yaw_pi_is_the_same_world():
    grid = rooms_map()
    a = OccupancyMap(occupied=grid.occupied, resolution=0.05, origin=(1.0, -2.0, 0.0))
    w, h = a.extent
    b = OccupancyMap(
        occupied=np.rot90(grid.occupied, 2), resolution=0.05, origin=(1.0 + w, -2.0 + h, math.pi)
    )
    poses = free_poses(a, 50, seed=4)
    np.testing.assert_allclose(
        RayCaster(a, 10.0).cast(poses, FULL_TURN),
        RayCaster(b, 10.0).cast(poses, FULL_TURN),
        atol=1e-6,
    )


# ---------------------------------------------------------------------- no ray passes a wall
@settings(max_examples=40, deadline=None)
@given(grid=small_maps(), seed=st.integers(0, 2**32 - 1))
def test_no_ray_passes_a_wall(grid, seed):
    rng = np.random.default_rng(seed)
    poses = free_poses(grid, 4, seed=seed)
    angles = rng.uniform(-math.pi, math.pi, 16)
    max_range = 3.0 * grid.resolution * max(grid.shape)
    ranges = RayCaster(grid, max_range).cast(poses, angles)
    eps = 1e-6 * grid.resolution
    directions = poses[:, 2:3] + angles[None, :]
    unit = np.stack([np.cos(directions), np.sin(directions)], axis=-1)
    before = poses[:, None, :2] + (ranges - eps)[..., None] * unit
    after = poses[:, None, :2] + (ranges + eps)[..., None] * unit
    assert grid.is_free(before).all()
    hit = ranges < max_range
    assert not grid.is_free(after[hit]).any()


# ---------------------------------------------------------------------- approximate methods
def _errors(grid: OccupancyMap, method: str, max_range: float = 10.0) -> np.ndarray:
    poses = free_poses(grid, 1500, seed=1)
    exact = RayCaster(grid, max_range).cast(poses, FULL_TURN)
    approx = RayCaster(grid, max_range, method).cast(poses, FULL_TURN)
    return np.abs(approx - exact)


@pytest.mark.parametrize("method", ["lut", "march"])
def test_approximate_methods_within_bounds_on_built_map(method):
    err = _errors(rooms_map(), method)
    mean_bound, p99_bound = ERROR_BOUNDS[method]
    assert err.mean() <= mean_bound
    assert np.percentile(err, 99) <= p99_bound


@pytest.mark.parametrize("method", ["lut", "march"])
def test_approximate_methods_within_bounds_on_stata(method, stata_map):
    err = _errors(stata_crop(stata_map), method)
    mean_bound, p99_bound = ERROR_BOUNDS[method]
    assert err.mean() <= mean_bound
    assert np.percentile(err, 99) <= p99_bound


def test_lut_smaller_tolerance_is_more_accurate():
    """Tolerance 0 sends every ray whose two table ranges differ to the exact cast; guide inf
    starts those casts at the pose. Rays that still interpolate see one flat face in both bins."""
    grid = rooms_map()
    poses = free_poses(grid, 300, seed=2)
    exact = RayCaster(grid, 10.0).cast(poses, FULL_TURN)
    strict = RayCaster(grid, 10.0, "lut", lut=LutParams(tolerance=0.0, guide=math.inf))
    loose = RayCaster(grid, 10.0, "lut", lut=LutParams(tolerance=1.0))
    err_strict = np.abs(strict.cast(poses, FULL_TURN) - exact)
    err_loose = np.abs(loose.cast(poses, FULL_TURN) - exact)
    assert err_strict.mean() < err_loose.mean()
    assert np.percentile(err_strict, 99) <= 0.05


def test_lut_table_is_compact_and_over_free_cells_only():
    grid = rooms_map()
    caster = RayCaster(grid, 10.0, "lut", lut=LutParams(n_angles=64))
    table = caster.table
    assert table is not None
    assert table.table.dtype == np.uint16
    assert table.table.shape == (int(np.count_nonzero(~grid.occupied)), 64)
    assert (table.index >= 0).sum() == table.table.shape[0]


def test_lut_entries_along_the_grid_axes_are_exact_casts_from_cell_centres():
    """With one sweep line per cell, the lines of the axis directions pass through the cell
    centres, so those entries are the exact ranges from the centres (to the uint16 quantum)."""
    grid = rooms_map()  # origin yaw 0.7: table directions are in the grid frame
    n_angles = 16
    caster = RayCaster(grid, 10.0, "lut", lut=LutParams(n_angles=n_angles, sub_lines=1))
    table = caster.table
    assert table is not None
    rows, cols = np.nonzero(~grid.occupied)
    centres = grid.grid_to_world(np.column_stack([rows, cols]))
    index = table.index[grid.height - rows, cols + 1]  # pad frame: flipped, one-cell ring
    exact = RayCaster(grid, 10.0)
    for k in (0, 4, 8, 12):
        theta = 2 * math.pi * k / n_angles + grid.yaw
        want = exact.cast(np.column_stack([centres, np.full(len(rows), theta)]), [0.0])[:, 0]
        codes = table.table[index, k] & RANGE_MASK  # the high bit is the planar flag
        got = np.minimum(codes * table.unit * grid.resolution, 10.0)
        np.testing.assert_allclose(got, want, atol=table.unit * grid.resolution)


def _box_room(h: int, w: int, yaw: float) -> OccupancyMap:
    """An empty h x w-cell room with one-cell walls: every face is exactly straight."""
    occ = np.zeros((h, w), dtype=bool)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = True
    return OccupancyMap(occupied=occ, resolution=0.05, origin=(1.0, -2.0, yaw))


@settings(max_examples=15, deadline=None)
@given(
    h=st.integers(12, 40),
    w=st.integers(12, 40),
    n_angles=st.sampled_from([48, 90, 360]),
    yaw=st.floats(-math.pi, math.pi),
)
def test_lut_flags_pairs_on_one_straight_wall(h, w, n_angles, yaw):
    """In a box room, two table rays of a cell that hit the same wall well away from its ends (and
    so does the ray between them) see one straight face: if their ranges differ by more than
    FLAG_ABOVE the pair is flagged."""
    grid = _box_room(h, w, yaw)
    caster = RayCaster(grid, 10.0, "lut", lut=LutParams(n_angles=n_angles), cache=False)
    table = caster.table
    assert table is not None
    rv, col = np.nonzero(table.index >= 0)  # pad frame; the free box is [2, w] x [2, h] cells
    rows = table.index[rv, col]
    cx, cy = col + 0.5, rv + 0.5
    theta = 2 * math.pi * np.arange(n_angles + 1) / n_angles
    hits = []
    for k in (np.arange(n_angles), np.arange(1, n_angles + 1) % n_angles):
        r = (table.table[rows[:, None], k[None, :]] & RANGE_MASK) * table.unit
        hits.append((cx[:, None] + r * np.cos(theta[k]), cy[:, None] + r * np.sin(theta[k]), r))
    (x0, y0, r0), (x1, y1, r1) = hits
    lo_x, hi_x, lo_y, hi_y = 2.0, w * 1.0, 2.0, h * 1.0  # the inner faces, pad frame
    away = 1.5  # cells from the room's corners

    def on_wall(x, y):
        """Wall id (0-3) of a hit point well inside one face, -1 near a corner."""
        wall = np.full(x.shape, -1)
        inner_y = (y > lo_y + away) & (y < hi_y - away)
        inner_x = (x > lo_x + away) & (x < hi_x - away)
        wall[(np.abs(x - lo_x) < 0.5) & inner_y] = 0
        wall[(np.abs(x - hi_x) < 0.5) & inner_y] = 1
        wall[(np.abs(y - lo_y) < 0.5) & inner_x] = 2
        wall[(np.abs(y - hi_y) < 0.5) & inner_x] = 3
        return wall

    # Where the middle direction's ray from the cell centre leaves the box (it may pass a
    # corner that both table rays miss, when the cell hugs a wall and the rays graze it).
    mid = theta[:-1] + math.pi / n_angles
    dx, dy = np.cos(mid)[None, :], np.sin(mid)[None, :]
    with np.errstate(divide="ignore"):
        tx = np.where(dx > 0, (hi_x - cx[:, None]) / dx, (lo_x - cx[:, None]) / dx)
        ty = np.where(dy > 0, (hi_y - cy[:, None]) / dy, (lo_y - cy[:, None]) / dy)
    tm = np.minimum(np.abs(tx), np.abs(ty))
    wm = on_wall(cx[:, None] + tm * dx, cy[:, None] + tm * dy)
    w0, w1 = on_wall(x0, y0), on_wall(x1, y1)
    same = (w0 >= 0) & (w0 == w1) & (wm == w0) & (np.abs(r0 - r1) > FLAG_ABOVE + 0.01)
    flagged = (table.table[rows] & FLAG) > 0
    assert same.sum() > 0
    assert flagged[same].all()


def test_lut_with_flags_only_is_exact_in_a_box_room():
    """Tolerance 0: a ray is interpolated only where the table flags one straight face, and the
    interpolation (the true ray against the line through the two table hits) is exact there;
    everything else is cast. So in a room of straight walls the lut equals exact casting to the
    table's range quantum, but for rays from a pose off its cell centre that pass a corner the
    centre's rays do not (rare, under two cells)."""
    grid = _box_room(37, 53, 0.4)
    poses = free_poses(grid, 300, seed=4)
    lut = RayCaster(grid, 10.0, "lut", lut=LutParams(n_angles=90, tolerance=0.0), cache=False)
    table = lut.table
    assert table is not None and table.n_flagged > 0
    err = np.abs(lut.cast(poses, FULL_TURN) - RayCaster(grid, 10.0).cast(poses, FULL_TURN))
    assert np.mean(err <= 1e-3) >= 0.99
    assert err.max() <= 2 * grid.resolution


def test_methods_list():
    assert set(METHODS) == {"exact", "lut", "march"}
    assert METHODS[0] == "exact"


# ---------------------------------------------------------------------- cache, dtype, shapes
def test_cache_shares_tables_between_casters(monkeypatch):
    clear_cache()
    grid = rooms_map()
    a = RayCaster(grid, 10.0, "lut", lut=LutParams(n_angles=32))
    same_content = OccupancyMap(occupied=grid.occupied.copy(), resolution=0.05, origin=(5, 5, 1))
    b = RayCaster(same_content, 10.0, "lut", lut=LutParams(n_angles=32, tolerance=0.3))
    assert a.table is b.table  # origin and query parameters do not change the table
    assert RayCaster(grid, 8.0, "lut", lut=LutParams(n_angles=32)).table is not a.table
    assert RayCaster(grid, 10.0, "lut", lut=LutParams(n_angles=32), cache=False).table is not (
        a.table
    )
    clear_cache()
    assert RayCaster(grid, 10.0, "lut", lut=LutParams(n_angles=32)).table is not a.table
    one_table = a.table.nbytes
    monkeypatch.setattr(table_cache, "CACHE_BYTES", 3 * one_table)
    tables = [RayCaster(grid, 5.0 + k, "lut", lut=LutParams(n_angles=32)).table for k in range(5)]
    assert RayCaster(grid, 9.0, "lut", lut=LutParams(n_angles=32)).table is tables[-1]
    assert RayCaster(grid, 5.0, "lut", lut=LutParams(n_angles=32)).table is not tables[0]
    assert sum(v.nbytes for v in table_cache._cache.values()) <= 3 * one_table


@pytest.mark.parametrize("method", METHODS)
def test_float32_output(method):
    grid = rooms_map()
    poses = free_poses(grid, 20)
    r64 = RayCaster(grid, 10.0, method).cast(poses, FULL_TURN)
    r32 = RayCaster(grid, 10.0, method, dtype=np.float32).cast(poses, FULL_TURN)
    assert r32.dtype == np.float32
    np.testing.assert_allclose(r32, r64, atol=1e-5)


def test_shapes():
    caster = RayCaster(corridor_map(), 10.0)
    assert caster.cast([1.0, 0.25, 0.0], FULL_TURN).shape == (1, 100)
    assert caster.cast(np.zeros((0, 3)), FULL_TURN).shape == (0, 100)
    assert caster.cast([[1.0, 0.25, 0.0]] * 2, []).shape == (2, 0)


def test_params_load_from_mappings():
    p = from_mapping(LutParams, {"n_angles": 180, "tolerance": 0.2})
    assert p == LutParams(n_angles=180, tolerance=0.2)
    assert from_mapping(MarchParams, {"min_step": 0.25}).min_step == 0.25


# ---------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    "poses",
    [np.zeros((4, 2)), np.zeros((2, 3, 1)), np.zeros(4), [[1.0, np.nan, 0.0]], [[np.inf, 0, 0]]],
)
def test_bad_poses_raise(poses):
    with pytest.raises(ValueError, match="poses"):
        RayCaster(corridor_map(), 10.0).cast(poses, FULL_TURN)


def test_bad_angles_raise():
    caster = RayCaster(corridor_map(), 10.0)
    with pytest.raises(ValueError, match="angles"):
        caster.cast([1.0, 0.25, 0.0], [0.0, np.nan])
    with pytest.raises(ValueError, match="angles"):
        caster.cast([1.0, 0.25, 0.0], np.zeros((2, 2)))


@pytest.mark.parametrize("max_range", [0.0, -1.0, np.nan, np.inf, "10"])
def test_bad_max_range_raises(max_range):
    with pytest.raises(ValueError, match="max_range"):
        RayCaster(corridor_map(), max_range)


def test_unknown_method_raises_listing_methods():
    with pytest.raises(ValueError, match="exact"):
        RayCaster(corridor_map(), 10.0, "magic")


@pytest.mark.parametrize(
    "kwargs",
    [
        {"lut": LutParams(), "method": "lut", "dtype": np.int32},
        {"lut": {"n_angles": 8}, "method": "lut"},
        {"march": 0.5, "method": "march"},
    ],
)
def test_bad_options_raise(kwargs):
    with pytest.raises(ValueError):
        RayCaster(corridor_map(), 10.0, **kwargs)


@pytest.mark.parametrize(
    ("cls", "kwargs"),
    [
        (LutParams, {"n_angles": 4}),
        (LutParams, {"n_angles": 360.0}),
        (LutParams, {"sub_lines": 0}),
        (LutParams, {"tolerance": -0.1}),
        (LutParams, {"tolerance": math.nan}),
        (LutParams, {"guide": -1.0}),
        (MarchParams, {"min_step": 0.0}),
        (MarchParams, {"min_step": 2.0}),
        (MarchParams, {"refine": -1}),
        (MarchParams, {"refine": 2.5}),
    ],
)
def test_bad_params_raise(cls, kwargs):
    with pytest.raises(ValueError, match=next(iter(kwargs))):
        cls(**kwargs)


def test_remembered_beam_directions_follow_changed_angles():
    grid = rooms_map()
    poses = free_poses(grid, 20, seed=5)
    angles = np.linspace(-2.0, 2.0, 37)
    caster = RayCaster(grid, 8.0)
    first = caster.cast(poses, angles)
    angles += 0.3  # the same array, changed in place: the caster must not reuse stale directions
    moved = caster.cast(poses, angles)
    np.testing.assert_array_equal(moved, RayCaster(grid, 8.0, cache=False).cast(poses, angles))
    assert not np.array_equal(first, moved)
