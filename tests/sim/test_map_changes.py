"""map_changes / with_cells: the cells one map opened and closed against another, in any frame."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from racecar_sim.maps import OccupancyMap, load_map
from racecar_sim.maps.changes import map_changes, with_cells
from tests.skips import need_shared


def _room(h: int = 20, w: int = 30) -> np.ndarray:
    occ = np.zeros((h, w), dtype=bool)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = True
    return occ


def test_a_wall_taken_down_is_opened_and_a_new_one_closed():
    old_occ = _room()
    old_occ[5:15, 10] = True  # a wall the world no longer has
    new_occ = _room()
    new_occ[8, 20:25] = True  # a wall the old map lacks
    old = OccupancyMap(old_occ, 0.1, (1.0, -2.0, 0.0))
    new = OccupancyMap(new_occ, 0.1, (1.0, -2.0, 0.0))
    opened, closed = map_changes(old, new)
    want_opened = np.zeros_like(old_occ)
    want_opened[5:15, 10] = True
    want_closed = np.zeros_like(old_occ)
    want_closed[8, 20:25] = True
    assert np.array_equal(opened, want_opened)
    assert np.array_equal(closed, want_closed)
    assert not map_changes(old, old)[0].any() and not map_changes(old, old)[1].any()


def test_cells_are_compared_in_the_world_frame_not_by_index():
    # new is old's image cropped by 7 columns on the left, its origin moved to match (yaw pi,
    # as the Stata maps): the same world, so nothing changed; by index everything would.
    occ = _room(20, 40)
    occ[3:9, 12] = True
    res, yaw = 0.05, math.pi
    old = OccupancyMap(occ, res, (3.0, 4.0, yaw))
    # with yaw pi, image column c lies at world x = 3 - (c + 0.5) res: column 7 -> x 3 - 7 res
    new = OccupancyMap(occ[:, 7:], res, (3.0 - 7 * res, 4.0, yaw))
    opened, closed = map_changes(old, new)
    assert not opened.any() and not closed.any()
    # the first 7 columns lie outside new's image: in neither mask even where they differ
    changed = occ.copy()
    changed[3:9, 12] = False
    moved = OccupancyMap(changed[:, 7:], res, (3.0 - 7 * res, 4.0, yaw))
    opened, _ = map_changes(old, moved)
    assert np.array_equal(np.argwhere(opened), np.argwhere(occ & ~changed))


def test_with_cells_sets_exactly_the_cells_and_keeps_the_geometry():
    old = OccupancyMap(_room(), 0.1, (0.5, 0.5, 0.3), name="old")
    cells = np.zeros(old.shape, dtype=bool)
    cells[0, 3:6] = True
    cells[10, 10] = True
    opened = with_cells(old, cells, free=True)
    assert not opened.occupied[cells].any()
    assert np.array_equal(opened.occupied[~cells], old.occupied[~cells])
    assert (opened.resolution, opened.origin) == (old.resolution, old.origin)
    assert opened.name == "old+opened"
    closed = with_cells(old, cells, free=False, name="shut")
    assert closed.occupied[cells].all() and closed.name == "shut"
    assert old.occupied[10, 10] == np.False_  # the original is untouched


def test_map_changes_refuses_what_is_not_a_map_by_name():
    room = OccupancyMap(_room(), 0.1)
    with pytest.raises(ValueError, match="new must be an OccupancyMap, got str"):
        map_changes(room, "basement.yaml")
    with pytest.raises(ValueError, match="old must be an OccupancyMap, got ndarray"):
        map_changes(_room(), room)


@pytest.mark.parametrize(
    "cells", [np.zeros((3, 3), dtype=bool), np.zeros((20, 30), dtype=np.uint8)]
)
def test_with_cells_refuses_a_mask_of_the_wrong_shape_or_type(cells):
    with pytest.raises(ValueError, match="bool mask of the map's shape"):
        with_cells(OccupancyMap(_room(), 0.1), cells, free=True)


@settings(deadline=None, max_examples=40)
@given(
    seed=st.integers(0, 2**31 - 1),
    shift=st.integers(0, 6),
    yaw=st.sampled_from([0.0, math.pi / 2, math.pi, -math.pi / 2]),
)
def test_applying_the_changes_leaves_nothing_to_change(seed, shift, yaw):
    """Opening what new opened and closing what it closed gives a map with no changes left
    against new, wherever new's image overlaps old's."""
    rng = np.random.default_rng(seed)
    h, w, res = 16, 24, 0.1
    old_occ = rng.random((h, w)) < 0.3
    new_occ = rng.random((h, w - shift)) < 0.3
    old_occ[0, 0] = new_occ[0, 0] = False  # at least one free cell each
    old = OccupancyMap(old_occ, res, (2.0, -1.0, yaw))
    # new's image starts ``shift`` columns further along the image's u axis
    c, s = math.cos(yaw), math.sin(yaw)
    new = OccupancyMap(new_occ, res, (2.0 + c * shift * res, -1.0 + s * shift * res, yaw))
    opened, closed = map_changes(old, new)
    assert not (opened & closed).any()
    assert not opened[:, :shift].any() and not closed[:, :shift].any()
    assert np.array_equal(opened[:, shift:], old_occ[:, shift:] & ~new_occ)
    edited = with_cells(with_cells(old, opened, free=True), closed, free=False)
    again = map_changes(edited, new)
    assert not again[0].any() and not again[1].any()


def test_stata_against_the_rebuilt_basement_matches_the_readmes_column_offset():
    """../shared/maps/README.md: basement_fixed.png is stata_basement.png's columns 430-1729, and
    the aligned YAML puts it in Stata's frame; compared by that column offset, cell for cell."""
    stata_yaml, fixed_yaml = need_shared(
        "maps/stata_basement.yaml", "maps/basement_fixed_aligned.yaml"
    )
    old, new = load_map(stata_yaml), load_map(fixed_yaml)
    opened, closed = map_changes(old, new)
    new_free = np.zeros(old.shape, dtype=bool)
    new_free[:, 430:] = ~new.occupied
    beside = np.zeros(old.shape, dtype=bool)
    beside[:, 430:] = True
    assert np.array_equal(opened, old.occupied & new_free)
    assert np.array_equal(closed, ~old.occupied & beside & ~new_free)
    assert opened.sum() > 1000 and closed.sum() > 1000  # the rebuilt basement differs


def test_save_map_round_trips_and_never_overwrites(tmp_path) -> None:
    from racecar_sim.maps.writer import save_map

    occ = _room(20, 30)
    occ[4:9, 11] = True
    grid = OccupancyMap(occ, 0.05, (-3.25, 1.5, math.pi), name="edited")
    path = save_map(grid, tmp_path / "edited.yaml")
    back = load_map(path)
    assert np.array_equal(back.occupied, occ)
    assert back.resolution == 0.05 and back.origin == (-3.25, 1.5, math.pi)
    assert (tmp_path / "edited.pgm").is_file()
    # a user's files are never replaced: a PGM there blocks the YAML too, and stays as it was
    (tmp_path / "mine.pgm").write_bytes(b"not ours")
    with pytest.raises(FileExistsError, match=r"mine\.pgm"):
        save_map(grid, tmp_path / "mine.yaml")
    assert not (tmp_path / "mine.yaml").exists()
    assert (tmp_path / "mine.pgm").read_bytes() == b"not ours"
    with pytest.raises(FileExistsError, match=r"edited\.yaml"):
        save_map(grid, path)
    with pytest.raises(ValueError, match=r"\.yaml"):
        save_map(grid, tmp_path / "edited.png")
