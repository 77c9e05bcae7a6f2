"""The map update: cells a map draws as wall that the drives' scans see through, opened only where
enough drives agree; and the whole path from recorded drives through the filter."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcl.experiments.recorded import record_drive
from mcl.mapping import MapUpdateParams, drive_evidence, opened_cells, update_from_drives
from racecar_sim.maps import OccupancyMap, resolve_map
from racecar_sim.maps.changes import with_cells
from racecar_sim.raycast import RayCaster
from racecar_sim.settings.params import from_mapping

RES = 0.05
ANGLES = np.linspace(-2.35, 2.35, 541)
MAX_RANGE = 10.0


def _rooms() -> tuple[OccupancyMap, OccupancyMap, np.ndarray]:
    """A 6 x 4 m room (the world) and its old map, which draws a 1 x 0.8 m recess in the north
    wall as wall; returns (world, old, the recess's cells)."""
    occ = np.zeros((80, 120), dtype=bool)  # rows 0..79 top to bottom, 0.05 m cells
    occ[:2, :] = occ[-2:, :] = occ[:, :2] = occ[:, -2:] = True
    occ[2:18, :] = True  # the north wall, 0.9 m thick ...
    occ[2:18, 50:70] = False  # ... with a recess 1 m wide, 0.8 m deep in the world
    world = OccupancyMap(occ, RES, (0.0, 0.0, 0.0), name="world")
    recess = np.zeros_like(occ)
    recess[2:18, 50:70] = True
    old = with_cells(world, recess, free=True)
    old = OccupancyMap(occ | recess, RES, (0.0, 0.0, 0.0), name="old")
    return world, old, recess


def _scans(world: OccupancyMap, poses: np.ndarray) -> np.ndarray:
    return RayCaster(world, MAX_RANGE).cast(poses, ANGLES)


def _poses(n: int, rng: np.random.Generator) -> np.ndarray:
    """Poses in the room's open part (x 0.5..5.5 m, y 0.5..2.5 m), any heading."""
    return np.column_stack([rng.uniform(0.5, 5.5, n), rng.uniform(0.5, 2.5, n),
                            rng.uniform(-math.pi, math.pi, n)])  # fmt: skip


def test_returns_from_inside_the_old_wall_pass_the_recess_and_nothing_else() -> None:
    world, old, recess = _rooms()
    poses = _poses(60, np.random.default_rng(1))
    ev = drive_evidence(old, poses, _scans(world, poses), ANGLES, 0.0, MAX_RANGE)
    seen = ev.passed >= 3
    assert ev.scans == 60
    assert seen.sum() > 0.5 * recess.sum()  # most of the recess is seen through
    assert not (seen & ~recess).any()  # exact poses: no standing wall is passed
    # the recess's back wall (rows 0-1) is where the returns end: returns there, no passes
    assert ev.returns[1:3, 52:68].sum() > 0 and ev.passed[:2, :].sum() == 0


def test_the_map_the_scans_agree_with_gives_no_evidence() -> None:
    world, _, _ = _rooms()
    poses = _poses(40, np.random.default_rng(2))
    ev = drive_evidence(world, poses, _scans(world, poses), ANGLES, 0.0, MAX_RANGE)
    assert not ev.passed.any()
    assert ev.returns.sum() > 40 * 400  # the returns are counted all the same


def test_a_pose_a_few_centimetres_off_opens_no_standing_wall() -> None:
    world, _, _ = _rooms()
    rng = np.random.default_rng(3)
    poses = _poses(40, rng)
    off = poses + np.column_stack([rng.normal(0, 0.05, 40), rng.normal(0, 0.05, 40),
                                   rng.normal(0, 0.01, 40)])  # fmt: skip
    ev = drive_evidence(world, off, _scans(world, poses), ANGLES, 0.0, MAX_RANGE)
    opened, _ = opened_cells(world, [ev] * 6)
    assert not opened.any()


def test_cells_open_only_when_enough_drives_agree_and_are_then_the_recess() -> None:
    world, old, recess = _rooms()
    params = MapUpdateParams(drives_needed=3)
    drives = []
    for seed in range(4):
        poses = _poses(30, np.random.default_rng(10 + seed))
        drives.append(drive_evidence(old, poses, _scans(world, poses), ANGLES, 0.0, MAX_RANGE))
    opened, votes = opened_cells(old, drives[:2], params)
    assert not opened.any() and votes.max() == 2
    opened, votes = opened_cells(old, drives, params)
    assert votes.max() == 4
    # the face's growth may take one wall cell beside the recess's mouth, no more
    beside = cv2.dilate(recess.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    assert not (opened & ~beside).any() and (opened & ~recess).sum() <= 4
    # all but the end margin (0.1 m: two cells) before the back and side walls
    assert opened[4:18, 52:68].all() and not opened[2, :].any()
    assert opened[17, 50:70].all()  # the old wall's face, between the recess and the room


def test_a_drive_s_own_opening_is_not_the_map_s() -> None:
    """One drive sees through the wall (a door open that day): with two drives needed, nothing."""
    world, old, _ = _rooms()
    poses = _poses(30, np.random.default_rng(5))
    that_day = _scans(world, poses)
    usual = _scans(old, poses)
    evidence = [drive_evidence(old, poses, that_day, ANGLES, 0.0, MAX_RANGE)]
    evidence += [drive_evidence(old, poses, usual, ANGLES, 0.0, MAX_RANGE) for _ in range(3)]
    opened, _ = opened_cells(old, evidence, MapUpdateParams(drives_needed=2))
    assert not opened.any()


def test_scans_not_used_count_nothing_and_shapes_are_checked() -> None:
    world, old, _ = _rooms()
    poses = _poses(10, np.random.default_rng(6))
    scans = _scans(world, poses)
    ev = drive_evidence(old, poses, scans, ANGLES, 0.0, MAX_RANGE, use=np.zeros(10, bool))
    assert ev.scans == 0 and not ev.passed.any() and not ev.returns.any()
    with pytest.raises(ValueError, match="poses"):
        drive_evidence(old, poses[:5], scans, ANGLES, 0.0, MAX_RANGE)
    with pytest.raises(ValueError, match="use"):
        drive_evidence(old, poses, scans, ANGLES, 0.0, MAX_RANGE, use=np.ones(3, bool))


@pytest.mark.parametrize(
    ("field", "value"),
    [("margin", -0.1), ("reach", 0.0), ("drives_needed", 0), ("scans_needed", 1.5),
     ("close_cells", -1), ("pass_ratio", float("nan")), ("smooth", "0.1")],
)  # fmt: skip
def test_bad_settings_are_refused_naming_the_field(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=f"MapUpdateParams.{field}"):
        MapUpdateParams(**{field: value})


def test_settings_load_from_a_mapping() -> None:
    params = from_mapping(MapUpdateParams, {"drives_needed": 2, "reach": 8.0})
    assert params.drives_needed == 2 and params.reach == 8.0
    with pytest.raises(ValueError, match="unknown MapUpdateParams"):
        from_mapping(MapUpdateParams, {"drives": 2})


@settings(deadline=None, max_examples=25)
@given(
    seed=st.integers(0, 10_000),
    needed=st.integers(1, 4),
    close=st.sampled_from([0, 3, 5]),
)
def test_opened_cells_are_blocked_in_the_old_map_and_fewer_as_more_drives_are_needed(
    seed: int, needed: int, close: int
) -> None:
    world, old, _ = _rooms()
    rng = np.random.default_rng(seed)
    evidence = []
    for _ in range(4):
        poses = _poses(8, rng)
        noisy = poses + np.column_stack([rng.normal(0, 0.1, 8), rng.normal(0, 0.1, 8),
                                         rng.normal(0, 0.03, 8)])  # fmt: skip
        evidence.append(drive_evidence(old, noisy, _scans(world, poses), ANGLES, 0.0, MAX_RANGE))
    fewer, _ = opened_cells(old, evidence, MapUpdateParams(drives_needed=needed + 1, close_cells=0))
    more, _ = opened_cells(old, evidence, MapUpdateParams(drives_needed=needed, close_cells=0))
    closed, _ = opened_cells(old, evidence, MapUpdateParams(drives_needed=needed, close_cells=close))
    assert not (more & ~old.occupied).any()
    assert not (fewer & ~more).any()
    assert not (more & ~closed).any() and not (closed & ~old.occupied).any()


def test_update_from_drives_localizes_each_drive_and_frees_exactly_the_opened_cells() -> None:
    """End to end on the bundled loop: its old map lacks a 0.4 m recess along the walls of a
    stretch; the drives are localized on the old map (never their truth)."""
    world = resolve_map("basement_loop")
    band = cv2.dilate(world.occupied.astype(np.uint8), np.ones((17, 17), np.uint8)).astype(bool)
    rows, cols = np.indices(world.shape)
    x = world.grid_to_world(np.stack([rows, cols], axis=-1))[..., 0]
    recess = band & ~world.occupied & (x >= 5.0) & (x <= 9.0)
    old = with_cells(world, recess, free=False)
    drives = [record_drive("basement_loop", seed=s, duration=8.0) for s in range(3)]
    update = update_from_drives(drives, old, params=MapUpdateParams(drives_needed=2))
    assert update.drives == 3 and 0 < update.scans <= sum(int(d.fresh.sum()) for d in drives)
    assert update.opened.sum() > 500
    assert np.array_equal(update.map.occupied, old.occupied & ~update.opened)
    near = cv2.dilate(recess.astype(np.uint8), np.ones((11, 11), np.uint8)).astype(bool)
    assert (update.opened & near).sum() > 0.8 * update.opened.sum()  # within 0.25 m of it
    with pytest.raises(ValueError, match="no drives"):
        update_from_drives([], old)
