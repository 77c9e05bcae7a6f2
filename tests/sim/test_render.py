"""Tests of racecar_sim.render: pixel geometry, the map image and the drawing helpers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from racecar_sim.maps import OccupancyMap
from racecar_sim.render import (
    CAR_COLOUR,
    FREE_COLOUR,
    OCCUPIED_COLOUR,
    PARTICLE_COLOUR,
    SCAN_COLOUR,
    MapRenderer,
)


def small_map(yaw: float = 0.0) -> OccupancyMap:
    rng = np.random.default_rng(0)
    occ = rng.random((30, 40)) < 0.3
    return OccupancyMap(occupied=occ, resolution=0.1, origin=(2.0, -1.0, yaw))


def colour_mask(img: np.ndarray, colour: tuple[int, int, int]) -> np.ndarray:
    return (img == np.array(colour, dtype=np.uint8)).all(axis=-1)


@settings(max_examples=50, deadline=None)
@given(
    yaw=st.floats(-math.pi, math.pi),
    scale=st.sampled_from([1.0, 2.0, 3.0, 5.0]),
    row=st.integers(0, 29),
    col=st.integers(0, 39),
    frac=st.tuples(st.floats(0.05, 0.95), st.floats(0.05, 0.95)),
)
def test_world_points_land_in_their_cells_pixels(yaw, scale, row, col, frac) -> None:
    grid = small_map(yaw)
    renderer = MapRenderer(grid, scale=scale)
    # A point inside cell (row, col), anywhere in it.
    u = (col + frac[0]) * grid.resolution
    v = (grid.height - 1 - row + frac[1]) * grid.resolution
    xy = grid.map_to_world(np.array([u, v]))
    px, py = renderer.world_to_pixel(xy)
    assert int(px // scale) == col
    assert int(py // scale) == row


def test_base_image_shows_the_grid() -> None:
    grid = small_map()
    renderer = MapRenderer(grid, scale=1.0)
    img = renderer.base()
    assert img.shape == (grid.height, grid.width, 3) and img.dtype == np.uint8
    assert np.array_equal(colour_mask(img, OCCUPIED_COLOUR), grid.occupied)
    assert np.array_equal(colour_mask(img, FREE_COLOUR), ~grid.occupied)
    img[:] = 0  # the cached image is not handed out
    assert np.array_equal(colour_mask(renderer.base(), FREE_COLOUR), ~grid.occupied)


def test_default_scale_keeps_frames_a_sensible_size() -> None:
    big = OccupancyMap(occupied=np.zeros((1300, 1730), bool), resolution=0.05)
    r_big = MapRenderer(big)
    assert max(r_big.size) <= 1000
    assert r_big.base().shape == (r_big.size[1], r_big.size[0], 3)
    tiny = OccupancyMap(occupied=np.zeros((20, 30), bool), resolution=0.05)
    assert MapRenderer(tiny).scale <= 2.0
    with pytest.raises(ValueError, match="scale"):
        MapRenderer(tiny, scale=-1.0)


def test_draw_car_fills_the_footprint_only() -> None:
    grid = OccupancyMap(occupied=np.zeros((100, 100), bool), resolution=0.05)
    renderer = MapRenderer(grid, scale=2.0)
    img = renderer.base()
    centre = np.array([2.5, 2.5])
    footprint = centre + np.array([[-0.3, -0.15], [0.3, -0.15], [0.3, 0.15], [-0.3, 0.15]])
    renderer.draw_car(img, footprint)
    mask = colour_mask(img, CAR_COLOUR)
    cx, cy = renderer.world_to_pixel(centre)
    assert mask[cy, cx]
    # Filled area ~ the footprint's area in pixels (0.6 m x 0.3 m at 40 px/m).
    assert mask.sum() == pytest.approx(0.6 * 0.3 * 40**2, rel=0.15)
    fx, fy = renderer.world_to_pixel(np.array([4.5, 4.5]))
    assert not mask[fy, fx]


def test_draw_scan_marks_the_hit_points() -> None:
    grid = OccupancyMap(occupied=np.zeros((100, 100), bool), resolution=0.05)
    renderer = MapRenderer(grid, scale=1.0)
    img = renderer.base()
    pose = np.array([2.5, 2.5, math.pi / 2])
    angles = np.array([0.0, -math.pi / 2, 1.0])
    ranges = np.array([1.0, 2.0, 10.0])  # the last one is a drop-out at max range
    renderer.draw_scan(img, pose, ranges, angles, max_range=10.0)
    mask = colour_mask(img, SCAN_COLOUR)
    for hit in ([2.5, 3.5], [4.5, 2.5]):
        px, py = renderer.world_to_pixel(np.array(hit))
        assert mask[py, px]
    assert mask.sum() <= 2 * 4  # two 2x2 dots, nothing for the drop-out
    with pytest.raises(ValueError, match="same length"):
        renderer.draw_scan(img, pose, ranges[:2], angles)


def test_draw_particles_and_pose() -> None:
    grid = OccupancyMap(occupied=np.zeros((100, 100), bool), resolution=0.05)
    renderer = MapRenderer(grid, scale=1.0)
    img = renderer.base()
    rng = np.random.default_rng(1)
    particles = np.column_stack([rng.uniform(-1, 6, 500), rng.uniform(-1, 6, 500), np.zeros(500)])
    renderer.draw_particles(img, particles)  # some are off the map: skipped
    mask = colour_mask(img, PARTICLE_COLOUR)
    on_map = (particles[:, :2] >= 0).all(axis=1) & (particles[:, :2] < 5).all(axis=1)
    pix = renderer.world_to_pixel(particles[on_map, :2])
    assert mask[pix[:, 1], pix[:, 0]].all()
    assert mask.sum() <= on_map.sum()
    colour = (10, 20, 250)
    renderer.draw_pose(img, np.array([2.5, 2.5, 0.0]), colour)
    px, py = renderer.world_to_pixel(np.array([2.5, 2.5]))
    assert colour_mask(img, colour)[py, px]
    tx, ty = renderer.world_to_pixel(np.array([2.9, 2.5]))  # along the arrow
    assert colour_mask(img, colour)[ty - 1 : ty + 2, tx - 1 : tx + 2].any()
