"""The walls in a car's pymunk space: only those near it, with the same motion as with all walls."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from racecar_sim.car.physics import RacecarPhysics
from racecar_sim.car.walls import TILE, tiles_for, wall_segments
from racecar_sim.maps import OccupancyMap

RES = 0.05


def pillar_hall(seed: int, size: int = 400) -> OccupancyMap:
    """A ``size`` x ``size`` cell hall (20 m at 5 cm) with walls round it and random pillars."""
    rng = np.random.default_rng(seed)
    occ = np.zeros((size, size), dtype=bool)
    occ[:3], occ[-3:], occ[:, :3], occ[:, -3:] = True, True, True, True
    for r, c in rng.integers(20, size - 30, (40, 2)):
        h, w = rng.integers(2, 12, 2)
        occ[r : r + h, c : c + w] = True
    occ[size // 2 - 20 : size // 2 + 20, size // 2 - 20 : size // 2 + 20] = False  # room to start
    return OccupancyMap(occupied=occ, resolution=RES, origin=(-7.0, -9.0, 0.3))


def _segment_distance(segments: np.ndarray, x: float, y: float) -> np.ndarray:
    a, b = segments[:, 0], segments[:, 1]
    ab = b - a
    t = np.clip(((np.array([x, y]) - a) * ab).sum(1) / np.maximum((ab * ab).sum(1), 1e-12), 0, 1)
    return np.hypot(*(a + t[:, None] * ab - np.array([x, y])).T)


def test_the_space_holds_the_walls_near_the_car_and_not_the_far_ones() -> None:
    grid = pillar_hall(0)
    phys = RacecarPhysics(grid)
    assert phys.n_segments == len(wall_segments(grid))
    assert len(phys.space.shapes) == 1  # just the car: no wall made yet
    start = np.array([*grid.map_to_world(np.array([10.0, 10.0])), 0.0])
    phys.reset(start)
    phys.step((0.0, 2.0), 0.025)
    held = {(tuple(s.a), tuple(s.b)) for s in phys.space.shapes if hasattr(s, "a")}
    segs = tiles_for(grid).segments
    near = _segment_distance(segs, *phys.pose[:2]) <= TILE
    for k in np.flatnonzero(near):
        assert (tuple(segs[k, 0]), tuple(segs[k, 1])) in held
    assert len(held) < len(segs)  # the far ones stay out


def _drive_lazy_and_full(seed: int) -> tuple[int, set]:
    """Drive one car with walls loaded near it and one with all walls on the same random commands
    (placements now and then); assert bit-for-bit equal motion; return the contacts seen and the
    blocks of tiles the lazy car held its walls for."""
    grid = pillar_hall(seed % 7)
    lazy, full = RacecarPhysics(grid), RacecarPhysics(grid)
    full._walls.ensure(0.0, 0.0, math.inf)
    rng = np.random.default_rng(seed)
    start = np.array([*grid.map_to_world(np.array([10.0, 10.0])), rng.uniform(-3, 3)])
    for phys in (lazy, full):
        phys.reset(start)
    hits = 0
    blocks = set()
    for k in range(400):
        if k % 150 == 149:
            pose = np.array([*grid.map_to_world(rng.uniform(1.0, 19.0, 2)), rng.uniform(-3, 3)])
            free = lazy.pose_is_free(pose)
            assert free == full.pose_is_free(pose)
            if free:
                lazy.teleport(pose)
                full.teleport(pose)
        command = (rng.uniform(-0.4, 0.4), rng.uniform(-2.0, 6.0))
        hit = lazy.step(command, 0.025)
        assert hit == full.step(command, 0.025)
        hits += hit
        assert np.array_equal(lazy.pose, full.pose), f"step {k}"
        assert np.array_equal(lazy.twist, full.twist)
        blocks.add(lazy._walls._block)
    return hits, blocks


@settings(max_examples=8, deadline=None)
@example(seed=3)
@given(seed=st.integers(0, 2**32 - 1))
def test_walls_near_the_car_give_the_motion_of_all_walls(seed: int) -> None:
    _drive_lazy_and_full(seed)


def test_the_drive_crosses_tiles_and_hits_walls() -> None:
    """The equality above is not vacuous: the car meets walls and changes tiles."""
    grid = pillar_hall(3 % 7)
    hits, blocks = _drive_lazy_and_full(3)
    assert hits > 0
    assert len(tiles_for(grid)._tiles) > 9  # more tiles than one block
    assert len(blocks - {None}) >= 2, blocks  # and the lazy car's walls moved with it


def test_tiles_are_shared_by_the_cars_of_a_map() -> None:
    grid = pillar_hall(1)
    assert RacecarPhysics(grid)._walls.tiles is RacecarPhysics(grid)._walls.tiles
    assert tiles_for(pillar_hall(1)) is not tiles_for(grid)  # another map object


@pytest.mark.parametrize("reach", [0.5, 4.0, 9.0])
def test_a_block_holds_every_wall_within_reach(reach: float) -> None:
    grid = pillar_hall(2)
    tiles = tiles_for(grid)
    rng = np.random.default_rng(0)
    for x, y in rng.uniform(-8, 12, (30, 2)):
        radius = max(1, math.ceil(reach / tiles.tile))
        ids = set(tiles.block(tiles.key(x, y), radius).tolist())
        near = np.flatnonzero(_segment_distance(tiles.segments, x, y) <= reach)
        assert set(near.tolist()) <= ids
