"""A map updated between runs from the drives that used it: the cells its walls no longer have.

Where the world has opened since the map was drawn (a recess, a wall set back, a corridor rebuilt
wider) the beam model prefers a pose beside the car whose scan happens to fit the old walls, and
the filter can lose the car (docs: "Localization in a changing world"). One drive cannot learn those
cells while it needs them (its poses are wrong exactly there); the drives that went before can.
[update_from_drives][mcl.mapping.update.update_from_drives] localizes each recorded drive on the
old map with the filter, counts what its scans saw through the map's walls at the steps its
``lost`` flag did not call lost ([drive_evidence][mcl.mapping.see_through.drive_evidence]), and
opens the cells enough drives agree on ([opened_cells][mcl.mapping.update.opened_cells]); the
returned map is the old one with those cells free. Cells are only opened, never closed: what the
world has put up the filter's sensor model already treats as clutter.

Frames: masks in the old map's grid frame (row 0 = the image's top row).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from mcl.experiments.recorded import RecordedDrive, localize_recorded
from mcl.mapping.params import MapUpdateParams
from mcl.mapping.see_through import DriveEvidence, drive_evidence
from mcl.wrappers.localization import LocalizationConfig
from racecar_sim.maps import OccupancyMap
from racecar_sim.maps.changes import with_cells

__all__ = ["MapUpdate", "opened_cells", "update_from_drives"]


@dataclass(frozen=True, eq=False)
class MapUpdate:
    """The updated map and what made it.

    Attributes:
        map: the old map with the opened cells free (same geometry).
        opened: (H, W) bool, the cells opened (grid frame).
        votes: (H, W) int32, drives that voted for each cell.
        drives: drives used.
        scans: scans used, over all drives.
    """

    map: OccupancyMap
    opened: np.ndarray
    votes: np.ndarray
    drives: int
    scans: int


def opened_cells(
    old_map: OccupancyMap,
    evidence: Sequence[DriveEvidence],
    params: MapUpdateParams | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The blocked cells of ``old_map`` the drives agree the world has opened, and the votes.

    A drive votes for a cell its scans passed ``scans_needed`` times; a cell opens with
    ``drives_needed`` votes when it was passed ``pass_ratio`` times as often as returns ended in
    it; the set is then closed over ``close_cells`` and given the wall cells between it and the
    map's free space ([MapUpdateParams][mcl.mapping.params.MapUpdateParams]). Returns
    ``(opened, votes)``: (H, W) bool and int32 in the grid frame.
    """
    params = params or MapUpdateParams()
    votes = np.zeros(old_map.shape, dtype=np.int32)
    passed = np.zeros(old_map.shape, dtype=np.int64)
    returns = np.zeros(old_map.shape, dtype=np.int64)
    for drive in evidence:
        votes += drive.passed >= params.scans_needed
        passed += drive.passed
        returns += drive.returns
    blocked = old_map.occupied
    opened = (votes >= params.drives_needed) & (passed >= params.pass_ratio * returns) & blocked
    k = params.close_cells
    if k > 0 and opened.any():
        square = np.ones((k, k), dtype=np.uint8)
        closed = cv2.morphologyEx(opened.astype(np.uint8), cv2.MORPH_CLOSE, square).astype(bool)
        ring = np.ones((3, 3), dtype=np.uint8)
        by_free = cv2.dilate((~blocked).astype(np.uint8), ring).astype(bool)
        by_opened = cv2.dilate(closed.astype(np.uint8), ring).astype(bool)
        opened = (closed | (by_free & by_opened)) & blocked
    return opened, votes


def update_from_drives(
    drives: Iterable[RecordedDrive],
    old_map: OccupancyMap,
    config: LocalizationConfig | None = None,
    params: MapUpdateParams | None = None,
) -> MapUpdate:
    """``old_map`` updated from recorded drives in the world as it is now.

    Each drive is localized on ``old_map`` with ``config`` (None: the defaults) and its own
    seed ([localize_recorded][mcl.experiments.recorded.localize_recorded]); its scans count at
    the estimates of the steps that carried them, where the ``lost`` flag was down. No drive's
    true pose is used.

    Args:
        drives: the drives (any world; their scans, odometry and lidar geometry); any iterable,
            read once, one drive at a time (a generator that records each drive when asked
            keeps one drive in memory).
        old_map: the map the filter holds.
        config: the filter's settings.
        params: the update's settings.

    Raises:
        ValueError: no drives.
    """
    params = params or MapUpdateParams()
    evidence = []
    for drive in drives:
        run = localize_recorded(drive, config, old_map)
        steps = np.flatnonzero(drive.fresh)
        counts = drive_evidence(
            old_map, run.estimate[steps], drive.scans, drive.beam_angles,
            drive.mount_offset, drive.max_range, ~run.lost[steps], params,
        )  # fmt: skip
        evidence.append(counts)
    if not evidence:
        raise ValueError("update_from_drives: no drives given")
    opened, votes = opened_cells(old_map, evidence, params)
    updated = with_cells(old_map, opened, free=True, name=f"{old_map.name}+updated")
    return MapUpdate(updated, opened, votes, len(evidence), sum(e.scans for e in evidence))
